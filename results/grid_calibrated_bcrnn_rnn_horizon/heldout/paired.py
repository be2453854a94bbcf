"""Episode-by-episode comparison of two reset periods on the same bowls, from this folder's committed episodes.

Each pair is one seed's episode on one bowl at both periods; a pair counts as gained when only the rarer reset
succeeds and lost when only the stock one does. The p-value is the two-sided sign test over those discordant pairs.
Run: python results/grid_calibrated_bcrnn_rnn_horizon/heldout/paired.py
"""

import csv
from pathlib import Path

from scipy.stats import binomtest

HERE = Path(__file__).parent
SEEN = {"rice", "buckwheat", "barley", "pasta"}


def successes(path: Path, agent: str | None = None) -> dict[tuple[str, str], bool]:
    with open(path) as f:
        return {
            (r["food"], r["episode"]): r["success"] == "True"
            for r in csv.DictReader(f)
            if agent is None or r["agent"] == agent
        }


def sign_test(gained: int, lost: int) -> float:
    return binomtest(gained, gained + lost).pvalue if gained + lost else 1.0


def compare(pairs: list[tuple[dict, dict]], label: str) -> None:
    for group, keep in (("seen", SEEN.__contains__), ("unseen", lambda f: f not in SEEN), ("overall", bool)):
        n = a = b = gained = lost = 0
        for stock, rarer in pairs:
            for key in stock:
                if keep(key[0]):
                    n += 1
                    a += stock[key]
                    b += rarer[key]
                    gained += rarer[key] and not stock[key]
                    lost += stock[key] and not rarer[key]
        print(f"{label:58s} {group:8s} {a:3d} -> {b:3d} of {n:3d}  gained {gained:2d} lost {lost:2d}  p={sign_test(gained, lost):.2f}")


grid = HERE.parent / "episodes.csv"
expert = "expert BC-RNN 50k rnn.horizon {} seed {}"
spacemouse = "spacemouse no-noops BC-RNN 20k rnn.horizon {} seed {}"
other_expert = [(successes(HERE / f"expert_seed{s}_h10_episodes.csv"), successes(HERE / f"expert_seed{s}_h20_episodes.csv")) for s in (2, 3)]
grid_expert = [(successes(grid, expert.format(10, s)), successes(grid, expert.format(20, s))) for s in (2, 3)]
other_spacemouse = [(successes(HERE / f"seed{s}_h10_episodes.csv"), successes(HERE / f"seed{s}_h30_episodes.csv")) for s in (1, 2, 3)]
grid_spacemouse = [(successes(grid, spacemouse.format(10, s)), successes(grid, spacemouse.format(30, s))) for s in (1, 2, 3)]
compare(grid_expert, "expert BC-RNN 50k seeds 2-3, 10 -> 20, grid bowls")
compare(other_expert, "expert BC-RNN 50k seeds 2-3, 10 -> 20, other bowls")
compare(grid_expert + other_expert, "expert BC-RNN 50k seeds 2-3, 10 -> 20, both")
compare(grid_spacemouse, "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, grid bowls")
compare(other_spacemouse, "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, other bowls")
compare(grid_spacemouse + other_spacemouse, "spacemouse cut BC-RNN 20k seeds 1-3, 10 -> 30, both")
