#!/bin/bash
# Pools every model of the grid trained on the mended recordings (demos that start as evaluations do, 9f84426) from
# the committed results.json of the folders that scored them, then shapes the pooled tables like the paper's. Each
# data half's own recipe: expert data `no-load` observations; spacemouse data its pauses cut (`--drop-noops`) and
# `no-load-rot` observations (the best spacemouse recipe, ../grid_mended_spacemouse_bc_noops_rot/). The grid's 20
# bowls per food, the task's spill rule. Run from the repository root: bash results/grid_mended_tables/pool.sh
set -euo pipefail
source results/grid_calibrated_tables/pool_tables.sh  # add FOLDER MODEL, pool_tables NAME
add grid_mended_operators "expert operator"
add grid_mended_expert_bc "expert BC no-load obs"
add grid_mended_expert_bcq "expert BCQ no-load obs"
add grid_mended_operators "spacemouse operator"
add grid_mended_spacemouse_bc_noops_rot "spacemouse BC no-load-rot obs no-noops"
add grid_mended_spacemouse_bcq_noops_rot "spacemouse BCQ no-load-rot obs no-noops"
# the paper's questions bowl by bowl, seed by seed (paired.md): VR-like against 3D-mouse data for each algorithm and
# the operators, then the paper's order of algorithms on each data half
P+=(--paired "spacemouse operator" "expert operator")
P+=(--paired "spacemouse BC no-load-rot obs no-noops" "expert BC no-load obs")
P+=(--paired "spacemouse BCQ no-load-rot obs no-noops" "expert BCQ no-load obs")
P+=(--paired "expert BC no-load obs" "expert BCQ no-load obs")
P+=(--paired "spacemouse BC no-load-rot obs no-noops" "spacemouse BCQ no-load-rot obs no-noops")
pool_tables grid_mended_tables
