"""
Where each evaluation episode starts, against where the training demos started, beside each agent's failures on it.

An episode's start is drawn from its seed alone: the bowl's place (rim centre, `bowl_pos`) and the arm's initial
joint noise, which moves the spoon (`robot0_eef_pos`). Both are observations of the low-dim configs, so a policy
meets an unfamiliar start as inputs it has seen little of. This prints, per evaluation episode, the rim and the
spoon at reset as offsets from the training demos' mean start (mm), the distance to the nearest training start
(rim xy and spoon xyz together), and how many foods each agent failed on it (from one or more `episodes.csv`).
With --checkpoint it also runs that policy on --probe episodes twice: as drawn, and with the arm's initial joint
noise set to zero (the noise is still drawn, times zero, so the bowl and pile stay those of the seed).

    python results/start_pose/episode_starts.py --dataset runs/grid3/data/expert.hdf5 --filter-key first30 \\
        results/grid_expert_20ep/episodes.csv results/bc_demos_expert/episodes.csv \\
        --checkpoint runs/grid3/runs/expert_bc_100demos_50000steps/<time>/models/model_epoch_100.pth \\
        --probe 17 13 --probe-foods pasta peas
"""

from __future__ import annotations

import argparse
import collections
import csv
import os
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

M_TO_MM = 1000.0
# the food whose env is reset to read each seed's start: the start's draws do not depend on the food
PROBE_FOOD = "pasta"


def start_vector(bowl_pos: np.ndarray, eef_pos: np.ndarray) -> np.ndarray:
    """An episode's start: the rim centre's x, y and the spoon's x, y, z (m, world frame)."""
    return np.r_[bowl_pos[:2], eef_pos]


def training_starts(dataset: str, filter_key: str | None) -> np.ndarray:
    from veragmil_suite.data.schema import open_dataset

    with open_dataset(dataset) as f:
        names = [n.decode() for n in f["mask"][filter_key][:]] if filter_key else list(f["data"])
        return np.array(
            [start_vector(f["data"][n]["obs/bowl_pos"][0], f["data"][n]["obs/robot0_eef_pos"][0]) for n in names]
        )


def episode_start(seed: int) -> np.ndarray:
    import robosuite

    import veragmil_suite  # noqa: F401
    from veragmil_suite.evaluation.agents import EXPERT_KWARGS

    env = robosuite.make("ScoopGranular", **dict(EXPERT_KWARGS, food=PROBE_FOOD, seed=seed))
    obs = env.reset()
    env.close()
    return start_vector(obs["bowl_pos"], obs["robot0_eef_pos"])


def failures(paths: list[str]) -> tuple[list[str], dict[int, collections.Counter]]:
    """Failed foods per episode and agent, the scripted operators left out."""
    counts: dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    agents: list[str] = []
    for path in paths:
        with open(path) as f:
            for row in csv.DictReader(f):
                if row["agent"].endswith("operator"):
                    continue
                if row["agent"] not in agents:
                    agents.append(row["agent"])
                counts[int(row["episode"])][row["agent"]] += row["success"] != "True"
    return agents, counts


NO_JOINT_NOISE = {"initialization_noise": {"magnitude": 0.0, "type": "gaussian"}}


def probe(checkpoint: str, episodes: list[int], foods: list[str], seed: int) -> None:
    from veragmil_suite.evaluation.agents import AgentSpec, EpisodeTask, run_episode

    spec = AgentSpec("checkpoint", checkpoint)
    print(f"\n{checkpoint}, as drawn and without the arm's initial joint noise:\n")
    print("| episode | food | start | success | furthest stage | steps | most grains in the spoon |")
    print("|---:|---|---|---|---|---:|---:|")
    for episode in episodes:
        for food in foods:
            for label, kwargs in (("as drawn", {}), ("no joint noise", NO_JOINT_NOISE)):
                task = EpisodeTask("probe", spec, food, episode, seed + episode, env_kwargs=kwargs)
                r = run_episode(task)
                print(
                    f"| {episode} | {food} | {label} | {r.success} | {r.stage} | {r.steps} | {r.peak_grains_in_spoon} |"
                )


def main(argv: list[str] | None = None) -> None:
    from veragmil_suite.models.foods import FOODS

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("episodes_csv", nargs="+", help="evaluation episodes.csv files (veragmil-evaluate, study)")
    parser.add_argument("--dataset", required=True, help="the training data (robomimic HDF5)")
    parser.add_argument("--filter-key", help="the demos a model trained on (e.g. first30); default: all")
    parser.add_argument("--seed", type=int, default=100000, help="the evaluation's first seed (episode i: seed + i)")
    parser.add_argument("--far-mm", type=float, default=25.0, help="a spoon start this far from the mean is 'far'")
    parser.add_argument("--checkpoint", help="a robomimic checkpoint to run on the --probe episodes")
    parser.add_argument("--probe", type=int, nargs="+", default=[], help="episodes to run the checkpoint on")
    parser.add_argument(
        "--probe-foods", nargs="+", choices=list(FOODS), default=[PROBE_FOOD], metavar="FOOD", help="foods to probe"
    )
    args = parser.parse_args(argv)

    train = training_starts(args.dataset, args.filter_key)
    mean = train.mean(axis=0)
    spoon_spread = M_TO_MM * np.linalg.norm(train[:, 2:] - mean[2:], axis=1)
    agents, counts = failures(args.episodes_csv)
    episodes = sorted(counts)
    print(
        f"{len(train)} training starts: spoon {spoon_spread.mean():.1f} mm from their mean on average, at most ", end=""
    )
    print(f"{spoon_spread.max():.1f}; {np.mean(spoon_spread > args.far_mm):.0%} farther than {args.far_mm:g} mm\n")
    print(
        "| episode | rim dx | rim dy | spoon dx | spoon dy | spoon dz | spoon off mean | nearest training start |",
        end="",
    )
    print("".join(f" {a} |" for a in agents))
    print("|" + "---:|" * (8 + len(agents)))
    far_fail, near_fail, far_n, near_n = collections.Counter(), collections.Counter(), 0, 0
    for episode in episodes:
        start = episode_start(args.seed + episode)
        offset = M_TO_MM * (start - mean)
        spoon_off = float(np.linalg.norm(offset[2:]))
        nearest = M_TO_MM * float(np.linalg.norm(train - start, axis=1).min())
        cells = "".join(f" {counts[episode][a]} |" for a in agents)
        print(f"| {episode} |" + "".join(f" {v:+.1f} |" for v in offset) + f" {spoon_off:.1f} | {nearest:.1f} |{cells}")
        far = spoon_off > args.far_mm
        far_n, near_n = far_n + far, near_n + (not far)
        (far_fail if far else near_fail).update(counts[episode])
    print(
        f"\nFailed foods on the {far_n} episodes whose spoon starts farther than {args.far_mm:g} mm from the mean, and"
    )
    print(f"on the other {near_n}:\n")
    print("| agent | far starts | other starts |\n|---|---:|---:|")
    for agent in agents:
        print(f"| {agent} | {far_fail[agent]} | {near_fail[agent]} |")
    if args.checkpoint:
        probe(args.checkpoint, args.probe, args.probe_foods, args.seed)


if __name__ == "__main__":
    main()
