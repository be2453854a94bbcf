"""What the demos did where BC-RNN's spoon stalls: rolls the study's checkpoint out on one of the grid's bowls for
``--steps`` control steps, then lists the recorded demo states nearest the stalled spoon (its position relative to the
bowl, and its attitude weighted 2 cm per unit of quaternion distance; at most three from one demo), each with the
demo's action there (the first six of seven: translation and rotation, a fraction of full scale). Run from the
repository root after the study:

    python results/grid_calibrated_dart_bcrnn/probe/probe_nearest.py runs/grid_calibrated_dart_bcrnn --episode 1
"""

import argparse
import glob
from pathlib import Path

import h5py
import numpy as np
from probe_stall import grid_task, study_checkpoint

from veragmil_suite.evaluation.agents import _checkpoint_env

QUAT_WEIGHT_M = 0.02


def spoon_state(obs) -> np.ndarray:
    """The spoon's position from the bowl's rim centre and its attitude (a step's observations, or a demo's)."""
    pos = np.asarray(obs["robot0_eef_pos"]) - np.asarray(obs["bowl_pos"])
    return np.concatenate([pos, np.asarray(obs["robot0_eef_quat"])], axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--food", default="rice")
    parser.add_argument("--episode", type=int, default=1)
    parser.add_argument("--steps", type=int, default=160)
    parser.add_argument("--nearest", type=int, default=25)
    args = parser.parse_args()
    (data,) = glob.glob(str(Path(args.study) / "data" / "*.hdf5"))
    env, obs, act, step = _checkpoint_env(grid_task(study_checkpoint(args.study), args.food, args.episode, args.steps))
    for _ in range(args.steps):
        action = np.asarray(act(obs))
        obs, _, _, _ = step(action)
    env.close()
    stall = spoon_state(obs)
    print(f"{args.food} bowl {args.episode}, step {args.steps}: spoon at {np.round(1000 * stall[:3], 1)} mm from the"
          f" rim's centre, policy action {np.round(action[:6], 3)}")  # fmt: skip
    rows = []
    with h5py.File(data, "r") as f:
        for name, demo in f["data"].items():
            states = spoon_state(
                {key: demo["obs"][key][:] for key in ("robot0_eef_pos", "bowl_pos", "robot0_eef_quat")}
            )
            quat = states[:, 3:] * np.sign(states[:, 3:] @ stall[3:])[:, None]  # q and -q are one attitude
            dist = np.linalg.norm(states[:, :3] - stall[:3], axis=1) + QUAT_WEIGHT_M * np.linalg.norm(
                quat - stall[3:], axis=1
            )
            for t in np.argsort(dist)[:3]:
                rows.append((dist[t], name, t, len(states), demo["actions"][t][:6]))
    rows.sort(key=lambda r: r[0])
    for dist, name, t, n, action in rows[: args.nearest]:
        print(f"{1000 * dist:5.1f} mm  {name:>9} step {t:3d} of {n}  action {np.round(action, 3)}")
    mean = np.mean([r[4] for r in rows[: args.nearest]], axis=0)
    print(f"mean action of the {args.nearest} nearest: {np.round(mean, 3)}")


if __name__ == "__main__":
    main()
