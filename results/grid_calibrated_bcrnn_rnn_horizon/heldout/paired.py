"""Episode-by-episode comparison of two reset periods on the same bowls, from this folder's committed episodes.

Each pair is one seed's episode on one bowl at both periods; a pair counts as gained when only the rarer reset
succeeds and lost when only the stock one does. The pairs are counted, and tested (the exact two-sided sign test),
by veragmil_suite.evaluation.reporting.paired_comparison, as `veragmil-pool-results --paired` does.
Run: python results/grid_calibrated_bcrnn_rnn_horizon/heldout/paired.py
"""

import csv
from pathlib import Path

from veragmil_suite.evaluation.agents import EpisodeRecord
from veragmil_suite.evaluation.reporting import EvaluationResult, paired_comparison

HERE = Path(__file__).parent
FOODS = ["rice", "buckwheat", "barley", "pasta", "peas", "beans", "flakes"]


def typed(text: str) -> bool | int | float | str:
    """An episodes.csv cell as the record held it."""
    if text in ("True", "False"):
        return text == "True"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def episodes(path: Path, agent: str | None, name: str, offset: int) -> list[EpisodeRecord]:
    """``agent``'s episodes of ``path`` (all of them when None) renamed ``name``, numbered from ``offset`` so that
    episodes of two sets of bowls stay apart."""
    with open(path) as f:
        rows = [r for r in csv.DictReader(f) if agent is None or r["agent"] == agent]
    return [
        EpisodeRecord.from_dict(
            {**{k: typed(v) for k, v in r.items()}, "agent": name, "episode": offset + int(r["episode"])}
        )
        for r in rows
    ]


def compare(sets: list[list[tuple[int, tuple, tuple]]], label: str) -> None:
    """``sets``: per set of bowls, (training seed, (path, agent) of the stock period, (path, agent) of the rarer)."""
    records, points = [], []
    for offset, pairs in enumerate(sets):
        for seed, stock, rarer in pairs:
            for recipe, (path, agent) in (("stock", stock), ("rarer", rarer)):
                records += episodes(path, agent, f"{recipe} seed {seed}", 1000 * offset)
                points.append(dict(agent=f"{recipe} seed {seed}", recipe=recipe, train_seed=seed))
    unique_points = list({p["agent"]: p for p in points}.values())
    result = EvaluationResult(records, [p["agent"] for p in unique_points], FOODS)
    for row in paired_comparison(result, "stock", "rarer", unique_points):
        print(
            f"{label:58s} {row['group']:15s} {row['first']:3d} -> {row['second']:3d} of {row['pairs']:3d}  "
            f"gained {row['gained']:2d} lost {row['lost']:2d}  p={row['p']:.2f}"
        )


grid = HERE.parent / "episodes.csv"
expert = "expert BC-RNN 50k rnn.horizon {} seed {}"
spacemouse = "spacemouse no-noops BC-RNN 20k rnn.horizon {} seed {}"
grid_expert = [(s, (grid, expert.format(10, s)), (grid, expert.format(20, s))) for s in (2, 3)]
other_expert = [
    (s, (HERE / f"expert_seed{s}_h10_episodes.csv", None), (HERE / f"expert_seed{s}_h20_episodes.csv", None))
    for s in (2, 3)
]
grid_spacemouse = [(s, (grid, spacemouse.format(10, s)), (grid, spacemouse.format(30, s))) for s in (1, 2, 3)]
other_spacemouse = [
    (s, (HERE / f"seed{s}_h10_episodes.csv", None), (HERE / f"seed{s}_h30_episodes.csv", None)) for s in (1, 2, 3)
]
compare([grid_expert], "expert BC-RNN 50k seeds 2-3, 10 -> 20, grid bowls")
compare([other_expert], "expert BC-RNN 50k seeds 2-3, 10 -> 20, other bowls")
compare([grid_expert, other_expert], "expert BC-RNN 50k seeds 2-3, 10 -> 20, both")
compare([grid_spacemouse], "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, grid bowls")
compare([other_spacemouse], "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, other bowls")
compare([grid_spacemouse, other_spacemouse], "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, both")
