"""Whether BC-RNN's stall comes from its short memory: robomimic's rollout starts the LSTM afresh every
``rnn.horizon`` (10) control steps, so a spoon still for longer sees only the present. Rolls the study's checkpoint
out on the grid's bowls with that reset, and again with the state carried through the episode. Run from the
repository root after the study:

    python results/grid_calibrated_dart_bcrnn/probe/probe_memory.py runs/grid_calibrated_dart_bcrnn --episodes 0 1 2
"""

import argparse
import json

from probe_stall import grid_task, study_checkpoint

from veragmil_suite.environments.episode import run_until_done
from veragmil_suite.evaluation.agents import _checkpoint_env, _policy

NEVER = 10**9


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--food", default="rice")
    parser.add_argument("--episodes", type=int, nargs="+", default=[0, 1, 2])
    args = parser.parse_args()
    path = study_checkpoint(args.study)
    policy, _ = _policy(path)
    trained_horizon = policy.policy._rnn_horizon
    for reset_every in (trained_horizon, NEVER):
        policy.policy._rnn_horizon = reset_every
        for episode in args.episodes:
            env, obs, act, step = _checkpoint_env(grid_task(path, args.food, episode, 400))
            end = run_until_done(act, step, obs, env.control_freq, 400)
            env.close()
            row = {"lstm reset every": "never" if reset_every == NEVER else reset_every, "episode": episode}
            print(json.dumps(row | {"stage": end.stage, "steps": end.steps, "reason": end.reason}), flush=True)


if __name__ == "__main__":
    main()
