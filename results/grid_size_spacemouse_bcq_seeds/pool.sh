#!/bin/bash
# Pools spacemouse BCQ `no-load-size` seed 1 (../grid_size_spacemouse_bcq/, session 68), seed 2 (this folder's
# results.json as session 70 committed it, f94fd56: its study's eval/ was overwritten by seed 3's) and seed 3
# (runs/size_sm_bcq, session 71), all recorded and scored on AMD EPYC hosts' piles, into
# runs/grid_size_spacemouse_bcq_seeds (then published here: RUN.md). Run from the repository root after seed 3's study.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
M="spacemouse BCQ no-load-size obs no-noops"
rm -rf runs/grid_size_spacemouse_bcq_seeds
mkdir -p runs/grid_size_spacemouse_bcq_seeds
SEED2=runs/grid_size_spacemouse_bcq_seeds/seed2_results.json
git show f94fd56:results/grid_size_spacemouse_bcq_seeds/results.json > "$SEED2"
veragmil-pool-results runs/grid_size_spacemouse_bcq_seeds/eval \
  --agent "$M seed 1=results/grid_size_spacemouse_bcq/results.json:$M" \
  --agent "$M seed 2=$SEED2:$M seed 2" \
  --agent "$M seed 3=runs/size_sm_bcq/eval/results.json:$M"
