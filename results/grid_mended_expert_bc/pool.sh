#!/bin/bash
# Pairs each seed of the study (runs/mended_expert_bc), bowl by bowl, with the same seed trained on the recording made
# before the start mend (../grid_calibrated_noload/; its peas and flakes on 40 solver iterations, so only its seen foods
# compare), and the expert operator on the same piles (../grid_mended_operators/): compare/paired.md. Run from the
# repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_expert_bc
O=results/grid_calibrated_noload/results.json
M=results/grid_mended_expert_bc/results.json
P=results/grid_mended_operators/results.json
A="expert BC no-load obs seed"
rm -rf runs/grid_mended_expert_bc
veragmil-pool-results runs/grid_mended_expert_bc/compare \
  --agent "old start seed 1=$O:$A 1" --agent "old start seed 2=$O:$A 2" --agent "old start seed 3=$O:$A 3" \
  --agent "mended start seed 1=$M:$A 1" --agent "mended start seed 2=$M:$A 2" --agent "mended start seed 3=$M:$A 3" \
  --agent "$P:expert operator" \
  --paired "old start" "mended start" --paired "old start seed 1" "mended start seed 1" \
  --paired "old start seed 2" "mended start seed 2" --paired "old start seed 3" "mended start seed 3" \
  --paired "expert operator" "mended start seed 1" --paired "expert operator" "mended start seed 2" \
  --paired "expert operator" "mended start seed 3"
mkdir -p $D/compare && cp runs/grid_mended_expert_bc/compare/{paired.md,seeds.md,stages.md} $D/compare/
# the paper's central question on the mended recordings: expert data against the spacemouse data (its pauses cut, the
# orientation observed: ../grid_mended_spacemouse_bc_noops_rot/), BC seed by seed on the same bowls: profiles/paired.md
S=results/grid_mended_spacemouse_bc_noops_rot/results.json
B="spacemouse BC no-load-rot obs no-noops seed"
veragmil-pool-results runs/grid_mended_expert_bc/profiles \
  --agent "expert BC seed 1=$M:$A 1" --agent "expert BC seed 2=$M:$A 2" --agent "expert BC seed 3=$M:$A 3" \
  --agent "spacemouse BC seed 1=$S:$B 1" --agent "spacemouse BC seed 2=$S:$B 2" --agent "spacemouse BC seed 3=$S:$B 3" \
  --paired "spacemouse BC" "expert BC"
mkdir -p $D/profiles && cp runs/grid_mended_expert_bc/profiles/paired.md $D/profiles/
