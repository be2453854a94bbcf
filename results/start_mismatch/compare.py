"""Restarted starts (restarted_start.py's JSON lines) against the same checkpoints' plain evaluation (a committed
results.json), episode by episode on the same bowls (veragmil_suite.evaluation.reporting.paired_comparison: the
pairs each wins alone and the exact two-sided sign test of those), beside the episodes that never reach the pile
(on the five bowls where the spoon starts high).
Run from the repository root:
python results/start_mismatch/compare.py <results.json> "<agent in it>=<restarted.jsonl>" ..."""

import json
import sys

from veragmil_suite.evaluation.agents import EpisodeRecord
from veragmil_suite.evaluation.reporting import EvaluationResult, paired_comparison
from veragmil_suite.evaluation.reporting.tables import food_groups

HIGH_START_BOWLS = (3, 4, 7, 10, 18)
RESTARTED = "{}, restarted start"


def never(records: list[EpisodeRecord], foods: list[str]) -> str:
    """Episodes on ``foods`` that never reach the pile (of them on the high-start bowls)."""
    started = [e for e in records if e.food in foods and e.stage == "start"]
    return f"{len(started)} ({sum(e.episode in HIGH_START_BOWLS for e in started)})"


committed = json.loads(open(sys.argv[1]).read())
env_kwargs = committed["config"].get("env_kwargs")
print(
    "| model | foods | episodes | success, plain start | success, restarted start | gained | lost | p | "
    "never reach the pile, plain (high-start bowls) | restarted (high-start bowls) |"
)
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for pair in sys.argv[2:]:
    agent, path = pair.split("=")
    plain = [EpisodeRecord.from_dict(e, env_kwargs) for e in committed["episodes"] if e["agent"] == agent]
    restarted = [
        EpisodeRecord.from_dict({**json.loads(line), "agent": RESTARTED.format(agent)}, env_kwargs)
        for line in open(path).read().splitlines()
    ]
    foods = list(dict.fromkeys(e.food for e in plain))
    result = EvaluationResult(plain + restarted, [agent, RESTARTED.format(agent)], foods)
    groups = dict(food_groups(foods), overall=foods)
    for row in paired_comparison(result, agent, RESTARTED.format(agent)):
        foods_of_row = groups[row["group"]]
        print(
            f"| {agent} | {row['group']} | {row['pairs']} | {row['first']} | {row['second']} | {row['gained']} | "
            f"{row['lost']} | {row['p']:.3g} | {never(plain, foods_of_row)} | {never(restarted, foods_of_row)} |"
        )
