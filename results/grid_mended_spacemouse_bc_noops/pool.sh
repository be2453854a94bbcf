#!/bin/bash
# Pairs each seed of this folder's study (runs/mended_sm_bc), bowl by bowl, with the same seed trained on the recording made
# before the start mend (../grid_calibrated_spacemouse_bc_noops/): compare/paired.md. Run from the repository root
# after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc_noops
O=results/grid_calibrated_spacemouse_bc_noops/results.json
M=results/grid_mended_spacemouse_bc_noops/results.json
A="spacemouse BC no-load obs no-noops seed"
rm -rf runs/grid_mended_spacemouse_bc_noops
veragmil-pool-results runs/grid_mended_spacemouse_bc_noops/compare \
  --agent "old start seed 1=$O:$A 1" --agent "old start seed 2=$O:$A 2" --agent "old start seed 3=$O:$A 3" \
  --agent "mended start seed 1=$M:$A 1" --agent "mended start seed 2=$M:$A 2" --agent "mended start seed 3=$M:$A 3" \
  --paired "old start" "mended start" --paired "old start seed 1" "mended start seed 1" \
  --paired "old start seed 2" "mended start seed 2" --paired "old start seed 3" "mended start seed 3"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc_noops/compare/{paired.md,seeds.md,stages.md} $D/compare/
