"""
veragmil-pool-results: pool agents of finished evaluations (each a results.json) into one evaluation folder, as if
one run had scored them all: the tables, stages and chart, and, when a recipe has several training seeds (agents
named "<recipe> seed <n>"), the seed tables a multi-seed study writes.

A later training seed is scored alone, then pooled with the seeds an earlier study scored, without re-running their
episodes:

    veragmil-pool-results runs/bc_four_seeds/eval \\
        --agent "expert BC seed 1=results/grid_stockobs_expert/results.json:expert BC seed 1" \\
        --agent "expert BC seed 4=runs/grid_bc4/eval/results.json:expert BC"

The evaluations must agree on what decides an episode's outcome (foods, episodes, seeds, horizon, robot, success
hold, env kwargs, package versions); a mismatch names the setting and both values. The wall times of the pieces
behind the pooled agents (their recordings, trainings and evaluations, from each source study's timings.json) land in
<output-dir>/timings.json, which veragmil-publish-results reads.

--paired FIRST SECOND compares two of the pooled agents, or two recipes seed by seed, episode by episode on the same
bowls (paired.md: the pairs each wins alone and the exact sign test of those), e.g. a recipe against its variant:

    veragmil-pool-results runs/cut_against_full/eval --agent ... \\
        --paired "spacemouse BC" "spacemouse BC no-noops"
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

from veragmil_suite.evaluation.reporting import paired_comparison, paired_markdown, pool, write_seed_tables
from veragmil_suite.study.publish import pooled_timings
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.whole_files import same_file, write_text_whole


class PooledAgent(cli.Text):
    """``NAME=RESULTS_JSON:AGENT`` (``RESULTS_JSON:AGENT`` keeps the agent's name) -> (name, source, agent)."""

    def __init__(self):
        super().__init__("NAME=RESULTS_JSON:AGENT or RESULTS_JSON:AGENT")

    def __call__(self, text: str) -> tuple[str, Path, str]:
        super().__call__(text)
        name, sep, rest = text.partition("=")
        if not sep:
            name, rest = "", text
        source, sep, agent = rest.rpartition(":")
        if not sep or not source or not agent.strip():
            raise self.refuse(text, f"expected {self.accepted}")
        return (name.strip() or agent.strip()), Path(source), agent.strip()


def build_parser() -> Parser:
    p = Parser(
        "veragmil-pool-results", description=__doc__.split("\n\n")[0].strip(), epilog=__doc__.split("\n\n", 1)[1]
    )
    p.add_argument("output_dir", type=cli.output_folder, help="the pooled evaluation's folder (a study's eval/ shape)")
    p.add_argument(
        "--agent",
        type=PooledAgent(),
        action="append",
        required=True,
        metavar="NAME=RESULTS_JSON:AGENT",
        help="an agent of a finished evaluation, under a new name ('<recipe> seed <n>' joins the seed tables)",
    )
    p.add_argument(
        "--paired",
        type=cli.Text("an agent or recipe of the pooled evaluation"),
        nargs=2,
        action="append",
        default=[],
        metavar=("FIRST", "SECOND"),
        help="compare SECOND against FIRST episode by episode (pooled agents, or recipes seed by seed): paired.md",
    )
    p.add_argument("--force", action="store_true", help="overwrite an evaluation OUTPUT_DIR already holds")
    return p


@command(build_parser)
def main(args: argparse.Namespace) -> int:
    for _, source, _ in args.agent:
        if same_file(source.parent, args.output_dir):
            raise UsageError(f"{args.output_dir} holds {source}, which is pooled: write the pool to another folder")
    cli.refuse_existing(str(Path(args.output_dir) / "results.json"), args.force)
    try:
        result, points = pool(args.agent)
        comparisons = [(a, b, paired_comparison(result, a, b, points)) for a, b in args.paired]
    except ValueError as e:
        raise UsageError(str(e)) from None
    for path in result.write(str(args.output_dir)).values():
        print(path)
    timings = pooled_timings(result.config)
    if timings:
        write_text_whole(Path(args.output_dir) / "timings.json", json.dumps(timings, indent=2) + "\n")
        print(Path(args.output_dir) / "timings.json")
    if any(n > 1 for n in Counter(p["recipe"] for p in points).values()):
        write_seed_tables(result, points, Path(args.output_dir))
        print(Path(args.output_dir) / "seeds.md")
    if comparisons:
        paired = paired_markdown(comparisons)
        write_text_whole(Path(args.output_dir) / "paired.md", paired)
        print(Path(args.output_dir) / "paired.md")
        print(paired, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
