"""The standard lifting cylinder with the grains' module-level contact and body constants changed: the levers
grain_shape_probe.py (GrainModel fields, solver) does not reach.

    python results/calibration/exploration/heap_levers_probe.py rice --set grains.GRAIN_MIN_INERTIA_FACTOR=0.1 \
        --set grains.GRAIN_SPIN_DECAY_PER_S=100 [--changes '{"friction": 0.7}'] [--solver '{"iterations": "60"}'] \
        --cyl-seeds 0,1 [--slope]

``--set module.NAME=value`` sets a constant of ``veragmil_suite.models.<module>`` (a tuple as ``a,b,c``).
"""

import argparse
import json
import time
from dataclasses import replace

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.lifting_cylinder import lifting_cylinder
from veragmil_suite.calibration.slope import slope_travel_m
from veragmil_suite.models import foods, grains, scoop_task

MODULES = {"grains": grains, "foods": foods}

parser = argparse.ArgumentParser()
parser.add_argument("food")
parser.add_argument("--set", action="append", default=[], metavar="MODULE.NAME=VALUE")
parser.add_argument("--changes", default="{}", help="GrainModel fields (JSON)")
parser.add_argument("--solver", default=None, help="physics_solver_options changes (JSON)")
parser.add_argument("--cyl-seeds", default="0,1")
parser.add_argument("--scale", type=float, default=1.0)
parser.add_argument("--slope", action="store_true", help="also one grain on 5 and 8 degree slopes (2 s)")
args = parser.parse_args()

for item in args.set:
    dotted, value = item.split("=", 1)
    module, name = dotted.split(".")
    parsed = tuple(float(v) for v in value.split(",")) if "," in value else float(value)
    getattr(MODULES[module], name)  # the constant must exist
    setattr(MODULES[module], name, parsed)
changes = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(args.changes).items()}
spec = foods.FOODS[args.food]
spec = replace(spec, calibrated=replace(spec.calibrated, **changes))
foods.FOODS[args.food] = spec
solver = {**scoop_task.PHYSICS_SOLVER_OPTIONS["calibrated"], **(json.loads(args.solver) if args.solver else {})}
print(f"# {args.food} set {args.set} changes {changes} solver {solver}", flush=True)
if args.slope:
    for deg in (5.0, 8.0):
        print(f"slope {deg:.0f} deg: {1000 * slope_travel_m(spec, 'calibrated', deg):.3f} mm in 2 s", flush=True)
for cyl_seed in [int(x) for x in args.cyl_seeds.split(",")]:
    t = time.time()
    d = lifting_cylinder(spec, "calibrated", seed=cyl_seed, solver_options=solver, scale=args.scale).as_dict()
    print(
        f"cylinder {args.scale}x seed {cyl_seed}: fit {d['angle_slope_fit_deg']:.1f} h/b {d['angle_height_base_deg']:.1f} "
        f"bulk {d['bulk_density_g_cm3']:.2f} packing {d['packing_fraction']:.2f} settled {d['settled']} "
        f"escaped {d['escaped_fast']} sim {d['sim_time_s']:.1f} s wall {time.time() - t:.0f} s",
        flush=True,
    )
