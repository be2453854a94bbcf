#!/bin/bash
# Pairs each seed of the study (runs/size_sm_bc: spacemouse BC on `no-load-size`, pauses cut), bowl by bowl, with the
# same seed on the cut data observing the turn instead of the size (../grid_mended_spacemouse_bc_noops_rot/: pasta on
# 40 iterations there), with expert BC on `no-load-size` (../grid_size_expert_bc/: VR-like against 3D-mouse data, the
# paper's claim) and with the spacemouse operator on the same piles (../grid_mended_operators/): compare/paired.md.
# Run from the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_spacemouse_bc
Z=$D/results.json
R=results/grid_mended_spacemouse_bc_noops_rot/results.json
E=results/grid_size_expert_bc/results.json
P=results/grid_mended_operators/results.json
args=(--agent "$P:spacemouse operator")
for s in 1 2 3; do
  args+=(--agent "no-load-rot seed $s=$R:spacemouse BC no-load-rot obs no-noops seed $s")
  args+=(--agent "no-load-size seed $s=$Z:spacemouse BC no-load-size obs no-noops seed $s")
  args+=(--agent "expert data seed $s=$E:expert BC no-load-size obs seed $s")
  args+=(--paired "no-load-rot seed $s" "no-load-size seed $s" --paired "no-load-size seed $s" "expert data seed $s")
  args+=(--paired "spacemouse operator" "no-load-size seed $s")
done
args+=(--paired "no-load-rot" "no-load-size" --paired "no-load-size" "expert data")  # the three seeds together
rm -rf runs/grid_size_spacemouse_bc
veragmil-pool-results runs/grid_size_spacemouse_bc/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_size_spacemouse_bc/compare/{paired.md,seeds.md,stages.md} $D/compare/
