"""One grain on a tilted plane, on the scene the benchmark uses: how far it creeps on gentle slopes (the package's
slope test, 2 s and 6 s) and from which angle it rolls when it lies across the slope, with rolling friction added.

    python results/calibration/exploration/slope_roll_probe.py rice,barley --rolling 0,0.00025,0.0005,0.001
    python results/calibration/exploration/slope_roll_probe.py --creep
"""

import argparse
import math
from dataclasses import replace

import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.slope import slope_travel_m
from veragmil_suite.models import foods

CREEP_CASES = [("rice", 8.0), ("barley", 8.0), ("buckwheat", 8.0), ("peas", 5.0), ("beans", 8.0), ("pasta", 8.0),
               ("flakes", 8.0)]  # fmt: skip


parser = argparse.ArgumentParser()
parser.add_argument("foods", nargs="?", default="rice,barley")
parser.add_argument("--rolling", default="0", help="rolling friction lengths (m), comma-separated; torsion is twice")
parser.add_argument("--degrees", default="14,16,18,20,22,24,26,28")
parser.add_argument("--along", action="store_true", help="the long axis along the slope instead of across")
parser.add_argument("--creep", action="store_true", help="the package's slope test on every food, 2 s and 6 s")
args = parser.parse_args()

if args.creep:
    for food, deg in CREEP_CASES:
        for physics in ("calibrated", "table1"):
            spec = foods.FOODS[food]
            friction = math.degrees(math.atan(spec.grain(physics).friction))
            cells = [f"{1000 * slope_travel_m(spec, physics, deg, duration_s=d):.3f}" for d in (2.0, 6.0)]
            where = f"{food} {physics} {deg:.0f} deg (friction angle {friction:.1f})"
            print(f"{where}: {cells[0]} mm in 2 s, {cells[1]} in 6 s", flush=True)
else:
    for food in args.foods.split(","):
        base = foods.FOODS[food]
        for rolling in (float(r) for r in args.rolling.split(",")):
            grain = replace(base.grain("calibrated"), rolling_friction_m=rolling, torsional_friction_m=2 * rolling)
            spec = replace(base, calibrated=grain)
            cells = []
            for deg in (float(d) for d in args.degrees.split(",")):
                travel = np.mean([slope_travel_m(spec, "calibrated", deg, seed=s, along=args.along) for s in (0, 1)])
                cells.append(f"{deg:.0f}:{1000 * travel:.1f}")
            side = "along" if args.along else "across"
            print(
                f"{food} {side}, rolling {1000 * rolling:.2f} mm: " + " ".join(cells) + " (deg:mm in 2 s)", flush=True
            )
