"""Success per food under the task's spill rule (spilled volume under 5% of the volume scooped) against the paper's
words read literally (under 5% of all the food in the bowl), on the same bowls: the bowl-rule episodes from this
folder's evaluation, the scooped-rule ones from the published grids' episodes.csv.

    python results/spill_rule/compare.py results/spill_rule/episodes.csv \
        results/grid_calibrated_noload/episodes.csv results/grid_calibrated_dart/episodes.csv
"""

import csv
import sys
from collections import defaultdict

SEEN = ("rice", "buckwheat", "barley", "pasta")


def _by_agent_food(*paths: str) -> dict:
    out = defaultdict(dict)
    for path in paths:
        with open(path) as f:
            for row in csv.DictReader(f):
                out[(row["agent"], row["food"])][int(row["episode"])] = row
    return out


def main(bowl_csv: str, *scooped_csvs: str) -> None:
    bowl, scooped = _by_agent_food(bowl_csv), _by_agent_food(*scooped_csvs)
    print(
        "| agent | food | episodes | success, spill of the scooped volume | of the bowl "
        "| flipped to success | to failure |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    totals = defaultdict(lambda: [0, 0, 0])
    for key in sorted(bowl, key=lambda k: (k[0], list(bowl[k].values())[0]["food"])):
        if key not in scooped:
            continue
        episodes = sorted(set(scooped[key]) & set(bowl[key]))
        a = [scooped[key][i]["success"] == "True" for i in episodes]
        b = [bowl[key][i]["success"] == "True" for i in episodes]
        up = sum(y and not x for x, y in zip(a, b))
        down = sum(x and not y for x, y in zip(a, b))
        n = len(episodes)
        print(f"| {key[0]} | {key[1]} | {n} | {100 * sum(a) / n:.0f} | {100 * sum(b) / n:.0f} | {up} | {down} |")
        for group in ("seen" if key[1] in SEEN else "unseen", "overall"):
            t = totals[(key[0], group)]
            t[0] += n
            t[1] += sum(a)
            t[2] += sum(b)
    print()
    print("| agent | foods | episodes | scooped rule | bowl rule |")
    print("|---|---|---:|---:|---:|")
    for (agent, group), (n, a, b) in sorted(totals.items()):
        print(f"| {agent} | {group} | {n} | {100 * a / n:.0f} | {100 * b / n:.0f} |")


if __name__ == "__main__":
    main(*sys.argv[1:])
