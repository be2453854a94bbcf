"""How each model's spoon arrives at the post-scoop pose: for episodes 0..n-1 of a food, the spoon's orientation
(robot0_eef_quat_site) at the first step at the pose, against the demos' at theirs, and the largest rotation action
in the 20 steps after. Run from the repository root:
python results/grid_mended_spacemouse_bc/probe/arrival.py <data.hdf5> <food> <n> <checkpoint>..."""

import sys

import h5py
import numpy as np

import veragmil_suite.evaluation.agents as agents

data, food, n, checkpoints = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
with h5py.File(data, "r") as f:
    arrivals = []
    for d in f["data"]:
        g = f["data"][d]
        near = np.where(np.linalg.norm(g["obs/spoon_to_desired_pos"][:], axis=1) <= 0.02)[0]
        if len(near):
            arrivals.append(g["obs/robot0_eef_quat_site"][near[0]])
arrivals = np.array(arrivals)
mean, std = arrivals.mean(0).round(3).tolist(), arrivals.std(0).round(3).tolist()
print(f"demos ({len(arrivals)}): quat at arrival mean {mean}, std {std}")
print(
    "checkpoint | episode | quat at arrival | its largest gap from the demos' mean, in their std | "
    "largest |rotation action| over the next 20 steps | success"
)
for checkpoint in checkpoints:
    for episode in range(n):
        task = agents.EpisodeTask(
            agent="probe", spec=agents.parse_spec(checkpoint), food=food, episode=episode, seed=100000 + episode,
            horizon=400, env_kwargs={"physics": "calibrated"},
        )  # fmt: skip
        env, obs, act, step = agents._checkpoint_env(task)
        arrived, rotation, quat = None, 0.0, None
        for t in range(400):
            action = act(obs)
            if arrived is None and np.linalg.norm(obs["spoon_to_desired_pos"]) <= 0.02:
                arrived, quat = t, np.asarray(obs["robot0_eef_quat_site"])
            if arrived is not None:
                rotation = max(rotation, float(np.linalg.norm(action[3:6])))
                if t - arrived >= 20:
                    break
            obs, _, done, _ = step(action)
            if done:
                break
        gap = "-" if quat is None else f"{np.max(np.abs(quat - arrivals.mean(0)) / arrivals.std(0)):.1f}"
        q = "-" if quat is None else quat.round(3).tolist()
        print(f"{checkpoint.split('/')[1]} | {episode} | {q} | {gap} | {rotation:.2f} | {env.scoop_info()['success']}")
