#!/bin/bash
# Pairs the study's seeds (runs/mended_expert_rot), bowl by bowl, with the same seeds on the same expert data without
# the orientation error (../grid_mended_expert_bc/): compare/paired.md. Run from the repository root after the study's
# command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_expert_bc_rot
R=$D/results.json
N=results/grid_mended_expert_bc/results.json
args=()
for s in 1 2 3; do
  args+=(--agent "no-load seed $s=$N:expert BC no-load obs seed $s")
  args+=(--agent "no-load-rot seed $s=$R:expert BC no-load-rot obs seed $s")
  args+=(--paired "no-load seed $s" "no-load-rot seed $s")
done
args+=(--paired "no-load" "no-load-rot")  # the three seeds together
rm -rf runs/grid_mended_expert_bc_rot
veragmil-pool-results runs/grid_mended_expert_bc_rot/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_mended_expert_bc_rot/compare/{paired.md,stages.md} $D/compare/
