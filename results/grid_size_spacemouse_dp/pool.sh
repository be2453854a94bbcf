#!/bin/bash
# Pairs spacemouse Diffusion Policy `no-load-size` seed 1 (this folder: pauses cut), bowl by bowl, with seed 1 of
# spacemouse BC, BC-RNN and BCQ on the same observations and demos (../grid_size_spacemouse_bc/,
# ../grid_size_spacemouse_bcrnn/, ../grid_size_spacemouse_bcq_intel/: recorded with the same seeds on the same Intel hosts, the same piles),
# with the spacemouse operator that recorded its demos (../grid_mended_operators/) and with expert Diffusion Policy
# seed 1 (../grid_size_expert_dp/: VR-like against 3D-mouse data, the paper's claim): compare/paired.md.
# Reads only committed files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
S="spacemouse Diffusion Policy no-load-size obs no-noops"
A=(--agent "spacemouse DP seed 1=results/grid_size_spacemouse_dp/results.json:$S")
A+=(--agent "spacemouse BC seed 1=results/grid_size_spacemouse_bc/results.json:spacemouse BC no-load-size obs no-noops seed 1")
A+=(--agent "spacemouse BC-RNN seed 1=results/grid_size_spacemouse_bcrnn/results.json:spacemouse BC-RNN no-load-size obs no-noops seed 1")
A+=(--agent "spacemouse BCQ seed 1=results/grid_size_spacemouse_bcq_intel/results.json:spacemouse BCQ no-load-size obs no-noops seed 1")
A+=(--agent "spacemouse operator=results/grid_mended_operators/results.json:spacemouse operator")
A+=(--agent "expert DP seed 1=results/grid_size_expert_dp/results.json:expert Diffusion Policy no-load-size obs")
rm -rf runs/grid_size_spacemouse_dp
veragmil-pool-results runs/grid_size_spacemouse_dp/compare "${A[@]}" \
  --paired "spacemouse BC seed 1" "spacemouse DP seed 1" --paired "spacemouse BC-RNN seed 1" "spacemouse DP seed 1" \
  --paired "spacemouse BCQ seed 1" "spacemouse DP seed 1" --paired "spacemouse operator" "spacemouse DP seed 1" \
  --paired "spacemouse DP seed 1" "expert DP seed 1"
mkdir -p results/grid_size_spacemouse_dp/compare
cp runs/grid_size_spacemouse_dp/compare/{paired.md,stages.md,table.md} results/grid_size_spacemouse_dp/compare/
