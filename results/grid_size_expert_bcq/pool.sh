#!/bin/bash
# Pairs each seed of the study (runs/size_expert_bcq: BCQ on `no-load-size`), bowl by bowl, with the same seed of
# BCQ on `no-load` (../grid_mended_expert_bcq/: the same actions, pasta recorded on 40 solver iterations) and of BC on
# `no-load-size` from the very demos (../grid_size_expert_bc/): compare/paired.md. Run from the repository root after
# the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_expert_bcq
N=results/grid_mended_expert_bcq/results.json
Z=$D/results.json
B=results/grid_size_expert_bc/results.json
rm -rf runs/grid_size_expert_bcq
args=()
for s in 1 2 3; do
  args+=(--agent "BCQ no-load seed $s=$N:expert BCQ no-load obs seed $s")
  args+=(--agent "BCQ no-load-size seed $s=$Z:expert BCQ no-load-size obs seed $s")
  args+=(--agent "BC no-load-size seed $s=$B:expert BC no-load-size obs seed $s")
done
veragmil-pool-results runs/grid_size_expert_bcq/compare "${args[@]}" \
  --paired "BCQ no-load" "BCQ no-load-size" --paired "BC no-load-size" "BCQ no-load-size" \
  --paired "BCQ no-load seed 1" "BCQ no-load-size seed 1" --paired "BCQ no-load seed 2" "BCQ no-load-size seed 2" \
  --paired "BCQ no-load seed 3" "BCQ no-load-size seed 3"
mkdir -p $D/compare && cp runs/grid_size_expert_bcq/compare/{paired.md,seeds.md,stages.md} $D/compare/
