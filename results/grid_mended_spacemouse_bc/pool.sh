#!/bin/bash
# Pairs each seed of the study (runs/mended_sm_full), bowl by bowl, with the same seed trained on the full spacemouse
# data recorded before the start mend (../grid_calibrated_spacemouse_noload/) and with the same seed on the mended data
# with its pauses cut (../grid_mended_spacemouse_bc_noops/): compare/paired.md. Run from the repository root after the
# study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc
O=results/grid_calibrated_spacemouse_noload/results.json
M=results/grid_mended_spacemouse_bc/results.json
C=results/grid_mended_spacemouse_bc_noops/results.json
A="spacemouse BC no-load obs"
rm -rf runs/grid_mended_spacemouse_bc
veragmil-pool-results runs/grid_mended_spacemouse_bc/compare \
  --agent "old start seed 1=$O:$A seed 1" --agent "old start seed 2=$O:$A seed 2" --agent "old start seed 3=$O:$A seed 3" \
  --agent "mended start seed 1=$M:$A seed 1" --agent "mended start seed 2=$M:$A seed 2" \
  --agent "mended start seed 3=$M:$A seed 3" --agent "mended start, pauses cut seed 1=$C:$A no-noops seed 1" \
  --agent "mended start, pauses cut seed 2=$C:$A no-noops seed 2" --agent "mended start, pauses cut seed 3=$C:$A no-noops seed 3" \
  --paired "old start" "mended start" --paired "old start seed 1" "mended start seed 1" \
  --paired "old start seed 2" "mended start seed 2" --paired "old start seed 3" "mended start seed 3" \
  --paired "mended start" "mended start, pauses cut" --paired "mended start seed 2" "mended start, pauses cut seed 2" \
  --paired "mended start seed 3" "mended start, pauses cut seed 3"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc/compare/{paired.md,seeds.md,stages.md} $D/compare/
