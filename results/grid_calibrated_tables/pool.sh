#!/bin/bash
# Pools every model of the calibrated grid (the `no-load` observations, the task's spill rule, the grid's 20 bowls
# per food) from the committed results.json of the folders that scored them, then shapes the pooled tables like the
# paper's. Run from the repository root: bash results/grid_calibrated_tables/pool.sh
set -euo pipefail
source results/grid_calibrated_tables/pool_tables.sh  # add FOLDER MODEL, pool_tables NAME
add grid_calibrated_noload "expert operator"
add grid_calibrated_noload "expert BC no-load obs"
add grid_calibrated_bcrnn_50k_seeds "expert BC-RNN no-load obs"
add grid_calibrated_bcq "expert BCQ no-load obs"
add grid_calibrated_diffusion_seeds "expert Diffusion Policy no-load obs"
add grid_calibrated_spacemouse "spacemouse operator"
add grid_calibrated_spacemouse_noload "spacemouse BC no-load obs"
add grid_calibrated_spacemouse_bcq "spacemouse BCQ no-load obs"
add grid_calibrated_spacemouse_bcrnn "spacemouse BC-RNN no-load obs"
add grid_calibrated_diffusion_9k "expert Diffusion Policy no-load obs"
add grid_calibrated_diffusion_9k "spacemouse Diffusion Policy no-load obs"
# the paper's questions bowl by bowl, seed by seed (paired.md): VR-like against 3D-mouse data for each algorithm and
# the operators, then the paper's order of algorithms on the expert data
for model in operator "BC no-load obs" "BCQ no-load obs" "BC-RNN no-load obs" "Diffusion Policy no-load obs"; do
  P+=(--paired "spacemouse $model" "expert $model")
done
for model in "BC-RNN no-load obs" "BCQ no-load obs" "Diffusion Policy no-load obs"; do
  P+=(--paired "expert BC no-load obs" "expert $model")
done
pool_tables grid_calibrated_tables
