"""Records a scripted-expert episode's model and every control step's state (positions, velocities, controls), so
that the same solver problems can be stepped again under another MuJoCo (replay_solver_problems.py).

    python results/calibration/exploration/record_episode_states.py FOOD PHYSICS SEED OUT.npz
"""

import sys

import numpy as np

import veragmil_suite  # noqa: F401
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.scripts.bench import make_env

food, physics, seed, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
env = make_env(food, physics=physics, pile_variants=3)
obs = env.reset(seed=seed)
expert = ScriptedScooper(env, "expert", seed=seed)
data = env.sim.data._data
qpos, qvel, ctrl, act = [], [], [], []
for _ in range(600):
    action = expert.agent(obs)
    if action is None:
        break
    qpos.append(data.qpos.copy())
    qvel.append(data.qvel.copy())
    obs, _, _, info = env.step(action)
    ctrl.append(data.ctrl.copy())  # the controller's torques of the step's last substep
    if info["success"]:
        break
np.savez_compressed(out, xml=env.sim.model.get_xml(), qpos=qpos, qvel=qvel, ctrl=ctrl, grains=env.grain_body_ids)
print("steps", len(qpos), "success", info["success"])
