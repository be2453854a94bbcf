#!/bin/bash
# Pairs each seed of the study (runs/mended_expert_bcq), bowl by bowl, with the same seed trained on the recording made
# before the start mend (../grid_calibrated_bcq/) and with BC's same seed on the same mended recording
# (../grid_mended_expert_bc/): compare/paired.md. Run from the repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_expert_bcq
O=results/grid_calibrated_bcq/results.json
M=results/grid_mended_expert_bcq/results.json
B=results/grid_mended_expert_bc/results.json
A="expert BCQ no-load obs seed"
rm -rf runs/grid_mended_expert_bcq
veragmil-pool-results runs/grid_mended_expert_bcq/compare \
  --agent "old start seed 1=$O:$A 1" --agent "old start seed 2=$O:$A 2" --agent "old start seed 3=$O:$A 3" \
  --agent "mended start seed 1=$M:$A 1" --agent "mended start seed 2=$M:$A 2" --agent "mended start seed 3=$M:$A 3" \
  --agent "BC seed 1=$B:expert BC no-load obs seed 1" --agent "BC seed 2=$B:expert BC no-load obs seed 2" \
  --agent "BC seed 3=$B:expert BC no-load obs seed 3" \
  --paired "old start" "mended start" --paired "old start seed 1" "mended start seed 1" \
  --paired "old start seed 2" "mended start seed 2" --paired "old start seed 3" "mended start seed 3" \
  --paired "BC" "mended start"
mkdir -p $D/compare && cp runs/grid_mended_expert_bcq/compare/{paired.md,seeds.md,stages.md} $D/compare/
