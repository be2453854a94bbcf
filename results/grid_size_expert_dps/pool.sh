#!/bin/bash
# Pairs expert Diffusion Policy with a U-Net half as wide (`diffusion_policy_small`, `no-load-size`, seed 1: this
# folder), bowl by bowl, with the full U-Net's seed 1 (../grid_size_expert_dp/), seed 1 of expert BC, BC-RNN and BCQ
# on the same observations (../grid_size_expert_bc/, ../grid_size_expert_bcrnn/, ../grid_size_expert_bcq/) and the
# expert operator (../grid_mended_operators/): compare/paired.md. Reads only committed files; run from the
# repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
A=(--agent "DP small seed 1=results/grid_size_expert_dps/results.json:expert Diffusion Policy small U-Net no-load-size obs")
A+=(--agent "DP seed 1=results/grid_size_expert_dp/results.json:expert Diffusion Policy no-load-size obs")
A+=(--agent "BC seed 1=results/grid_size_expert_bc/results.json:expert BC no-load-size obs seed 1")
A+=(--agent "BC-RNN seed 1=results/grid_size_expert_bcrnn/results.json:expert BC-RNN no-load-size obs seed 1")
A+=(--agent "BCQ seed 1=results/grid_size_expert_bcq/results.json:expert BCQ no-load-size obs seed 1")
A+=(--agent "expert operator=results/grid_mended_operators/results.json:expert operator")
rm -rf runs/grid_size_expert_dps
veragmil-pool-results runs/grid_size_expert_dps/compare "${A[@]}" \
  --paired "DP seed 1" "DP small seed 1" --paired "BC seed 1" "DP small seed 1" \
  --paired "BC-RNN seed 1" "DP small seed 1" --paired "BCQ seed 1" "DP small seed 1" \
  --paired "expert operator" "DP small seed 1"
mkdir -p results/grid_size_expert_dps/compare
cp runs/grid_size_expert_dps/compare/{paired.md,stages.md,table.md} results/grid_size_expert_dps/compare/
