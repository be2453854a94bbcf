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
