"""The scripted expert on one food and physics, seed by seed: where the grains are at each phase, and the rate.

    python results/calibration/exploration/expert_probe.py FOOD PHYSICS SEEDS [MAKE_KWARGS_JSON]
    SOLREF=0.04 python ... : the grains' contact time constant (s) set after each reset
    SPOON_SOLREF=0.08 python ... : the spoon's, for its contacts alone
    PROFILE=spacemouse python ... : another operator profile (veragmil_suite.devices.expert.PROFILES)
    GRAIN_CHANGES='{"rolling_friction_m": 1e-4}' python ... : the food's calibrated GrainModel with these fields

Prints per seed: success, grains and grams in the spoon at the end, grains spilled (outside the bowl's rim), steps,
control steps a second (resets untimed), and at each phase's start the grains in the spoon / spilled.
"""

import json
import os
import sys
import time
from dataclasses import replace

import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.models import foods
from veragmil_suite.scripts.bench import make_env

food, physics = sys.argv[1], sys.argv[2]
seeds = [int(s) for s in sys.argv[3].split(",")]
kwargs = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
if os.environ.get("GRAIN_CHANGES"):
    spec = foods.FOODS[food]
    changes = json.loads(os.environ["GRAIN_CHANGES"])
    foods.FOODS[food] = replace(spec, calibrated=replace(spec.calibrated, **changes))
env = make_env(food, physics=physics, pile_variants=3, **kwargs)
wins = 0
for seed in seeds:
    obs = env.reset(seed=seed)
    if os.environ.get("SOLREF"):
        grains = set(env.grain_body_ids)
        geoms = [i for i in range(env.sim.model.ngeom) if env.sim.model.geom_bodyid[i] in grains]
        env.sim.model._model.geom_solref[geoms, 0] = float(os.environ["SOLREF"])
    if os.environ.get("SPOON_SOLREF"):  # the spoon's contacts alone: its solref dominates the mix (solmix)
        model = env.sim.model
        spoon = [i for i in range(model.ngeom) if (model.geom_id2name(i) or "").startswith("gripper0_right_spoon")]
        model._model.geom_solref[spoon, 0] = float(os.environ["SPOON_SOLREF"])
        model._model.geom_solmix[spoon] = 1e3
    expert = ScriptedScooper(env, os.environ.get("PROFILE", "expert"), seed=seed)
    phase, log, start = None, [], time.time()
    for step in range(600):
        action = expert.agent(obs)
        if action is None:
            break
        obs, _, _, info = env.step(action)
        if expert.phase != phase:
            phase = expert.phase
            log.append(f"{phase}@{step}:sp{info['grains_in_spoon']}/sl{info['grains_spilled']}")
        if info["success"]:
            break
    grains = env.sim.data.body_xpos[env.grain_body_ids]
    reach = float(np.linalg.norm(grains - env._rim_center(), axis=1).max())
    wins += info["success"]
    rate = step / (time.time() - start)
    print(
        seed, "success", info["success"], "spoon", info["grains_in_spoon"], f"{info['spoon_mass_g']:.2f}g",
        "spilled", info["grains_spilled"], f"reach {reach:.2f}m", "steps", step, f"{rate:.1f}sps", " ".join(log),
        flush=True,
    )  # fmt: skip
print("wins", wins, "/", len(seeds))
