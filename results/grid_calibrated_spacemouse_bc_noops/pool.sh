#!/bin/bash
# Pools spacemouse BC 50k on the cut data (--drop-noops): seed 1 (session 57, runs/grid_sm_bc_noops_s1), seeds 2-3 (runs/grid_sm_bc_noops_s23)
set -euo pipefail
cd "$(dirname "$0")/.."  # the repository root
export PATH=$PWD/.venv/bin:$PATH
rm -rf runs/grid_calibrated_spacemouse_bc_noops
veragmil-pool-results runs/grid_calibrated_spacemouse_bc_noops/eval \
  --agent "spacemouse BC no-load obs no-noops seed 1=runs/grid_sm_bc_noops_s1/eval/results.json:spacemouse BC no-load obs no-noops" \
  --agent "spacemouse BC no-load obs no-noops seed 2=runs/grid_sm_bc_noops_s23/eval/results.json:spacemouse BC no-load obs no-noops seed 2" \
  --agent "spacemouse BC no-load obs no-noops seed 3=runs/grid_sm_bc_noops_s23/eval/results.json:spacemouse BC no-load obs no-noops seed 3"
python3 -c "import json; t = json.load(open('runs/grid_sm_bc_noops_s1/timings.json')); t['evaluate (seed 1)'] = t.pop('evaluate'); u = json.load(open('runs/grid_sm_bc_noops_s23/timings.json')); u['evaluate (seeds 2-3)'] = u.pop('evaluate'); json.dump({**t, **u}, open('runs/grid_calibrated_spacemouse_bc_noops/timings.json', 'w'), indent=2)"
# the cut data's seeds against the full data's same seeds (../grid_calibrated_spacemouse_noload/), bowl by bowl: compare/paired.md
R=results/grid_calibrated_spacemouse_noload/results.json
C=results/grid_calibrated_spacemouse_bc_noops/results.json
veragmil-pool-results runs/grid_calibrated_spacemouse_bc_noops/compare \
  --agent "spacemouse BC seed 1=$R:spacemouse BC no-load obs seed 1" --agent "spacemouse BC seed 2=$R:spacemouse BC no-load obs seed 2" \
  --agent "spacemouse BC seed 3=$R:spacemouse BC no-load obs seed 3" \
  --agent "spacemouse BC no-noops seed 1=$C:spacemouse BC no-load obs no-noops seed 1" --agent "spacemouse BC no-noops seed 2=$C:spacemouse BC no-load obs no-noops seed 2" \
  --agent "spacemouse BC no-noops seed 3=$C:spacemouse BC no-load obs no-noops seed 3" \
  --paired "spacemouse BC" "spacemouse BC no-noops" --paired "spacemouse BC seed 1" "spacemouse BC no-noops seed 1" \
  --paired "spacemouse BC seed 2" "spacemouse BC no-noops seed 2" --paired "spacemouse BC seed 3" "spacemouse BC no-noops seed 3"
mkdir -p results/grid_calibrated_spacemouse_bc_noops/compare && cp runs/grid_calibrated_spacemouse_bc_noops/compare/paired.md results/grid_calibrated_spacemouse_bc_noops/compare/
