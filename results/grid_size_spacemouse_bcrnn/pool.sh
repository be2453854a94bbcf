#!/bin/bash
# Pairs spacemouse BC-RNN `no-load-size` (this folder: pauses cut, training seed 1), bowl by bowl, with the same seed
# of spacemouse BC on the same recipe (../grid_size_spacemouse_bc/: the algorithm on 3D-mouse data), of expert BC-RNN
# (../grid_size_expert_bcrnn/: VR-like against 3D-mouse data, the paper's claim) and with the spacemouse operator that
# recorded its demos (../grid_mended_operators/), all on the Intel hosts' piles: compare/paired.md. Reads only
# committed files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_spacemouse_bcrnn
args=(--agent "spacemouse BC-RNN seed 1=$D/results.json:spacemouse BC-RNN no-load-size obs no-noops")
args+=(--agent "spacemouse BC seed 1=results/grid_size_spacemouse_bc/results.json:spacemouse BC no-load-size obs no-noops seed 1")
args+=(--agent "expert BC-RNN seed 1=results/grid_size_expert_bcrnn/results.json:expert BC-RNN no-load-size obs seed 1")
args+=(--agent "spacemouse operator=results/grid_mended_operators/results.json:spacemouse operator")
args+=(--paired "spacemouse BC" "spacemouse BC-RNN" --paired "spacemouse BC-RNN" "expert BC-RNN")
args+=(--paired "spacemouse operator" "spacemouse BC-RNN seed 1")
rm -rf runs/grid_size_spacemouse_bcrnn
veragmil-pool-results runs/grid_size_spacemouse_bcrnn/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_size_spacemouse_bcrnn/compare/{paired.md,stages.md,table.md} $D/compare/
