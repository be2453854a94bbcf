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

import mujoco
import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration import lifting_cylinder as cylinder_module
from veragmil_suite.calibration.lifting_cylinder import heap_angles, lifting_cylinder
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
parser.add_argument(
    "--watch", type=float, default=0.0, help="after the lift, print the heap's angles every 0.5 s for this many s"
)
args = parser.parse_args()

if args.watch:
    settle = cylinder_module.run_until_rest
    calls = []

    def watched(model, data, ids, max_s, min_s=0.3):
        """The heap's angles over time after the lift (the second settle), then the test's own rest rule."""
        calls.append(1)
        if len(calls) % 2 == 0:
            half = pile_half_thickness[-1]
            start = data.time
            while data.time - start < args.watch:
                mujoco.mj_step(model, data, nstep=120)
                speed = np.linalg.norm(data.cvel[ids, 3:], axis=1)
                h, b, hb, fit = heap_angles(data.xpos[ids], half, ring_width=ring[-1])
                print(
                    f"  t {data.time - start:4.1f} s: h/b {hb:4.1f} fit {fit:4.1f} height {1000 * h:4.1f} mm "
                    f"base {1000 * b:4.1f} mm fastest {1000 * speed.max():5.1f} mm/s",
                    flush=True,
                )
        return settle(model, data, ids, max_s, min_s)

    cylinder_module.run_until_rest = watched
    pile_half_thickness, ring = [], []
    grain_pile = cylinder_module.GrainPile

    class WatchedPile(grain_pile):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            pile_half_thickness.append(self.thickness_radii)
            ring.append(2 * float(self.radii.mean()))

    cylinder_module.GrainPile = WatchedPile

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
solver = scoop_task.pile_solver_options(spec.calibrated, "calibrated")  # the food's own cap where it names one
solver.update(json.loads(args.solver) if args.solver else {})
print(f"# {args.food} set {args.set} changes {changes} solver {solver}", flush=True)
if args.slope:
    for deg in (5.0, 8.0):
        print(f"slope {deg:.0f} deg: {1000 * slope_travel_m(spec, 'calibrated', deg):.3f} mm in 2 s", flush=True)
for cyl_seed in [int(x) for x in args.cyl_seeds.split(",")]:
    t = time.time()
    d = lifting_cylinder(spec, "calibrated", seed=cyl_seed, solver_options=solver, scale=args.scale).as_dict()
    print(
        f"cylinder {args.scale}x seed {cyl_seed}: fit {d['angle_slope_fit_deg']:.1f} "
        f"h/b {d['angle_height_base_deg']:.1f} "
        f"bulk {d['bulk_density_g_cm3']:.2f} packing {d['packing_fraction']:.2f} settled {d['settled']} "
        f"escaped {d['escaped_fast']} sim {d['sim_time_s']:.1f} s wall {time.time() - t:.0f} s",
        flush=True,
    )
