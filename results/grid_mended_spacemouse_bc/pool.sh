#!/bin/bash
# Pairs the study's seed (runs/mended_sm_full), bowl by bowl, with the same seed trained on the full spacemouse data
# recorded before the start mend (../grid_calibrated_spacemouse_noload/) and with the same seed on the mended data with
# its pauses cut (../grid_mended_spacemouse_bc_noops/): compare/paired.md. Run from the repository root after the
# study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc
O=results/grid_calibrated_spacemouse_noload/results.json
M=results/grid_mended_spacemouse_bc/results.json
C=results/grid_mended_spacemouse_bc_noops/results.json
rm -rf runs/grid_mended_spacemouse_bc
veragmil-pool-results runs/grid_mended_spacemouse_bc/compare \
  --agent "old start seed 1=$O:spacemouse BC no-load obs seed 1" --agent "mended start seed 1=$M:spacemouse BC no-load obs" \
  --agent "mended start, pauses cut seed 1=$C:spacemouse BC no-load obs no-noops seed 1" \
  --paired "old start seed 1" "mended start seed 1" --paired "mended start seed 1" "mended start, pauses cut seed 1"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc/compare/{paired.md,stages.md} $D/compare/
