#!/bin/bash
# Pairs the study's BCQ seeds (runs/mended_sm_bcq_cut_rot), bowl by bowl, with BC's same seeds on the same data and
# observations (../grid_mended_spacemouse_bc_noops_rot/) and with BCQ's same seeds on the old-start recording's cut
# data without the orientation error (../grid_calibrated_spacemouse_bcq_noops/): compare/paired.md. Run from the
# repository root after the study's command (RUN.md).
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
D=results/grid_mended_spacemouse_bcq_noops_rot
R=$D/results.json
B=results/grid_mended_spacemouse_bc_noops_rot/results.json
O=results/grid_calibrated_spacemouse_bcq_noops/results.json
args=()
for s in 1 2 3; do
  args+=(--agent "BC seed $s=$B:spacemouse BC no-load-rot obs no-noops seed $s")
  args+=(--agent "BCQ seed $s=$R:spacemouse BCQ no-load-rot obs no-noops seed $s")
  args+=(--agent "BCQ old start, no-load seed $s=$O:spacemouse BCQ no-load obs no-noops seed $s")
  args+=(--paired "BC seed $s" "BCQ seed $s" --paired "BCQ old start, no-load seed $s" "BCQ seed $s")
done
args+=(--paired "BC" "BCQ" --paired "BCQ old start, no-load" "BCQ")  # the three seeds together
rm -rf runs/grid_mended_spacemouse_bcq_noops_rot
veragmil-pool-results runs/grid_mended_spacemouse_bcq_noops_rot/compare "${args[@]}"
mkdir -p $D/compare && cp runs/grid_mended_spacemouse_bcq_noops_rot/compare/{paired.md,stages.md} $D/compare/
