#!/bin/bash
# Pools spacemouse BCQ 50k on the cut data (--drop-noops): seed 1 (session 57, runs/grid_sm_bcq_noops_s1), seeds 2-3
# (session 58, runs/grid_sm_bcq_noops_s23); then each seed against the full data's same seed
# (../grid_calibrated_spacemouse_bcq/), bowl by bowl: compare/paired.md. Run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
rm -rf runs/grid_calibrated_spacemouse_bcq_noops
veragmil-pool-results runs/grid_calibrated_spacemouse_bcq_noops/eval \
  --agent "spacemouse BCQ no-load obs no-noops seed 1=runs/grid_sm_bcq_noops_s1/eval/results.json:spacemouse BCQ no-load obs no-noops" \
  --agent "spacemouse BCQ no-load obs no-noops seed 2=runs/grid_sm_bcq_noops_s23/eval/results.json:spacemouse BCQ no-load obs no-noops seed 2" \
  --agent "spacemouse BCQ no-load obs no-noops seed 3=runs/grid_sm_bcq_noops_s23/eval/results.json:spacemouse BCQ no-load obs no-noops seed 3"
python3 -c "import json; t = json.load(open('runs/grid_sm_bcq_noops_s1/timings.json')); t['evaluate (seed 1)'] = t.pop('evaluate'); u = json.load(open('runs/grid_sm_bcq_noops_s23/timings.json')); u['evaluate (seeds 2-3)'] = u.pop('evaluate'); json.dump({**t, **u}, open('runs/grid_calibrated_spacemouse_bcq_noops/timings.json', 'w'), indent=2)"
F=results/grid_calibrated_spacemouse_bcq/results.json
C=runs/grid_calibrated_spacemouse_bcq_noops/eval/results.json
veragmil-pool-results runs/grid_calibrated_spacemouse_bcq_noops/compare \
  --agent "spacemouse BCQ seed 1=$F:spacemouse BCQ no-load obs seed 1" --agent "spacemouse BCQ seed 2=$F:spacemouse BCQ no-load obs seed 2" \
  --agent "spacemouse BCQ seed 3=$F:spacemouse BCQ no-load obs seed 3" \
  --agent "spacemouse BCQ no-noops seed 1=$C:spacemouse BCQ no-load obs no-noops seed 1" --agent "spacemouse BCQ no-noops seed 2=$C:spacemouse BCQ no-load obs no-noops seed 2" \
  --agent "spacemouse BCQ no-noops seed 3=$C:spacemouse BCQ no-load obs no-noops seed 3" \
  --paired "spacemouse BCQ" "spacemouse BCQ no-noops" --paired "spacemouse BCQ seed 1" "spacemouse BCQ no-noops seed 1" \
  --paired "spacemouse BCQ seed 2" "spacemouse BCQ no-noops seed 2" --paired "spacemouse BCQ seed 3" "spacemouse BCQ no-noops seed 3"
mkdir -p results/grid_calibrated_spacemouse_bcq_noops/compare
cp runs/grid_calibrated_spacemouse_bcq_noops/compare/{paired.md,table.md,stages.md} results/grid_calibrated_spacemouse_bcq_noops/compare/
