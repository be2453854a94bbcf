"""
A pooled grid in the shape of the paper's Tables II and III: each data half's models (their training seeds pooled)
beside the paper's VRI and 3DM columns, from a pooled evaluation's ``seeds/table.csv`` (veragmil-pool-results). The
paper's figures are copied from ../../../shared/reference/veragmil-paper.tex. A model's agent is
"<half> <model> <observation set> obs", optionally followed by its data's cut ("no-noops").

    python results/grid_calibrated_tables/paper_tables.py results/grid_calibrated_tables/seeds/table.csv \
        > results/grid_calibrated_tables/paper_tables.md
"""

from __future__ import annotations

import csv
import re
import sys

FOODS = ("rice", "buckwheat", "barley", "pasta", "peas", "beans", "flakes")
AVERAGES = {"seen": "seen (training) average", "unseen": "unseen average", "overall": "overall average"}
MODELS = ("operator", "BC", "BC-RNN", "BCQ", "Diffusion Policy")
PAPER_MODELS = ("Human", "BC", "BC-RNN", "BCQ")
HALVES = {"expert": "VRI", "spacemouse": "3DM"}

# The paper's Table II (success %, per food, then its all-materials average) and Table III (over the training foods)
PAPER_SUCCESS = {
    "VRI": {
        "BC": (82, 80, 78, 65, 55, 50, 35, 64),
        "BC-RNN": (90, 88, 85, 75, 65, 60, 50, 73),
        "BCQ": (93, 91, 89, 80, 75, 70, 60, 80),
        "Human": (97, 95, 96, 90, None, None, None, 95),
    },
    "3DM": {
        "BC": (65, 60, 58, 45, 40, 38, 20, 47),
        "BC-RNN": (75, 72, 70, 60, 50, 48, 30, 58),
        "BCQ": (85, 80, 78, 70, 65, 60, 40, 68),
        "Human": (91, 88, 90, 85, None, None, None, 89),
    },
}
PAPER_SPILL_TIME = {
    "VRI": {"BC": (20, 20), "BC-RNN": (12, 18), "BCQ": (8, 15), "Human": (3, 14)},
    "3DM": {"BC": (45, 30), "BC-RNN": (25, 26), "BCQ": (15, 22), "Human": (10, 19)},
}


def _agent(columns: list[str], half: str, model: str) -> str | None:
    """The pooled agent of ``model`` on ``half``'s data ("<half> operator" or "<half> <model> <obs> obs[ no-noops]")."""
    if model == "operator":
        name = f"{half} operator"
        return name if f"{name} success %" in columns else None
    pattern = re.compile(rf"({re.escape(half)} {re.escape(model)} \S+ obs( no-noops)?) success %")
    for c in columns:
        if match := pattern.fullmatch(c):
            return match.group(1)
    return None


def _paper_mean(values: tuple, indices: range) -> str:
    picked = [values[i] for i in indices if values[i] is not None]
    return f"{sum(picked) / len(picked):.2f}".rstrip("0").rstrip(".") if picked else "-"


def main(table_csv: str) -> None:
    with open(table_csv) as f:
        rows = {r["food"]: r for r in csv.DictReader(f)}
    columns = list(next(iter(rows.values())))
    for half, paper in HALVES.items():
        agents = {m: _agent(columns, half, m) for m in MODELS}
        agents = {m: a for m, a in agents.items() if a}
        print(f"### Table II, `{half}` data (the paper's {paper})\n")
        print(f"| food | {' | '.join(agents)} | {' | '.join(f'paper: {m}' for m in PAPER_MODELS)} |")
        print("|---|" + "---:|" * (len(agents) + len(PAPER_MODELS)))
        for food in (*FOODS[:4], "seen", *FOODS[4:], "unseen", "overall"):
            row = rows[AVERAGES.get(food, food)]
            ours = []
            for a in agents.values():
                ours.append(
                    f"{float(row[f'{a} success %']):.0f} ({float(row[f'{a} success % ci95 low']):.0f}-"
                    f"{float(row[f'{a} success % ci95 high']):.0f})"
                )
            if food in FOODS:
                k = FOODS.index(food)
                theirs = [PAPER_SUCCESS[paper][m][k] for m in PAPER_MODELS]
                theirs = ["-" if v is None else str(v) for v in theirs]
            else:
                span = {"seen": range(4), "unseen": range(4, 7), "overall": range(7, 8)}[food]
                theirs = [_paper_mean(PAPER_SUCCESS[paper][m], span) for m in PAPER_MODELS]
            label = food if food in FOODS else f"*{food} average*"
            print(f"| {label} | {' | '.join(ours)} | {' | '.join(theirs)} |")
        seen = rows[AVERAGES["seen"]]
        print(f"\n### Table III, `{half}` data, over the training foods (pieces and grams spilled: mean over all")
        print("episodes; completion time: mean over successes)\n")
        print(f"| metric | {' | '.join(agents)} | {' | '.join(f'paper: {m}' for m in PAPER_MODELS)} |")
        print("|---|" + "---:|" * (len(agents) + len(PAPER_MODELS)))
        for metric, key, fmt, paper_index in (
            ("spillage (pieces)", "spilled pieces mean", "{:.1f}", 0),
            ("spillage (g)", "spilled g mean", "{:.2f}", None),
            ("food carried (g)", "carried g mean", "{:.2f}", None),
            ("completion time (s)", "time s mean", "{:.1f}", 1),
        ):
            ours = [fmt.format(float(seen[f"{a} {key}"])) if seen[f"{a} {key}"] else "-" for a in agents.values()]
            theirs = [
                "-" if paper_index is None else str(PAPER_SPILL_TIME[paper][m][paper_index]) for m in PAPER_MODELS
            ]
            print(f"| {metric} | {' | '.join(ours)} | {' | '.join(theirs)} |")
        print()


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: paper_tables.py SEEDS_TABLE_CSV")
    main(sys.argv[1])
