"""Where the scripted expert's spoon rises out of the pile in a recording: the eef's x from the bowl rim's centre (mm;
+x away from the robot) when it first climbs back past 5 mm below the rim after its deepest point, per food.
Run from the repository root: python results/grid_size_expert_bc/probe/lift_x.py <folder of per-food recordings>"""

import sys
from pathlib import Path

import h5py
import numpy as np

for path in sorted(Path(sys.argv[1]).glob("*.hdf5")):
    xs = []
    with h5py.File(path) as f:
        for name in f["data"]:
            obs = f[f"data/{name}/obs"]
            rel = obs["robot0_eef_pos"][()] - obs["bowl_pos"][()]
            deepest = int(np.argmin(rel[:, 2]))
            up = deepest + int(np.argmax(rel[deepest:, 2] > -0.005))
            xs.append(1000 * rel[up, 0])
    q = np.percentile(xs, [0, 25, 50, 75, 100]).round(1).tolist()
    print(f"{path.stem}: {len(xs)} demos, x at the lift (min, quartiles, max) {q}")
