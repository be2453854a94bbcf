"""The calibrated spoon's contact time constant against what it holds and whether it throws grains: for each
time constant, the level spoonful (calibration.spoonful) of rice and barley, and the expert's scoop of rice.

    python results/calibration/exploration/spoon_stiffness.py 0.03,0.04,0.05 [SEEDS]
"""

import sys

import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.calibration.spoonful import level_spoonful_g
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.models import foods
from veragmil_suite.scripts.bench import make_env

seeds = [int(s) for s in (sys.argv[2] if len(sys.argv) > 2 else "0,1,2").split(",")]
for timeconst in (float(t) for t in sys.argv[1].split(",")):
    foods.SPOON_CONTACT_SOLREF["calibrated"] = (timeconst, 1.0)  # read by spoon_gripper.spoon_contact at build time
    spoonfuls = {food: level_spoonful_g(foods.FOODS[food], "calibrated")[0] for food in ("rice", "barley")}
    env = make_env("rice", physics="calibrated", pile_variants=3)
    wins, rows = 0, []
    for seed in seeds:
        obs = env.reset(seed=seed)
        expert = ScriptedScooper(env, "expert", seed=seed)
        for _ in range(600):
            action = expert.agent(obs)
            if action is None:
                break
            obs, _, _, info = env.step(action)
            if info["success"]:
                break
        reach = float(np.linalg.norm(env.sim.data.body_xpos[env.grain_body_ids] - env._rim_center(), axis=1).max())
        wins += info["success"]
        rows.append(f"{info['grains_in_spoon']}/{info['spoon_mass_g']:.2f}g/sp{info['grains_spilled']}/{reach:.2f}m")
    env.close()
    print(
        f"spoon solref {timeconst} s: level spoonful rice {spoonfuls['rice']:.2f} g,"
        f" barley {spoonfuls['barley']:.2f} g;"
        f" expert on rice {wins}/{len(seeds)} (grains/grams/spilled/furthest grain: {', '.join(rows)})",
        flush=True,
    )
