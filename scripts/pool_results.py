"""
Pools agents of several finished evaluations (each a results.json) into one evaluation folder, as if one run had
scored them all: the tables, stages and chart, and, when some recipe has several training seeds (agents named
"<recipe> seed <n>"), the seed tables a multi-seed study writes. A later training seed is scored alone, then pooled
with the seeds an earlier study scored, without re-running their episodes.

    python scripts/pool_results.py runs/bc_four_seeds/eval \
        --agent "expert BC seed 1=results/grid_stockobs_expert/results.json:expert BC seed 1" \
        --agent "expert BC seed 4=runs/grid_bc4/eval/results.json:expert BC"

The evaluations must agree on what decides an episode's outcome (foods, episodes, seeds, horizon, robot, success
hold, env kwargs, package versions); a mismatch names the setting and both values.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path

from veragmil_suite.evaluation.agents import EpisodeRecord
from veragmil_suite.evaluation.reporting import EvaluationResult, write_seed_tables

# the evaluation settings two results.json must share for their episodes to be comparable
SHARED_SETTINGS = ("foods", "episodes", "seed", "horizon", "robot", "success_hold_s", "env_kwargs", "versions")
SEED_LABEL = re.compile(r"^(?P<recipe>.+) seed (?P<seed>\d+)$")


def parse_agent(text: str) -> tuple[str, Path, str]:
    """``NAME=RESULTS_JSON:AGENT`` (``RESULTS_JSON:AGENT`` keeps the agent's name) -> (name, source, agent)."""
    name, sep, rest = text.partition("=")
    if not sep:
        name, rest = "", text
    source, sep, agent = rest.rpartition(":")
    if not sep or not source or not agent:
        raise argparse.ArgumentTypeError(f"expected NAME=RESULTS_JSON:AGENT or RESULTS_JSON:AGENT, got {text!r}")
    return (name.strip() or agent.strip()), Path(source), agent.strip()


def pool(choices: list[tuple[str, Path, str]]) -> tuple[EvaluationResult, list[dict]]:
    """The chosen agents' episodes under their new names, and the seed points (agent, recipe, train_seed) of the
    names that carry a training seed."""
    loaded: dict[Path, dict] = {}
    episodes: list[EpisodeRecord] = []
    agents: dict[str, str] = {}
    sources: dict[str, str] = {}
    reference: tuple[Path, dict] | None = None
    for name, source, agent in choices:
        if name in agents:
            raise SystemExit(f"pool_results: the name {name!r} is given twice")
        if source not in loaded:
            if not source.is_file():
                raise SystemExit(f"pool_results: {source} not found (expected an evaluation's results.json)")
            loaded[source] = json.loads(source.read_text())
        config = loaded[source]["config"]
        if reference is None:
            reference = (source, config)
        for key in SHARED_SETTINGS:
            if config.get(key) != reference[1].get(key):
                raise SystemExit(
                    f"pool_results: {source} and {reference[0]} differ in {key!r} "
                    f"({config.get(key)!r} against {reference[1].get(key)!r}); their episodes are not comparable"
                )
        known = config.get("agents", {})
        if agent not in known:
            raise SystemExit(f"pool_results: {source} has no agent {agent!r}; it has {sorted(known)}")
        agents[name] = known[agent]
        sources[name] = f"{source}:{agent}"
        episodes += [
            replace(EpisodeRecord.from_dict(e), agent=name) for e in loaded[source]["episodes"] if e["agent"] == agent
        ]
    config = {k: reference[1][k] for k in SHARED_SETTINGS if k in reference[1]}
    result = EvaluationResult(
        episodes=episodes,
        agents=list(agents),
        foods=list(config["foods"]),
        config=dict(config, agents=agents, pooled_from=sources),
    )
    points = []
    for name in agents:
        match = SEED_LABEL.match(name)
        if match:
            points.append(dict(agent=name, recipe=match["recipe"], train_seed=int(match["seed"])))
    return result, points


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1].strip())
    parser.add_argument("output_dir", type=Path, help="the pooled evaluation's folder (a study's eval/ shape)")
    parser.add_argument(
        "--agent",
        type=parse_agent,
        action="append",
        required=True,
        metavar="NAME=RESULTS_JSON:AGENT",
        help="an agent of a finished evaluation, under a new name ('<recipe> seed <n>' joins the seed tables)",
    )
    args = parser.parse_args(argv)
    result, points = pool(args.agent)
    for path in result.write(str(args.output_dir)).values():
        print(path)
    if any(n > 1 for n in Counter(p["recipe"] for p in points).values()):
        write_seed_tables(result, points, args.output_dir)
        print(args.output_dir / "seeds.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
