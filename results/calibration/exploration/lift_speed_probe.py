"""Is the lifting-cylinder heap a property of the grains or of the lift? The standard-size test for one food at
several lift speeds and seeds (exploration: the test's own LIFT_SPEED_M_S replaced for each run).

    python results/calibration/exploration/lift_speed_probe.py rice 0.02 0.005 --seeds 0 1
"""

import argparse
import json
import time

from veragmil_suite.calibration import lifting_cylinder as cylinder
from veragmil_suite.models.foods import DEFAULT_PHYSICS, get_food

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("food")
parser.add_argument("speeds", type=float, nargs="+", help="lift speeds, m/s")
parser.add_argument("--seeds", type=int, nargs="+", default=[0])
parser.add_argument("--physics", default=DEFAULT_PHYSICS)
args = parser.parse_args()
for speed in args.speeds:
    for seed in args.seeds:
        cylinder.LIFT_SPEED_M_S = speed
        start = time.perf_counter()
        result = cylinder.lifting_cylinder(get_food(args.food), args.physics, seed=seed)
        row = dict(food=args.food, physics=args.physics, lift_m_s=speed, seed=seed, wall_s=time.perf_counter() - start)
        row.update({k: round(v, 4) if isinstance(v, float) else v for k, v in result.as_dict().items()})
        print(json.dumps(row), flush=True)
