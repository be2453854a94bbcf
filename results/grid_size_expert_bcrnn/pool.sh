#!/bin/bash
# Pairs expert BC-RNN `no-load-size` seeds 1-3 (this folder), bowl by bowl, with expert BC and BCQ on the same
# observations and demos (../grid_size_expert_bc/, ../grid_size_expert_bcq/: the same seeds' recording, the same Intel
# hosts' piles), seed by seed, and with the expert operator (../grid_mended_operators/): compare/paired.md. Reads only
# committed files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
A=()
for seed in 1 2 3; do
  A+=(--agent "BC-RNN seed $seed=results/grid_size_expert_bcrnn/results.json:expert BC-RNN no-load-size obs seed $seed")
done
for seed in 1 2 3; do
  A+=(--agent "BC seed $seed=results/grid_size_expert_bc/results.json:expert BC no-load-size obs seed $seed")
  A+=(--agent "BCQ seed $seed=results/grid_size_expert_bcq/results.json:expert BCQ no-load-size obs seed $seed")
done
A+=(--agent "expert operator=results/grid_mended_operators/results.json:expert operator")
rm -rf runs/grid_size_expert_bcrnn
veragmil-pool-results runs/grid_size_expert_bcrnn/compare "${A[@]}" \
  --paired "BC" "BC-RNN" --paired "BCQ" "BC-RNN" \
  --paired "expert operator" "BC-RNN seed 1" --paired "expert operator" "BC-RNN seed 2" --paired "expert operator" "BC-RNN seed 3"
mkdir -p results/grid_size_expert_bcrnn/compare
cp runs/grid_size_expert_bcrnn/compare/{paired.md,stages.md,table.md,seeds.md} results/grid_size_expert_bcrnn/compare/
