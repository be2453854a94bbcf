"""Why a BC-RNN policy reaches the post-scoop pose and never holds it: the study's episodes (same seeds and bowls)
rolled out by one of its checkpoints, and at each control step which of the task's success tests pass (position,
tilt, speed, portion, spill). Prints per episode the runs of consecutive successful steps (success ends an episode
once it holds SUCCESS_HOLD_S, 20 steps), the test that failed at the step that ended each run and that step's place
in the policy's 10-step RNN window (robomimic resets BC-RNN's hidden state every rnn_horizon steps of a rollout),
and the spoon's pose error, tilt and speed over the episode's last 5 s. Run from the repository root after the
study:

    python results/grid_calibrated_spacemouse_held/probe/probe_hold.py runs/grid_sm_held_s3 --seed 3 \
        --episodes rice:1 rice:5 barley:11
"""

import argparse
import glob
import json
from pathlib import Path

import numpy as np

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.environments.episode import SUCCESS_HOLD_S
from veragmil_suite.evaluation.agents import EpisodeTask, _checkpoint_env, parse_spec
from veragmil_suite.study.settings import EVAL_SEED_OFFSET

RNN_HORIZON = 10  # configs/json/bc_rnn.json: algo.rnn.horizon


def study_checkpoint(study: str, seed: int) -> str:
    """The study's BC-RNN checkpoint of training seed ``seed`` (its last epoch)."""
    suffix = "" if seed == 1 else f"_seed{seed}"
    runs = glob.glob(str(Path(study) / "runs" / f"*_bc_rnn_*{suffix}" / "*" / "models" / "model_epoch_*.pth"))
    runs = [r for r in runs if seed != 1 or "_seed" not in Path(r).parts[-4]]
    return max(runs, key=lambda p: int(Path(p).stem.split("_")[-1]))


def tests(env) -> dict:
    """The task's success tests at this step (task_state._check_success), each passed or not, and the values."""
    m = env._scoop_metrics()
    error = float(np.linalg.norm(m["spoon_pos"] - env._desired_pos()))
    return dict(
        position=error <= env.success_pos_tolerance, tilt=m["spoon_tilt"] <= env.success_tilt_tolerance,
        speed=m["spoon_speed"] <= env.success_max_speed, portion=m["spoon_volume_m3"] >= env.min_portion_m3,
        spill=env._spill_within_limit(m), error_mm=1000 * error, tilt_deg=float(np.degrees(m["spoon_tilt"])),
        speed_mm_s=1000 * float(m["spoon_speed"]),
    )  # fmt: skip


def probe(path: str, food: str, episode: int, steps: int) -> dict:
    task = EpisodeTask(
        agent="probe", spec=parse_spec(path), food=food, episode=episode, seed=EVAL_SEED_OFFSET + episode,
        horizon=steps, env_kwargs={"physics": "calibrated"},
    )  # fmt: skip
    env, obs, act, step = _checkpoint_env(task)
    hold = int(round(SUCCESS_HOLD_S * env.control_freq))
    rows, run, runs = [], 0, []
    for t in range(steps):
        obs, _, _, _ = step(act(obs))
        row = tests(env)
        passed = all(row[k] for k in ("position", "tilt", "speed", "portion", "spill"))
        if passed:
            run += 1
        elif run:
            failed = [k for k in ("position", "tilt", "speed", "portion", "spill") if not row[k]]
            runs.append(dict(start=t - run, steps=run, ended_by=failed, rnn_step=t % RNN_HORIZON))
            run = 0
        rows.append(row)
        if run >= hold:
            runs.append(dict(start=t + 1 - run, steps=run, ended_by=["success held"], rnn_step=None))
            break
    env.close()
    last = rows[-5 * int(env.control_freq) :]

    def spread(key: str) -> list[float]:
        return [round(min(r[key] for r in last), 1), round(max(r[key] for r in last), 1)]

    return {
        "food": food, "episode": episode, "steps": len(rows), "success_runs": runs,
        "last 5 s": {"pose error mm": spread("error_mm"), "tilt deg": spread("tilt_deg"),
                     "speed mm/s": spread("speed_mm_s")},
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--seed", type=int, default=1, help="the training seed of the checkpoint")
    parser.add_argument("--episodes", nargs="+", default=["rice:1"], help="food:episode of the study's evaluation")
    parser.add_argument("--steps", type=int, default=400)
    args = parser.parse_args()
    path = study_checkpoint(args.study, args.seed)
    for item in args.episodes:
        food, episode = item.split(":")
        print(json.dumps(probe(path, food, int(episode), args.steps)), flush=True)


if __name__ == "__main__":
    main()
