#!/bin/bash
# Pairs the study's seeds (runs/mended_sm_rot), bowl by bowl, with the same seeds on the same full data without the
# orientation error (../grid_mended_spacemouse_bc/) and on the same data with its pauses cut
# (../grid_mended_spacemouse_bc_noops/): compare/paired.md. Run from the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc_rot
R=results/grid_mended_spacemouse_bc_rot/results.json
F=results/grid_mended_spacemouse_bc/results.json
C=results/grid_mended_spacemouse_bc_noops/results.json
args=()
for s in 1 2 3; do
  args+=(--agent "no-load seed $s=$F:spacemouse BC no-load obs seed $s")
  args+=(--agent "no-load-rot seed $s=$R:spacemouse BC no-load-rot obs seed $s")
  args+=(--agent "no-load, pauses cut seed $s=$C:spacemouse BC no-load obs no-noops seed $s")
  args+=(--paired "no-load seed $s" "no-load-rot seed $s" --paired "no-load, pauses cut seed $s" "no-load-rot seed $s")
done
args+=(--paired "no-load" "no-load-rot" --paired "no-load, pauses cut" "no-load-rot")  # the three seeds together
rm -rf runs/grid_mended_spacemouse_bc_rot
veragmil-pool-results runs/grid_mended_spacemouse_bc_rot/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc_rot/compare/{paired.md,stages.md} $D/compare/
