"""Where a scripted-expert episode's time goes: MuJoCo's timers, the solver's iterations, contacts and rows.

    python results/calibration/exploration/profile_episode.py FOOD PHYSICS SEEDS [MAKE_KWARGS_JSON] [GRAIN_CHANGES_JSON]

e.g. ``profile_episode.py rice calibrated 0 '{}' '{"rolling_friction_m": 0}'`` (a calibrated grain model with
fields changed). Per seed: success, grains in the spoon and spilled, control steps a second, the seconds MuJoCo spent
in each stage, and the CG iterations of each control step's last substep (how often at the cap), contacts and
constraint rows.
"""

import json
import os
import sys
import time
from dataclasses import replace

import mujoco
import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.models import foods
from veragmil_suite.scripts.bench import make_env

food, physics = sys.argv[1], sys.argv[2]
seeds = [int(s) for s in sys.argv[3].split(",")]
kwargs = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
if len(sys.argv) > 5:
    spec = foods.FOODS[food]
    foods.FOODS[food] = replace(spec, calibrated=replace(spec.calibrated, **json.loads(sys.argv[5])))
env = make_env(food, physics=physics, pile_variants=3, **kwargs)
STAGES = ["STEP", "POSITION", "CONSTRAINT", "POS_COLLISION", "POS_MAKE", "COL_NARROW"]
for seed in seeds:
    obs = env.reset(seed=seed)
    data, model = env.sim.data._data, env.sim.model._model
    for timer in data.timer:
        timer.duration, timer.number = 0, 0
    expert = ScriptedScooper(env, os.environ.get("PROFILE", "expert"), seed=seed)
    iterations, contacts, rows = [], [], []
    start = time.time()
    for step in range(600):  # noqa: B007
        action = expert.agent(obs)
        if action is None:
            break
        obs, _, _, info = env.step(action)
        iterations.append(int(data.solver_niter[0]))
        contacts.append(data.ncon)
        rows.append(data.nefc)
        if info["success"]:
            break
    wall = time.time() - start
    spent = {s: round(data.timer[getattr(mujoco.mjtTimer, "mjTIMER_" + s)].duration, 2) for s in STAGES}
    it = np.array(iterations)
    print(
        seed, food, physics, "success", info["success"], "spoon", info["grains_in_spoon"], "spilled",
        info["grains_spilled"], "steps", step, f"{step / wall:.1f} steps/s", "wall", round(wall, 2), "s:", spent,
        f"iterations mean {it.mean():.1f}, at the cap {(it >= model.opt.iterations).mean():.2f};",
        f"contacts {np.mean(contacts):.0f}, rows {np.mean(rows):.0f}", flush=True,
    )  # fmt: skip
