"""Where BC-RNN's loaded spoon stops: the study's episodes (same seeds and bowls) rolled out by its checkpoint, the
spoon's height above the bowl's rim, the grains in it, the size of the policy's translation and rotation actions and
its mean translation action (x, y, z, as a fraction of full scale), each averaged over blocks of 20 control steps
(1 s), and the share of those steps in which the spoon touches something that is not a grain (the bowl); and the
episode's lowest spoon height, step by step. With ``--expert`` the scripted expert runs the same
bowls instead (its translation actions are its own, before the noise of ``expert-dart``). Run from the repository
root after the study:

    python results/grid_calibrated_dart_bcrnn/probe/probe_stall.py runs/grid_calibrated_dart_bcrnn --food rice \
        --episodes 1 2 3 [--expert]
"""

import argparse
import glob
import json
from pathlib import Path

import numpy as np

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.evaluation.agents import EpisodeTask, _checkpoint_env, _expert_env, parse_spec
from veragmil_suite.study.settings import EVAL_SEED_OFFSET

BLOCK = 20


def study_checkpoint(study: str) -> str:
    """The study's one BC-RNN checkpoint (its last epoch)."""
    (path,) = glob.glob(str(Path(study) / "runs" / "*_bc_rnn_*" / "*" / "models" / "model_epoch_40.pth"))
    return path


def grid_task(path: str, food: str, episode: int, horizon: int) -> EpisodeTask:
    """The study's evaluation episode ``episode`` of ``food`` (its seed and bowl) for checkpoint or expert ``path``."""
    return EpisodeTask(
        agent="probe", spec=parse_spec(path), food=food, episode=episode, seed=EVAL_SEED_OFFSET + episode,
        horizon=horizon, env_kwargs={"physics": "calibrated"},
    )  # fmt: skip


def touches_bowl(env) -> bool:
    """Whether the spoon touches anything but a grain."""
    data = env.sim.data._data
    pairs = data.contact.geom[: data.ncon]
    spoon = np.isin(pairs, env.spoon_geom_ids)
    grain = np.isin(pairs, env.grain_geom_ids)
    other = ~(spoon | grain)
    return bool(((spoon[:, 0] & other[:, 1]) | (spoon[:, 1] & other[:, 0])).any())


def probe(path: str, food: str, episode: int, steps: int) -> dict:
    task = grid_task(path, food, episode, steps)
    env, obs, act, step = (_expert_env if path == "expert" else _checkpoint_env)(task)
    rows, block, lowest = [], [], np.inf
    for t in range(steps):
        action = act(obs)
        if action is None:  # the expert's scoop is done
            break
        action = np.asarray(action)
        obs, _, _, _ = step(action)
        height = float(obs["robot0_eef_pos"][2] - obs["bowl_pos"][2])
        grains = int(env._scoop_metrics()["grains_in_spoon"])
        lowest = min(lowest, height)
        block.append(
            (height, grains, np.linalg.norm(action[:3]), np.linalg.norm(action[3:6]), touches_bowl(env), *action[:3])
        )
        if len(block) == BLOCK:
            h, g, trans, rot, bowl, *xyz = np.mean(block, axis=0)
            rows.append({"s": (t + 1) // BLOCK, "height_mm": round(1000 * h, 1), "grains": round(float(g), 1),
                         "|translation action|": round(float(trans), 3), "|rotation action|": round(float(rot), 3),
                         "translation action xyz": [round(float(v), 3) for v in xyz],
                         "touching the bowl": round(float(bowl), 2)})  # fmt: skip
            block = []
    env.close()
    return {"food": food, "episode": episode, "lowest_height_mm": round(1000 * lowest, 1), "by second": rows}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--food", default="rice")
    parser.add_argument("--episodes", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--expert", action="store_true")
    args = parser.parse_args()
    path = "expert" if args.expert else study_checkpoint(args.study)
    for episode in args.episodes:
        print(json.dumps(probe(path, args.food, episode, args.steps)))


if __name__ == "__main__":
    main()
