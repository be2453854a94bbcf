#!/bin/bash
# Pairs each training seed of spacemouse BC-RNN `no-load-size` (this folder: pauses cut), bowl by bowl, with the same
# seed of spacemouse BC on the same recipe (../grid_size_spacemouse_bc/: the algorithm on 3D-mouse data), of expert
# BC-RNN (../grid_size_expert_bcrnn/: VR-like against 3D-mouse data, the paper's claim) and with the spacemouse
# operator that recorded its demos (../grid_mended_operators/), all on the Intel hosts' piles: compare/paired.md.
# Reads only committed files; run from the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_spacemouse_bcrnn
B=results/grid_size_spacemouse_bc/results.json
E=results/grid_size_expert_bcrnn/results.json
args=(--agent "spacemouse operator=results/grid_mended_operators/results.json:spacemouse operator")
for s in 1 2 3; do
  args+=(--agent "spacemouse BC-RNN seed $s=$D/results.json:spacemouse BC-RNN no-load-size obs no-noops seed $s")
  args+=(--agent "spacemouse BC seed $s=$B:spacemouse BC no-load-size obs no-noops seed $s")
  args+=(--agent "expert BC-RNN seed $s=$E:expert BC-RNN no-load-size obs seed $s")
  args+=(--paired "spacemouse BC seed $s" "spacemouse BC-RNN seed $s")
  args+=(--paired "spacemouse BC-RNN seed $s" "expert BC-RNN seed $s")
  args+=(--paired "spacemouse operator" "spacemouse BC-RNN seed $s")
done
args+=(--paired "spacemouse BC" "spacemouse BC-RNN" --paired "spacemouse BC-RNN" "expert BC-RNN")  # the seeds together
rm -rf runs/grid_size_spacemouse_bcrnn
veragmil-pool-results runs/grid_size_spacemouse_bcrnn/compare "${args[@]}"
mkdir -p $D/compare && rm -f $D/compare/*.md && cp runs/grid_size_spacemouse_bcrnn/compare/{paired.md,seeds.md,stages.md,table.md} $D/compare/
