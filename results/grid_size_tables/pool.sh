#!/bin/bash
# Pools the grid's models on the configs' observations (`no-load-size`: the spoon's pose, the bowl's position, the
# desired pose and the size of the food's pieces) and the scripted operators, from the committed results.json of the
# folders that scored them, then shapes the pooled tables like the paper's. Mended recordings (demos that start as
# evaluations do), pasta, peas and flakes on 100 solver iterations, the spacemouse data's pauses cut (`--drop-noops`).
# The grid's 20 bowls per food, the task's spill rule. Run from the repository root:
#   bash results/grid_size_tables/pool.sh
set -euo pipefail
source results/grid_calibrated_tables/pool_tables.sh  # add FOLDER MODEL, pool_tables NAME
add grid_mended_operators "expert operator"
add grid_size_expert_bc "expert BC no-load-size obs"
add grid_size_expert_bcq "expert BCQ no-load-size obs"
add grid_size_expert_bcrnn "expert BC-RNN no-load-size obs"  # training seeds 1-3
add grid_size_expert_dp "expert Diffusion Policy no-load-size obs"  # training seeds 1-3 (CPU-trained)
add grid_mended_operators "spacemouse operator"
add grid_size_spacemouse_bc "spacemouse BC no-load-size obs no-noops"
add grid_size_spacemouse_bcrnn "spacemouse BC-RNN no-load-size obs no-noops"  # training seeds 1-3
add grid_size_spacemouse_bcq_intel "spacemouse BCQ no-load-size obs no-noops"
add grid_size_spacemouse_dp "spacemouse Diffusion Policy no-load-size obs no-noops"  # training seeds 1-3 (CPU-trained)
# the paper's questions bowl by bowl, seed by seed (paired.md): VR-like against 3D-mouse data for each algorithm and
# the operators, then the paper's order of algorithms on the expert data and on the spacemouse data
P+=(--paired "spacemouse operator" "expert operator")
P+=(--paired "spacemouse BC no-load-size obs no-noops" "expert BC no-load-size obs")
P+=(--paired "spacemouse BC-RNN no-load-size obs no-noops" "expert BC-RNN no-load-size obs")
P+=(--paired "spacemouse BCQ no-load-size obs no-noops" "expert BCQ no-load-size obs")
P+=(--paired "spacemouse Diffusion Policy no-load-size obs no-noops" "expert Diffusion Policy no-load-size obs")
P+=(--paired "expert BC no-load-size obs" "expert BCQ no-load-size obs")
P+=(--paired "expert BC no-load-size obs" "expert BC-RNN no-load-size obs")
P+=(--paired "expert BC no-load-size obs" "expert Diffusion Policy no-load-size obs")
P+=(--paired "expert BC-RNN no-load-size obs" "expert Diffusion Policy no-load-size obs")
P+=(--paired "expert BCQ no-load-size obs" "expert Diffusion Policy no-load-size obs")
P+=(--paired "spacemouse BC no-load-size obs no-noops" "spacemouse BC-RNN no-load-size obs no-noops")
P+=(--paired "spacemouse BC no-load-size obs no-noops" "spacemouse BCQ no-load-size obs no-noops")
P+=(--paired "spacemouse BC no-load-size obs no-noops" "spacemouse Diffusion Policy no-load-size obs no-noops")
P+=(--paired "spacemouse BC-RNN no-load-size obs no-noops" "spacemouse Diffusion Policy no-load-size obs no-noops")
P+=(--paired "spacemouse BCQ no-load-size obs no-noops" "spacemouse Diffusion Policy no-load-size obs no-noops")
pool_tables grid_size_tables
