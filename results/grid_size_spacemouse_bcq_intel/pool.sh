#!/bin/bash
# Pairs spacemouse BCQ `no-load-size` on Intel hosts' piles (this folder: pauses cut), bowl by bowl and seed by seed,
# with spacemouse BC on the same recipe (../grid_size_spacemouse_bc/: the paper's BCQ > BC on 3D-mouse data), with
# expert BCQ (../grid_size_expert_bcq/: VR-like against 3D-mouse data), and with the spacemouse operator that recorded
# its demos (../grid_mended_operators/), all on the same piles: compare/paired.md. Reads only committed files; run from
# the repository root.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_spacemouse_bcq_intel
args=(--agent "spacemouse operator=results/grid_mended_operators/results.json:spacemouse operator")
for s in 1 2 3; do
  args+=(--agent "spacemouse BCQ seed $s=$D/results.json:spacemouse BCQ no-load-size obs no-noops seed $s")
  args+=(--agent "spacemouse BC seed $s=results/grid_size_spacemouse_bc/results.json:spacemouse BC no-load-size obs no-noops seed $s")
  args+=(--agent "expert BCQ seed $s=results/grid_size_expert_bcq/results.json:expert BCQ no-load-size obs seed $s")
  args+=(--paired "spacemouse operator" "spacemouse BCQ seed $s")
done
args+=(--paired "spacemouse BC" "spacemouse BCQ" --paired "spacemouse BCQ" "expert BCQ")
rm -rf runs/grid_size_spacemouse_bcq_intel
veragmil-pool-results runs/grid_size_spacemouse_bcq_intel/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_size_spacemouse_bcq_intel/compare/{paired.md,stages.md,table.md,seeds.md} $D/compare/
