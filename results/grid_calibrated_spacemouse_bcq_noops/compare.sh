#!/bin/bash
# The cut data's BCQ seed 1 against the full data's BCQ seed 1 (../grid_calibrated_spacemouse_bcq/), bowl by bowl:
# compare/paired.md. Run from the repository root after the study below.
set -euo pipefail
F=results/grid_calibrated_spacemouse_bcq/results.json
C=results/grid_calibrated_spacemouse_bcq_noops/results.json
veragmil-pool-results runs/grid_calibrated_spacemouse_bcq_noops/compare \
  --agent "spacemouse BCQ seed 1=$F:spacemouse BCQ no-load obs seed 1" \
  --agent "spacemouse BCQ no-noops seed 1=$C:spacemouse BCQ no-load obs no-noops" \
  --paired "spacemouse BCQ seed 1" "spacemouse BCQ no-noops seed 1"
mkdir -p results/grid_calibrated_spacemouse_bcq_noops/compare
cp runs/grid_calibrated_spacemouse_bcq_noops/compare/{paired.md,table.md,stages.md} results/grid_calibrated_spacemouse_bcq_noops/compare/
