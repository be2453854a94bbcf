#!/bin/bash
# Pairs expert Diffusion Policy `no-load-size` seeds 1-3 (this folder), seed by seed and bowl by bowl, with the same
# seed of expert BC, BC-RNN and BCQ on the same observations and demos (../grid_size_expert_bc/,
# ../grid_size_expert_bcrnn/, ../grid_size_expert_bcq/: the same recording, the same Intel hosts' piles), with the
# expert operator (../grid_mended_operators/) and with spacemouse Diffusion Policy (../grid_size_spacemouse_dp/, its
# seeds 1-3: VR-like against 3D-mouse data, the paper's claim): compare/paired.md. Reads only committed files; run
# from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
G=results/grid_size_expert  # the expert models' folders: ${G}_dp (this one), ${G}_bc, ...
D=${G}_dp
O="no-load-size obs"  # the expert models' label, after the algorithm
M="spacemouse Diffusion Policy $O no-noops"
A=(--agent "expert operator=results/grid_mended_operators/results.json:expert operator")
for s in 1 2 3; do
  A+=(--agent "expert DP seed $s=$D/results.json:expert Diffusion Policy $O seed $s")
  A+=(--agent "expert BC seed $s=${G}_bc/results.json:expert BC $O seed $s")
  A+=(--agent "expert BC-RNN seed $s=${G}_bcrnn/results.json:expert BC-RNN $O seed $s")
  A+=(--agent "expert BCQ seed $s=${G}_bcq/results.json:expert BCQ $O seed $s")
  A+=(--paired "expert operator" "expert DP seed $s")
done
for s in 1 2 3; do
  A+=(--agent "spacemouse DP seed $s=results/grid_size_spacemouse_dp/results.json:$M seed $s")
done
# the recipes seed by seed (every seed both have), and the seeds against each other
A+=(--paired "expert BC" "expert DP" --paired "expert BC-RNN" "expert DP" --paired "expert BCQ" "expert DP")
A+=(--paired "spacemouse DP" "expert DP")
A+=(--paired "expert DP seed 1" "expert DP seed 2" --paired "expert DP seed 1" "expert DP seed 3")
A+=(--paired "expert DP seed 2" "expert DP seed 3")
rm -rf runs/grid_size_expert_dp
veragmil-pool-results runs/grid_size_expert_dp/compare "${A[@]}"
mkdir -p $D/compare
cp runs/grid_size_expert_dp/compare/{paired.md,seeds.md,stages.md,table.md} $D/compare/
