"""A calibrated grain model with some fields changed, measured three ways: one grain on an 8 degree slope, the quick
lifting cylinder (0.7x tube), and scripted-expert episodes with MuJoCo's timers (sleeping off).

    python results/calibration/exploration/grain_shape_probe.py rice \
        '{"shape": "sphere_chain", "aspect": [0.42, 3, 0.5], "rolling_friction_m": 0, "torsional_friction_m": 0}' \
        --mass-mg 24 --seeds 0,1,2 [--skip slope,cylinder,expert] [--solver '{"iterations": "60"}']

``--mass-mg`` sets the density so that a grain of mean size weighs that much.
"""

import argparse
import json
import time
from dataclasses import replace

import mujoco
import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.lifting_cylinder import lifting_cylinder
from veragmil_suite.calibration.slope import slope_travel_m
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.models import foods, scoop_task
from veragmil_suite.scripts.bench import make_env

parser = argparse.ArgumentParser()
parser.add_argument("food")
parser.add_argument("changes", nargs="?", default="{}")
parser.add_argument("--mass-mg", type=float)
parser.add_argument("--seeds", default="0,1,2")
parser.add_argument("--skip", default="")
parser.add_argument("--cyl-seeds", default="0", help="lifting cylinder fills, comma-separated seeds")
parser.add_argument("--scale", type=float, default=0.7, help="lifting cylinder size against the standard tube")
parser.add_argument("--solver", default=None, help="physics_solver_options changes (JSON)")
args = parser.parse_args()
changes = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(args.changes).items()}
spec = foods.FOODS[args.food]
grain = replace(spec.calibrated, **changes)
if args.mass_mg:
    grain = replace(grain, density_kg_m3=args.mass_mg * 1e-6 / grain.piece_volume_m3())
solver_changes = json.loads(args.solver) if args.solver else {}
if "iterations" in solver_changes and grain.solver_iterations is not None:  # the food's own cap gives way too
    grain = replace(grain, solver_iterations=int(solver_changes["iterations"]))
spec = replace(spec, calibrated=grain)
foods.FOODS[args.food] = spec
# the solver changes apply to every scene of the calibrated physics (slope, cylinder, task)
scoop_task.PHYSICS_SOLVER_OPTIONS["calibrated"].update(solver_changes)
solver = scoop_task.pile_solver_options(grain, "calibrated")
print(f"# {args.food} {changes} density {grain.density_kg_m3:.0f} condim {grain.condim} solver {solver}", flush=True)
skip = set(args.skip.split(","))
if "slope" not in skip:
    for deg in (5.0, 8.0):
        print(f"slope {deg:.0f} deg: {1000 * slope_travel_m(spec, 'calibrated', deg):.3f} mm in 2 s", flush=True)
if "cylinder" not in skip:
    for cyl_seed in [int(x) for x in args.cyl_seeds.split(",")]:
        t = time.time()
        r = lifting_cylinder(spec, "calibrated", seed=cyl_seed, scale=args.scale)
        d = r.as_dict()
        print(
            f"cylinder {args.scale}x seed {cyl_seed}: fit {d['angle_slope_fit_deg']:.1f} h/b "
            f"{d['angle_height_base_deg']:.1f} bulk {d['bulk_density_g_cm3']:.2f} packing {d['packing_fraction']:.2f} "
            f"grains {d['n_grains']} mass {d['grain_mass_mg']:.1f} mg settled {d['settled']} "
            f"wall {time.time() - t:.0f} s",
            flush=True,
        )
if "expert" not in skip:
    env = make_env(args.food, physics="calibrated", pile_variants=3, physics_solver_options=solver)
    m = env.sim.model._model
    wins = 0
    for seed in [int(s) for s in args.seeds.split(",")]:
        obs = env.reset(seed=seed)
        expert = ScriptedScooper(env, "expert", seed=seed)
        d = env.sim.data._data
        solver_s = step_s = 0.0
        iters, start = [], time.time()
        for step in range(600):  # noqa: B007 (the count after the loop is the episode's length)
            action = expert.agent(obs)
            if action is None:
                break
            d.timer[mujoco.mjtTimer.mjTIMER_STEP].duration = 0
            d.timer[mujoco.mjtTimer.mjTIMER_CONSTRAINT].duration = 0
            obs, _, _, info = env.step(action)
            step_s += d.timer[mujoco.mjtTimer.mjTIMER_STEP].duration
            solver_s += d.timer[mujoco.mjtTimer.mjTIMER_CONSTRAINT].duration
            iters.append(int(d.solver_niter[0]))
            if info["success"]:
                break
        wall = time.time() - start
        grains = env.sim.data.body_xpos[env.grain_body_ids]
        reach = float(np.linalg.norm(grains - env._rim_center(), axis=1).max())
        wins += info["success"]
        print(
            f"seed {seed} success {info['success']} spoon {info['grains_in_spoon']} {info['spoon_mass_g']:.2f} g "
            f"spilled {info['grains_spilled']} reach {reach:.2f} m steps {step + 1} {(step + 1) / wall:.1f} sps "
            f"wall {wall:.1f} s mj step {step_s:.1f} s constraint {solver_s:.1f} s iters mean {np.mean(iters):.1f} "
            f"at cap {np.mean(np.array(iters) >= int(solver['iterations'])):.2f}",
            flush=True,
        )
    print(f"wins {wins}")
