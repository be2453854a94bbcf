#!/bin/bash
# Pairs the study's seed (runs/mended_sm_rot), bowl by bowl, with the same seed on the same full data without the
# orientation error (../grid_mended_spacemouse_bc/) and on the same data with its pauses cut
# (../grid_mended_spacemouse_bc_noops/): compare/paired.md. Run from the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc_rot
R=results/grid_mended_spacemouse_bc_rot/results.json
F=results/grid_mended_spacemouse_bc/results.json
C=results/grid_mended_spacemouse_bc_noops/results.json
rm -rf runs/grid_mended_spacemouse_bc_rot
veragmil-pool-results runs/grid_mended_spacemouse_bc_rot/compare \
  --agent "no-load seed 1=$F:spacemouse BC no-load obs seed 1" --agent "no-load-rot seed 1=$R:spacemouse BC no-load-rot obs" \
  --agent "no-load, pauses cut seed 1=$C:spacemouse BC no-load obs no-noops seed 1" \
  --paired "no-load seed 1" "no-load-rot seed 1" --paired "no-load, pauses cut seed 1" "no-load-rot seed 1"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc_rot/compare/{paired.md,stages.md} $D/compare/
