"""What the wrist sensor felt when BC-RNN (wrench) lifted an empty spoon: the study's rice episodes (same seeds and
bowls) rolled out by its checkpoint for their first 120 control steps, each step's spoon contacts sorted into grains
and anything else (the bowl), with the force read beyond the spoon's weight. Run from the repository root after the
study:

    python results/grid_calibrated_wrench/probe_contact.py runs/grid_wrench --episodes 0 1 2 3 4 17 18
"""

import argparse
import glob
import json
from pathlib import Path

import numpy as np

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.evaluation.agents import EpisodeTask, _checkpoint_env, parse_spec

STEPS = 120
FELT_N = 3.0  # a force this far from the spoon's weight is a contact


def contacts(env) -> tuple[bool, bool]:
    """Whether the spoon touches a grain, and whether it touches anything else."""
    data = env.sim.data._data
    pairs = data.contact.geom[: data.ncon]
    spoon = np.isin(pairs, env.spoon_geom_ids)
    grain = np.isin(pairs, env.grain_geom_ids)
    with_spoon = spoon[:, 0] | spoon[:, 1]
    other = ~(spoon | grain)
    touches_grain = bool((with_spoon & (grain[:, 0] | grain[:, 1])).any())
    touches_else = bool((with_spoon & (other[:, 0] | other[:, 1])).any())
    return touches_grain, touches_else


def probe(path: str, episode: int) -> dict:
    task = EpisodeTask(
        agent="probe", spec=parse_spec(path), food="rice", episode=episode, seed=100000 + episode, horizon=400,
        env_kwargs={"physics": "calibrated"},
    )  # fmt: skip
    env, obs, act, step = _checkpoint_env(task)
    weight = np.linalg.norm(obs["robot0_eef_force"])
    out = {"episode": episode, "first grain touch": None, "first felt": None, "felt touching only the bowl": 0,
           "max force touching only the bowl (N)": 0.0, "grains in spoon at step 120": None}  # fmt: skip
    for t in range(STEPS):
        obs, _, _, _ = step(act(obs))
        grain, other = contacts(env)
        felt = abs(np.linalg.norm(obs["robot0_eef_force"]) - weight) > FELT_N
        if grain and out["first grain touch"] is None:
            out["first grain touch"] = t
        if felt and out["first felt"] is None:
            out["first felt"] = t
        if felt and other and not grain:
            out["felt touching only the bowl"] += 1
            force = float(np.linalg.norm(obs["robot0_eef_force"]))
            out["max force touching only the bowl (N)"] = round(
                max(out["max force touching only the bowl (N)"], force), 1
            )
    out["grains in spoon at step 120"] = int(env._scoop_metrics()["grains_in_spoon"])
    env.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("study")
    parser.add_argument("--episodes", type=int, nargs="+", default=[0, 1, 2, 3, 4, 17, 18])
    args = parser.parse_args()
    pattern = Path(args.study) / "runs" / "expert_bc_rnn_*_obs-wrench" / "*" / "models" / "model_epoch_40.pth"
    (path,) = glob.glob(str(pattern))
    for episode in args.episodes:
        print(json.dumps(probe(path, episode)))


if __name__ == "__main__":
    main()
