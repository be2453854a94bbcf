#!/bin/bash
# Pairs spacemouse Diffusion Policy `no-load-size` seeds 1-3 (this folder: pauses cut), seed by seed and bowl by
# bowl, with the same seed of spacemouse BC, BC-RNN and BCQ on the same observations and demos
# (../grid_size_spacemouse_bc/, ../grid_size_spacemouse_bcrnn/, ../grid_size_spacemouse_bcq_intel/: recorded with the
# same seeds, the same piles; its seed 3 on an AMD host, the others on Intel hosts), with the spacemouse operator that
# recorded its demos (../grid_mended_operators/) and with expert Diffusion Policy, seed by seed
# (../grid_size_expert_dp/: VR-like against 3D-mouse data, the paper's claim): compare/paired.md. Reads only committed
# files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
G=results/grid_size_spacemouse  # the spacemouse models' folders: ${G}_dp (this one), ${G}_bc, ...
D=${G}_dp
S="spacemouse Diffusion Policy no-load-size obs no-noops"
O="no-load-size obs no-noops"  # the other spacemouse models' label, after the algorithm
E="expert Diffusion Policy no-load-size obs"
A=(--agent "spacemouse operator=results/grid_mended_operators/results.json:spacemouse operator")
for s in 1 2 3; do
  A+=(--agent "spacemouse DP seed $s=$D/results.json:$S seed $s")
  A+=(--agent "spacemouse BC seed $s=${G}_bc/results.json:spacemouse BC $O seed $s")
  A+=(--agent "spacemouse BC-RNN seed $s=${G}_bcrnn/results.json:spacemouse BC-RNN $O seed $s")
  A+=(--agent "spacemouse BCQ seed $s=${G}_bcq_intel/results.json:spacemouse BCQ $O seed $s")
  A+=(--agent "expert DP seed $s=results/grid_size_expert_dp/results.json:$E seed $s")
  A+=(--paired "spacemouse operator" "spacemouse DP seed $s")
done
# the recipes seed by seed (every seed both have), and the seeds against each other
A+=(--paired "spacemouse BC" "spacemouse DP" --paired "spacemouse BC-RNN" "spacemouse DP")
A+=(--paired "spacemouse BCQ" "spacemouse DP" --paired "spacemouse DP" "expert DP")
A+=(--paired "spacemouse DP seed 1" "spacemouse DP seed 2" --paired "spacemouse DP seed 1" "spacemouse DP seed 3")
A+=(--paired "spacemouse DP seed 2" "spacemouse DP seed 3")
rm -rf runs/grid_size_spacemouse_dp
veragmil-pool-results runs/grid_size_spacemouse_dp/compare "${A[@]}"
mkdir -p $D/compare
cp runs/grid_size_spacemouse_dp/compare/{paired.md,seeds.md,stages.md,table.md} $D/compare/
