#!/bin/bash
# Pairs each seed of the study (runs/size_expert_bc: BC on `no-load-size`), bowl by bowl, with the same seed trained
# on `no-load` from the same demos (../grid_mended_expert_bc/: the recordings hold the same actions, the new one adds
# piece_size), and with the expert operator on the same piles (../grid_mended_operators/): compare/paired.md. Run from
# the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_size_expert_bc
N=results/grid_mended_expert_bc/results.json
Z=results/grid_size_expert_bc/results.json
P=results/grid_mended_operators/results.json
A="expert BC no-load obs seed"
B="expert BC no-load-size obs seed"
rm -rf runs/grid_size_expert_bc
veragmil-pool-results runs/grid_size_expert_bc/compare \
  --agent "no-load seed 1=$N:$A 1" --agent "no-load seed 2=$N:$A 2" --agent "no-load seed 3=$N:$A 3" \
  --agent "no-load-size seed 1=$Z:$B 1" --agent "no-load-size seed 2=$Z:$B 2" --agent "no-load-size seed 3=$Z:$B 3" \
  --agent "$P:expert operator" \
  --paired "no-load" "no-load-size" --paired "no-load seed 1" "no-load-size seed 1" \
  --paired "no-load seed 2" "no-load-size seed 2" --paired "no-load seed 3" "no-load-size seed 3" \
  --paired "expert operator" "no-load-size seed 1" --paired "expert operator" "no-load-size seed 2" \
  --paired "expert operator" "no-load-size seed 3"
mkdir -p $D/compare && cp runs/grid_size_expert_bc/compare/{paired.md,seeds.md,stages.md} $D/compare/
