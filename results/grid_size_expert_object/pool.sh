#!/bin/bash
# Pairs the models of this folder (expert BC and Diffusion Policy with a U-Net half as wide, on `object`: grain counts
# in the observations) bowl by bowl with the same recipes' seed 1 on the observations a real robot could have, on the
# same demos and bowls: BC `no-load` (../grid_mended_expert_bc/), BC `no-load-size`, the configs' set
# (../grid_size_expert_bc/), and the small Diffusion Policy on `no-load-size` (../grid_size_expert_dps/); beside them
# expert Diffusion Policy `no-load-size` seed 1 (../grid_size_expert_dp/) and the expert operator
# (../grid_mended_operators/): compare/paired.md. Reads only committed files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_expert_object
A=(--agent "expert BC object obs=$D/results.json:expert BC object obs")
A+=(--agent "expert DP small object obs=$D/results.json:expert Diffusion Policy small U-Net object obs")
A+=(--agent "expert BC no-load obs=results/grid_mended_expert_bc/results.json:expert BC no-load obs seed 1")
A+=(--agent "expert BC no-load-size obs=results/grid_size_expert_bc/results.json:expert BC no-load-size obs seed 1")
A+=(--agent "expert DP small no-load-size obs=results/grid_size_expert_dps/results.json:expert Diffusion Policy small U-Net no-load-size obs")
A+=(--agent "expert DP no-load-size obs=results/grid_size_expert_dp/results.json:expert Diffusion Policy no-load-size obs seed 1")
A+=(--agent "expert operator=results/grid_mended_operators/results.json:expert operator")
A+=(--paired "expert BC object obs" "expert BC no-load obs" --paired "expert BC object obs" "expert BC no-load-size obs")
A+=(--paired "expert DP small object obs" "expert DP small no-load-size obs")
A+=(--paired "expert BC object obs" "expert DP small object obs")
rm -rf runs/grid_size_expert_object
veragmil-pool-results runs/grid_size_expert_object/compare "${A[@]}"
mkdir -p $D/compare
cp runs/grid_size_expert_object/compare/{paired.md,stages.md,table.md} $D/compare/
