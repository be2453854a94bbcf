#!/bin/bash
# Pairs expert BC-RNN `no-load-size` seed 1 (this folder), bowl by bowl, with expert BC and BCQ on the same
# observations and demos (../grid_size_expert_bc/, ../grid_size_expert_bcq/: the same seeds' recording, the same Intel
# hosts' piles) and with the expert operator (../grid_mended_operators/): compare/paired.md. Reads only committed
# files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
R="expert BC-RNN no-load-size obs"
B="expert BC no-load-size obs seed"
Q="expert BCQ no-load-size obs seed"
rm -rf runs/grid_size_expert_bcrnn
veragmil-pool-results runs/grid_size_expert_bcrnn/compare \
  --agent "BC-RNN seed 1=results/grid_size_expert_bcrnn/results.json:$R" \
  --agent "BC seed 1=results/grid_size_expert_bc/results.json:$B 1" \
  --agent "BC seed 2=results/grid_size_expert_bc/results.json:$B 2" \
  --agent "BC seed 3=results/grid_size_expert_bc/results.json:$B 3" \
  --agent "BCQ seed 1=results/grid_size_expert_bcq/results.json:$Q 1" \
  --agent "expert operator=results/grid_mended_operators/results.json:expert operator" \
  --paired "BC seed 1" "BC-RNN seed 1" --paired "BC seed 2" "BC-RNN seed 1" --paired "BC seed 3" "BC-RNN seed 1" \
  --paired "BCQ seed 1" "BC-RNN seed 1" --paired "expert operator" "BC-RNN seed 1"
mkdir -p results/grid_size_expert_bcrnn/compare
cp runs/grid_size_expert_bcrnn/compare/{paired.md,stages.md,table.md} results/grid_size_expert_bcrnn/compare/
