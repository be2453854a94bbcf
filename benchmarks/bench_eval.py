"""
Evaluation throughput of veragmil-evaluate: episodes per minute with 1 and 2 worker processes, and their ratio.

The same episodes (same agent, food and seeds, so the same work) run once per process count through
veragmil_suite.evaluation.evaluate.evaluate, timed from the call to the last record: worker start-up is included, as a
user pays it. A warm-up episode first fills the settled-pile cache. The issue's target is a ratio of at least 1.7.

    python benchmarks/bench_eval.py                                   # the scripted expert on pasta
    python benchmarks/bench_eval.py --food rice --episodes 6 --checkpoint runs/x/models/model_epoch_20.pth
"""

from __future__ import annotations

import argparse
import os
import sys

# OSMesa whatever the display (veragmil_suite.utils.rendering's forced choice), set before robosuite is imported
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

# the package imports robosuite: after MUJOCO_GL
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.numbers import seed_span_problem  # noqa: E402
from veragmil_suite.utils.timing import stopwatch  # noqa: E402

TARGET_RATIO = 1.7
SECONDS_PER_MINUTE = 60.0


def bench(spec: str, food: str, episodes: int, processes: int, horizon: int, seed: int) -> dict:
    """Runs ``episodes`` episodes of one agent on ``food`` in ``processes`` workers; returns the rates."""
    from veragmil_suite.evaluation.evaluate import evaluate  # the package's evaluation imports torch: only to run

    with stopwatch() as elapsed:
        result = evaluate(
            {"agent": spec}, [food], episodes, processes=processes, seed=seed, horizon=horizon, progress=False
        )
    wall = elapsed.wall_s
    steps = sum(e.steps for e in result.episodes)
    return dict(
        processes=processes,
        wall_s=wall,
        episodes_per_min=episodes / wall * SECONDS_PER_MINUTE,
        steps_per_s=steps / wall,
        successes=sum(e.success for e in result.episodes),
    )


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_eval.py", description=__doc__)
    parser.add_argument("--food", type=cli.food, default="pasta", help="the food of the episodes")
    parser.add_argument(
        "--episodes", type=cli.count, default=8, help="episodes per measurement (even: 2 workers share them)"
    )
    parser.add_argument("--horizon", type=cli.count, default=400, help="control steps an episode may take at most")
    parser.add_argument("--seed", type=cli.seed, default=0, help="the first episode's seed")
    parser.add_argument("--checkpoint", type=cli.checkpoint, help="also measure this robomimic checkpoint")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """The expert (and --checkpoint) with 1 and 2 worker processes, and the ratio of their rates."""
    problem = seed_span_problem(args.seed, args.episodes)
    if problem:
        raise cli.UsageError(problem)
    agents = {"expert": "expert"}
    if args.checkpoint:
        agents["checkpoint"] = args.checkpoint
    print(f"load average before: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    bench("expert", args.food, 1, 1, args.horizon, args.seed)  # warm-up: settles and caches the piles
    print(f"{'agent':<11} {'food':<8} {'episodes':>8} {'procs':>5} {'wall s':>7} {'ep/min':>7} {'steps/s':>8}")
    for name, spec in agents.items():
        rates = {}
        for processes in (1, 2):
            r = rates[processes] = bench(spec, args.food, args.episodes, processes, args.horizon, args.seed)
            print(
                f"{name:<11} {args.food:<8} {args.episodes:>8} {processes:>5} {r['wall_s']:>7.1f}"
                f" {r['episodes_per_min']:>7.1f} {r['steps_per_s']:>8.1f}  ({r['successes']} successes)",
                flush=True,
            )
        ratio = rates[2]["episodes_per_min"] / rates[1]["episodes_per_min"]
        verdict = "meets" if ratio >= TARGET_RATIO else "misses"
        print(f"{name}: 2 processes / 1 process = {ratio:.2f}x ({verdict} the {TARGET_RATIO}x target)")
    print(f"load average after: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
