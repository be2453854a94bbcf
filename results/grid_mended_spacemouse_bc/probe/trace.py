"""One episode of a checkpoint traced every 10 control steps: stage, grains in the spoon and spilled, the spoon's
offset from the desired post-scoop position (mm), the action's norms (translation, rotation), and (since session 64;
rice_bowl0.txt predates it) the spoon's orientation error to the post-scoop pose (the norm of spoon_to_desired_rot,
rad). <agent> is a checkpoint or "expert" (the scripted operator). Run from the repository root:
python results/grid_mended_spacemouse_bc/probe/trace.py <agent> <food> <episode>"""

import sys

import numpy as np

import veragmil_suite.evaluation.agents as agents

checkpoint, food, episode = sys.argv[1], sys.argv[2], int(sys.argv[3])
task = agents.EpisodeTask(
    agent="probe", spec=agents.parse_spec(checkpoint), food=food, episode=episode, seed=100000 + episode,
    horizon=400, env_kwargs={"physics": "calibrated"},
)  # fmt: skip
env, obs, act, step = agents.episode_env(task)
print(
    "step | stage | in spoon | spilled | spoon - desired (mm: x, y, z) | |translation action| | |rotation action| | "
    "orientation error (rad)"
)
for t in range(400):
    action = act(obs)
    obs, _, done, _ = step(action)
    if t % 10 == 9:
        info = env.scoop_info()
        offset = 1000 * np.asarray(obs["spoon_to_desired_pos"]).ravel()
        print(
            f"{t + 1} | {env.scoop_stage()} | {info['grains_in_spoon']} | {info['grains_spilled']} | "
            f"{offset.round(0).tolist()} | {np.linalg.norm(action[:3]):.2f} | {np.linalg.norm(action[3:6]):.2f} | "
            f"{np.linalg.norm(env._get_observations()['spoon_to_desired_rot']):.3f}"
        )
    if done:
        break
