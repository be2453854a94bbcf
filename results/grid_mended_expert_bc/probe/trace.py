"""One evaluated episode of a checkpoint traced every 10 control steps: stage, pieces in the spoon and spilled, the
spoon's offset from the desired post-scoop position (mm), its orientation error to it (the norm of
spoon_to_desired_rot, rad), and the action's norms (translation, rotation). Run from the repository root:
python results/grid_mended_expert_bc/probe/trace.py <checkpoint> <food> <episode>"""

import sys

import numpy as np

import veragmil_suite.evaluation.agents as agents

checkpoint, food, episode = sys.argv[1], sys.argv[2], int(sys.argv[3])
task = agents.EpisodeTask(
    agent="probe", spec=agents.parse_spec(checkpoint), food=food, episode=episode, seed=100000 + episode,
    horizon=400, env_kwargs={"physics": "calibrated"},
)  # fmt: skip
env, obs, act, step = agents._checkpoint_env(task)
print("step | stage | in spoon | spilled | spoon - desired (mm) | orientation error (rad) | |dpos| | |drot|")
for t in range(400):
    action = act(obs)
    obs, _, done, _ = step(action)
    if t % 10 == 9:
        info = env.scoop_info()
        offset = 1000 * np.asarray(obs["spoon_to_desired_pos"]).ravel()
        turn = np.linalg.norm(env._get_observations()["spoon_to_desired_rot"])
        print(
            f"{t + 1} | {env.scoop_stage()} | {info['grains_in_spoon']} | {info['grains_spilled']} | "
            f"{offset.round(0).tolist()} | {turn:.3f} | {np.linalg.norm(action[:3]):.2f} | "
            f"{np.linalg.norm(action[3:6]):.2f}"
        )
    if done:
        break
