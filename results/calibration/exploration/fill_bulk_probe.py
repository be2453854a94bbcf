"""Bulk density of the lifting cylinder's poured fill alone (the benchmark's bulk column), without the lift or the
spoonful:

    python results/calibration/exploration/fill_bulk_probe.py FOOD TUBE_SCALE [SEED]
"""

import sys
import time

import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.lifting_cylinder import fill_tube
from veragmil_suite.models.foods import FOODS

food, scale = sys.argv[1], float(sys.argv[2])
seed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
start = time.time()
fill = fill_tube(FOODS[food], "calibrated", scale=scale, seed=seed, max_settle_s=4.0 if scale < 1 else 8.0)
mass = fill.model.body_mass[fill.ids]
print(
    f"{food} scale {scale} seed {seed}: {len(fill.ids)} grains in a {fill.radius_m * 1000:.0f} mm tube, "
    f"fill {fill.fill_height_m * 1000:.1f} mm, bulk {fill.bulk_density_g_cm3:.3f} g/cm3, packing "
    f"{fill.packing_fraction:.2f}, grain {1e6 * mass.mean():.0f} mg, at rest {fill.rested}, escaped "
    f"{fill.escaped_fast}, sim {fill.data.time:.1f} s, wall {time.time() - start:.0f} s",
    flush=True,
)
pos = fill.data.xpos[fill.ids]
outside = int(((pos[:, 2] < 0) | (np.hypot(pos[:, 0], pos[:, 1]) > fill.radius_m + 0.005)).sum())
print(
    f"  grains below the support or outside the tube: {outside} of {len(fill.ids)}; stack top at the start "
    f"{fill.tube_height_m:.2f} m"
)
