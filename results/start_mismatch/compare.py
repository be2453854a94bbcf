"""Restarted starts (restarted_start.py's JSON lines) against the same checkpoints' plain evaluation (a committed
episodes.csv), episode by episode on the same bowls: successes, episodes that never reach the pile (on the five
bowls where the spoon starts high, and elsewhere), and the exact two-sided sign test of the pairs that differ.
Run from the repository root:
python results/start_mismatch/compare.py <episodes.csv> "<agent in it>=<restarted.jsonl>" ..."""

import csv
import json
import sys

from scipy.stats import binomtest

SEEN = ("rice", "buckwheat", "barley", "pasta")
HIGH_START_BOWLS = (3, 4, 7, 10, 18)


def truthy(value) -> bool:
    return value is True or str(value).lower() == "true"


with open(sys.argv[1]) as f:
    plain_rows = list(csv.DictReader(f))
print(
    "| model | foods | episodes | success, plain start | success, restarted start | gained | lost | p | "
    "never reach the pile, plain (high-start bowls) | restarted (high-start bowls) |"
)
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for pair in sys.argv[2:]:
    agent, path = pair.split("=")
    plain = {(r["food"], int(r["episode"])): r for r in plain_rows if r["agent"] == agent}
    restarted = {(r["food"], r["episode"]): r for r in map(json.loads, open(path).read().splitlines())}
    for group, foods in (("seen", SEEN), ("unseen", None), ("all", "all")):
        keys = [k for k in restarted if k in plain and (foods == "all" or (k[0] in SEEN) == (foods is not None))]
        a = [truthy(plain[k]["success"]) for k in keys]
        b = [truthy(restarted[k]["success"]) for k in keys]
        gained = sum(y and not x for x, y in zip(a, b))
        lost = sum(x and not y for x, y in zip(a, b))
        p = binomtest(gained, gained + lost).pvalue if gained + lost else 1.0

        def never(rows):
            return sum(r["stage"] == "start" for r in rows), sum(
                r["stage"] == "start" and int(r["episode"]) in HIGH_START_BOWLS for r in rows
            )

        n_plain, h_plain = never([plain[k] for k in keys])
        n_rest, h_rest = never([restarted[k] for k in keys])
        print(
            f"| {agent} | {group} | {len(keys)} | {sum(a)} | {sum(b)} | {gained} | {lost} | {p:.3g} | "
            f"{n_plain} ({h_plain}) | {n_rest} ({h_rest}) |"
        )
