#!/bin/bash
# Pairs the study's seeds (runs/mended_sm_cut_rot), bowl by bowl, with the same seeds on the same cut data without the
# orientation error (../grid_mended_spacemouse_bc_noops/) and with it on the full data (../grid_mended_spacemouse_bc_rot/):
# compare/paired.md. Run from the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bc_noops_rot
R=$D/results.json
C=results/grid_mended_spacemouse_bc_noops/results.json
F=results/grid_mended_spacemouse_bc_rot/results.json
args=()
for s in 1 2 3; do
  args+=(--agent "cut, no-load seed $s=$C:spacemouse BC no-load obs no-noops seed $s")
  args+=(--agent "cut, no-load-rot seed $s=$R:spacemouse BC no-load-rot obs no-noops seed $s")
  args+=(--agent "full, no-load-rot seed $s=$F:spacemouse BC no-load-rot obs seed $s")
  args+=(--paired "cut, no-load seed $s" "cut, no-load-rot seed $s" --paired "full, no-load-rot seed $s" "cut, no-load-rot seed $s")
done
args+=(--paired "cut, no-load" "cut, no-load-rot" --paired "full, no-load-rot" "cut, no-load-rot")  # the three seeds together
rm -rf runs/grid_mended_spacemouse_bc_noops_rot
veragmil-pool-results runs/grid_mended_spacemouse_bc_noops_rot/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bc_noops_rot/compare/{paired.md,stages.md} $D/compare/
