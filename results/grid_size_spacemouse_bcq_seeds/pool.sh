#!/bin/bash
# Pools spacemouse BCQ `no-load-size` seed 1 (../grid_size_spacemouse_bcq/, session 68) with seed 2 (runs/size_sm_bcq,
# session 70), both recorded and scored on AMD EPYC hosts' piles, into runs/grid_size_spacemouse_bcq_seeds (then
# published here: RUN.md). Run from the repository root after seed 2's study.
set -euo pipefail
export PATH=$PWD/.venv/bin:$PATH
M="spacemouse BCQ no-load-size obs no-noops"
rm -rf runs/grid_size_spacemouse_bcq_seeds
veragmil-pool-results runs/grid_size_spacemouse_bcq_seeds/eval \
  --agent "$M seed 1=results/grid_size_spacemouse_bcq/results.json:$M" \
  --agent "$M seed 2=runs/size_sm_bcq/eval/results.json:$M"
