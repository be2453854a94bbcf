"""The full-data model's actions near the post-scoop pose against the demos' there and the cut-data model's on the
same observations. Runs one episode of the full-data checkpoint; for every 5th step from the first at the pose, the
demo steps nearest in the policy's observations (each key scaled by its spread in the data) give the demos' mean
action there. Run from the repository root:
python results/grid_mended_spacemouse_bc/probe/neighbours.py <full.pth> <cut.pth> <data.hdf5> <food> <episode>"""

import sys

import h5py
import numpy as np

import veragmil_suite.evaluation.agents as agents
from veragmil_suite.learning.observation_sets import NO_LOAD

full, cut, data, food, episode = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
with h5py.File(data, "r") as f:
    demos = [f["data"][d] for d in f["data"]]
    rows = [[g["obs"][k][:].reshape(len(g["actions"]), -1) for k in NO_LOAD] for g in demos]
    states = np.concatenate([np.concatenate(r, 1) for r in rows])
    actions = np.concatenate([g["actions"][:] for g in demos])
scale = states.std(0) + 1e-6


def checkpoint_episode(checkpoint: str) -> tuple:
    """The checkpoint's env on the episode's bowl, reset: (env, obs, act, step)."""
    return agents._checkpoint_env(
        agents.EpisodeTask(
            agent="probe",
            spec=agents.parse_spec(checkpoint),
            food=food,
            episode=episode,
            seed=100000 + episode,
            horizon=400,
            env_kwargs={"physics": "calibrated"},
        )
    )


env, obs, act, step = checkpoint_episode(full)
_, _, cut_act, _ = checkpoint_episode(cut)
print(
    "step | stage | |offset| mm | full model: |translation|, |rotation| | cut model | 10 nearest demo steps: "
    "mean |translation|, |rotation|, share of zero actions; mean rotation action"
)
first = None
for t in range(300):
    action = act(obs)
    if env.scoop_stage() == "at post-scoop pose" and first is None:
        first = t
    if first is not None and (t - first) % 5 == 0:
        x = np.concatenate([np.asarray(obs[k]).ravel() for k in NO_LOAD])
        near = np.argsort(np.linalg.norm((states - x) / scale, axis=1))[:10]
        a = actions[near]
        c = cut_act(obs)
        gap = np.abs((states[near[0]] - x) / scale)
        sizes = {k: np.asarray(obs[k]).size for k in NO_LOAD}
        bounds = np.cumsum([0] + list(sizes.values()))
        worst = {k: round(float(gap[bounds[i] : bounds[i + 1]].max()), 1) for i, k in enumerate(NO_LOAD)}
        quat, nearest = np.asarray(obs["robot0_eef_quat"]).round(3).tolist(), states[near[0], 3:7].round(3).tolist()
        print("   eef_quat", quat, "nearest demo's", nearest, "largest scaled gap per key", worst)
        print(
            f"{t} | {env.scoop_stage()} | {1000 * np.linalg.norm(obs['spoon_to_desired_pos']):.0f} | "
            f"{np.linalg.norm(action[:3]):.2f}, {np.linalg.norm(action[3:6]):.2f} {action[3:6].round(2).tolist()} | "
            f"{np.linalg.norm(c[:3]):.2f}, {np.linalg.norm(c[3:6]):.2f} {c[3:6].round(2).tolist()} | "
            f"{np.linalg.norm(a[:, :3], axis=1).mean():.2f}, {np.linalg.norm(a[:, 3:6], axis=1).mean():.2f}, "
            f"{(np.abs(a[:, :6]).sum(1) == 0).mean():.1f}; {a[:, 3:6].mean(0).round(2).tolist()}"
        )
    obs, _, done, _ = step(action)
    if done or (first is not None and t - first > 60):
        break
