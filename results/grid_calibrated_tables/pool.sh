#!/bin/bash
# Pools every model of the calibrated grid (the `no-load` observations, the task's spill rule, the grid's 20 bowls
# per food) from the committed results.json of the folders that scored them, then shapes the pooled tables like the
# paper's. Run from the repository root: bash results/grid_calibrated_tables/pool.sh
set -euo pipefail
R=results
OUT=runs/grid_calibrated_tables/eval
A=(--agent "expert operator=$R/grid_calibrated_noload/results.json:expert operator")
for s in 1 2 3; do
  A+=(--agent "expert BC no-load obs seed $s=$R/grid_calibrated_noload/results.json:expert BC no-load obs seed $s")
  A+=(--agent "expert BC-RNN no-load obs seed $s=$R/grid_calibrated_bcrnn_seeds/results.json:expert BC-RNN no-load obs seed $s")
  A+=(--agent "expert BCQ no-load obs seed $s=$R/grid_calibrated_bcq/results.json:expert BCQ no-load obs seed $s")
done
for s in 1 2; do
  A+=(--agent "expert Diffusion Policy no-load obs seed $s=$R/grid_calibrated_diffusion_seeds/results.json:expert Diffusion Policy no-load obs seed $s")
done
A+=(--agent "spacemouse operator=$R/grid_calibrated_spacemouse/results.json:spacemouse operator")
for s in 1 2 3; do
  A+=(--agent "spacemouse BC no-load obs seed $s=$R/grid_calibrated_spacemouse_noload/results.json:spacemouse BC no-load obs seed $s")
done
for s in $(python -c "import json; print(' '.join(a.rsplit(' ', 1)[1] for a in json.load(open('$R/grid_calibrated_spacemouse_bcq/results.json'))['config']['agents']))"); do
  A+=(--agent "spacemouse BCQ no-load obs seed $s=$R/grid_calibrated_spacemouse_bcq/results.json:spacemouse BCQ no-load obs seed $s")
done
for s in $(python -c "import json; print(' '.join(a.rsplit(' ', 1)[1] for a in json.load(open('$R/grid_calibrated_spacemouse_bcrnn/results.json'))['config']['agents']))"); do
  A+=(--agent "spacemouse BC-RNN no-load obs seed $s=$R/grid_calibrated_spacemouse_bcrnn/results.json:spacemouse BC-RNN no-load obs seed $s")
done
veragmil-pool-results "$OUT" "${A[@]}"
python results/grid_calibrated_tables/paper_tables.py "$OUT/seeds/table.csv" > results/grid_calibrated_tables/paper_tables.md
cp -r "$OUT"/{table.md,table.csv,stages.md,stages.csv,seeds.md,seeds.csv,success.png,seeds} results/grid_calibrated_tables/
