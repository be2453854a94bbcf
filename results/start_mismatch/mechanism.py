"""Why a recorded demo and an evaluated episode start differently, in figures.

1. One bowl, zero actions for 8 steps after env.reset(): plain; restarted as EpisodeRecorder.reset restarted it
   before 9f84426 (the model reloaded by a deterministic reset, the state set back, the controllers left at the
   noise-free pose); and restarted as it does now (veragmil_suite.learning.robomimic_obs.restart_from_current_state,
   with ScoopGranular.hold_restored_pose): the spoon's attitude error against the pre-scoop attitude, and how far the
   spoon moves.
2. The recordings: each demo's attitude error at its first step and 5 steps later.
3. The grid's bowls (seed 100000 + i) as a plain evaluation starts them, the same two figures.
Run from the repository root: python results/start_mismatch/mechanism.py <dataset.hdf5> ..."""

import sys

import h5py
import numpy as np
import robosuite
import robosuite.utils.transform_utils as T
from restarted_start import restart_as_before  # this folder's script: the restart as it was

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.environments.start_pose import PRE_SCOOP_EEF_ROT
from veragmil_suite.learning import robomimic_obs


def attitude_error_deg(quat) -> float:
    return float(np.degrees(np.linalg.norm(T.quat2axisangle(T.mat2quat(PRE_SCOOP_EEF_ROT @ T.quat2mat(quat).T)))))


def zero_action_start(seed: int, restart: str = "", steps: int = 8):
    """An episode's start as the evaluation makes it (a fresh env of the episode's seed, reset), then zero actions."""
    env = robosuite.make(
        "ScoopGranular",
        robots="XArm7",
        food="rice",
        has_renderer=False,
        use_camera_obs=False,
        physics="calibrated",
        seed=seed,
    )
    obs = env.reset()
    if restart == "now":
        obs, _ = robomimic_obs.restart_from_current_state(env)
    elif restart == "before":
        restart_as_before(env)
        obs = robomimic_obs.observe(env)
    errors, start = [attitude_error_deg(obs["robot0_eef_quat_site"])], obs["robot0_eef_pos"].copy()
    for _ in range(steps):
        obs, _, _, _ = env.step(np.zeros(env.action_dim))
        errors.append(attitude_error_deg(obs["robot0_eef_quat_site"]))
    env.close()
    return errors, float(np.linalg.norm(obs["robot0_eef_pos"] - start) * 1000)


def summary(first, later) -> str:
    first, later = np.array(first), np.array(later)
    return (
        f"median {np.median(first):.1f} deg at the first step ({(first > 2).sum()} of {len(first)} above 2), "
        f"{np.median(later):.1f} 5 steps later ({(later > 2).sum()} above 2, largest {later.max():.1f})"
    )


print("## 1. zero actions from one start (grid bowl 4, seed 100004)\n")
for restart, name in (("", "plain env.reset()"), ("before", "restarted, before"), ("now", "restarted, now")):
    errors, moved = zero_action_start(100004, restart)
    print(
        f"- {name}: attitude error, deg, steps 0-8: {', '.join(f'{e:.1f}' for e in errors)}; the spoon moves "
        f"{moved:.1f} mm"
    )
print("\n## 2. the recordings: attitude error against the pre-scoop attitude\n")
for path in sys.argv[1:]:
    with h5py.File(path) as f:
        quats = [f[f"data/{d}/obs/robot0_eef_quat_site"][:6] for d in f["data"]]
    print(f"- {path}: {summary([attitude_error_deg(q[0]) for q in quats], [attitude_error_deg(q[5]) for q in quats])}")
print("\n## 3. the grid's 20 bowls, plain evaluation starts, zero actions\n")
first, later = [], []
for episode in range(20):
    errors, _ = zero_action_start(100000 + episode, steps=5)
    first.append(errors[0])
    later.append(errors[5])
print(f"- {summary(first, later)}")
print(f"- per bowl, 5 steps in: {', '.join(f'{i}: {e:.1f}' for i, e in enumerate(later))}")
