"""
veragmil-study: the paper's grid end to end from scripted data.

Two operator profiles (``expert``, smooth like the paper's VR operators, and ``spacemouse``, one axis at a time
like its 3D-mouse operators) each record a dataset of the training foods; BC, BC-RNN and BCQ (and Diffusion Policy,
``--algos``) train on each, with the observations of each ``--obs-sets``; every checkpoint, and each scripted operator
itself (the "Human" column's stand-in), is scored on all seven foods.
Tables II and III (markdown, CSV, JSON), the stage table and a bar chart land in <output-dir>/eval.

Run again with the same --output-dir, an interrupted or partial study resumes: recordings, trainings and
evaluation episodes already complete are skipped (each named), so a grid can be run in pieces. With --ray [ADDRESS]
the pieces run as Ray tasks, on this machine or spread over a cluster's nodes (docs/study.md: "On a cluster").

    veragmil-study                                   # small default: minutes per model on 2 cores
    veragmil-study --demos-per-food 30 --epochs 2000 --episodes 50    # the paper's sizes (docs/study.md)
    veragmil-study --demos-per-food 30 --epochs 100 --steps-per-epoch 500 --train-seeds 1 2 3   # mean over 3 seeds
    veragmil-study --algos bc diffusion_policy --obs-sets object no-load   # with and without grain counts
    veragmil-study --demos-per-food 30 --epochs 2000 --episodes 50 --ray HEAD:6379 --output-dir /shared/study
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import fields

from veragmil_suite.evaluation.agents import SPEC_HELP, parse_agent_argument
from veragmil_suite.models.foods import TRAINING_FOODS, UNSEEN_FOODS
from veragmil_suite.study.pipeline import run_pipeline
from veragmil_suite.study.settings import PipelineSettings, StageError
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.distributed import add_ray_argument, check_ray_argument

# Ctrl-C: what is finished stays, and the same command picks up from there
INTERRUPTED = "interrupted; run the same command (same --output-dir) again to resume: finished pieces are kept"


def add_pipeline_arguments(p: Parser, defaults: PipelineSettings) -> None:
    """The options study and quickstart share, with ``defaults`` shown in --help."""
    p.add_argument(
        "--output-dir",
        type=cli.output_folder,
        default=argparse.SUPPRESS,
        help=f"where data, runs and tables go; an existing one is resumed (default: {defaults.output_dir}/<date-time>)",
    )
    p.set_defaults(output_base=defaults.output_dir, default_agents=defaults.agents)
    p.add_argument("--profiles", type=cli.ListOf(cli.profile), default=defaults.profiles, help="operator profiles")
    p.add_argument("--algos", type=cli.ListOf(cli.algo), default=defaults.algos, help="algorithms trained")
    p.add_argument(
        "--obs-sets",
        type=cli.ListOf(cli.observation_set),
        default=defaults.obs_sets,
        help="train each model once per low-dim observation set, named in its column (veragmil_suite."
        "observation_sets): object holds grain counts, no-load what a real robot could observe",
    )
    p.add_argument("--train-foods", type=cli.ListOf(cli.food), default=defaults.train_foods, help="foods recorded")
    p.add_argument("--eval-foods", type=cli.ListOf(cli.food), default=defaults.eval_foods, help="foods evaluated")
    p.add_argument(
        "--demos-per-food",
        type=cli.ListOf(cli.count),
        default=defaults.demos_per_food,
        help="the paper: 30; several values train one model each (a learning curve over data)",
    )
    p.add_argument("--epochs", type=cli.count, default=defaults.epochs, help="the configs' own: 2000")
    p.add_argument(
        "--steps-per-epoch", type=cli.count, default=defaults.steps_per_epoch, help="gradient steps per epoch"
    )
    p.add_argument(
        "--algo-epochs",
        action="append",
        type=cli.KeyValue(cli.algo, cli.count, "ALGO=EPOCHS"),
        metavar="ALGO=EPOCHS",
        default=None,
        help="this algorithm's own number of epochs instead of --epochs (repeat for more), e.g. bc_rnn=40: "
        "BC-RNN costs 7x BC's time per gradient step; it is evaluated at its end and at the --eval-steps it reaches",
    )
    p.add_argument(
        "--eval-steps",
        type=cli.ListOf(cli.count),
        default=None,
        help="evaluate the checkpoints at these gradient steps (a learning curve; default: the last only)",
    )
    p.add_argument(
        "--episodes", type=cli.count, default=defaults.episodes, help="evaluation episodes per food and model"
    )
    p.add_argument(
        "--processes",
        type=cli.count,
        default=defaults.processes,
        help="parallel recording and evaluation processes (with --ray, the least number of pieces in flight)",
    )
    p.add_argument("--horizon", type=cli.count, default=defaults.horizon, help="longest episode, control steps")
    p.add_argument("--n-grains", type=cli.count, default=None, help="grains in the bowl (default: each food's own)")
    p.add_argument(
        "--physics",
        type=cli.physics,
        default=defaults.physics,
        help="the grain models every stage records and evaluates on (veragmil_suite.models.foods.PHYSICS)",
    )
    p.add_argument("--seed", type=cli.seed, default=defaults.seed, help="first recording seed")
    p.add_argument(
        "--train-seeds",
        type=cli.ListOf(cli.seed),
        default=None,
        metavar="SEED",
        help="train each model once per seed (torch's), on the same data and scored on the same episodes; "
        "eval/seeds.md gives each recipe's mean and range over them (default: --seed + 1 alone)",
    )
    p.add_argument(
        "--robots",
        aliases=["--robot"],
        type=cli.robot,
        default=defaults.robot,
        help="the robot that records, and that the models and operators scoop with (G1FixedLowerBody: the G1, "
        "with the humanoid extra)",
    )
    p.add_argument(
        "--no-operators",
        dest="score_demonstrators",
        action="store_false",
        help="do not score the scripted operators themselves (the Human column), e.g. when measure_expert has",
    )
    p.add_argument(
        "--verbose",
        "-v",
        action="store_true",
        help="also show what each recording and training prints (logged beside its results either way)",
    )
    p.add_argument(
        "--agent",
        action="append",
        type=cli.agent,
        metavar="[NAME=]SPEC",
        default=argparse.SUPPRESS,
        help=f"also evaluate this agent beside the run's own (repeat for more): SPEC is {SPEC_HELP} (default: "
        + (", ".join(f"{name}={spec}" for name, spec in defaults.agents.items()) or "none")
        + ")",
    )


def settings_from_args(args: argparse.Namespace) -> PipelineSettings:
    """The settings the options give: every PipelineSettings field an option of the same name sets, then the ones
    an option gives in another form (the output folder, --robots, --algo-epochs pairs, --agent texts, --ray)."""
    values = {f.name: getattr(args, f.name) for f in fields(PipelineSettings) if hasattr(args, f.name)}
    values.update(
        output_dir=getattr(args, "output_dir", None) or os.path.join(args.output_base, time.strftime("%Y%m%d-%H%M%S")),
        robot=args.robots,
        algo_epochs=algo_epochs(args.algo_epochs),
        agents=agent_columns(getattr(args, "agent", None), defaults=args.default_agents),
        ray=getattr(args, "ray", None),
    )
    return PipelineSettings(**values)


def algo_epochs(pairs: list[tuple[str, int]] | None) -> dict[str, int]:
    """``--algo-epochs`` values (cli.KeyValue pairs) as algorithm -> epochs, the last given for an algorithm."""
    return dict(pairs or [])


def agent_columns(texts: list[str] | None, defaults: dict[str, str]) -> dict[str, str]:
    """``--agent`` values as name -> SPEC (``defaults`` when none is given); ValueError for a bad or repeated one."""
    if texts is None:
        return dict(defaults)
    agents: dict[str, str] = {}
    for text in texts:
        name, spec = parse_agent_argument(text)
        if name in agents:
            raise ValueError(f"two agents are named {name!r}: give each a NAME= of its own")
        agents[name] = spec
    return agents


def run(args: argparse.Namespace, prog: str) -> int:
    """Runs the pipeline and prints the tables."""
    check_ray_argument(args)
    try:
        settings = settings_from_args(args)
    except ValueError as error:
        raise UsageError(str(error)) from None
    try:
        result = run_pipeline(settings, verbose=args.verbose)
    except StageError as error:
        print(f"{prog}: {error}", file=sys.stderr)
        return 1
    print(result.markdown())
    print(result.stages_markdown())
    print(f"Tables, chart and per-episode results: {settings.output_dir}/eval")
    return 0


def build_parser() -> Parser:
    parser = Parser("veragmil-study", description=__doc__.split("\n\n")[1].strip())
    defaults = PipelineSettings(
        output_dir="runs/study",
        profiles=["expert", "spacemouse"],
        algos=["bc", "bc_rnn", "bcq"],
        train_foods=list(TRAINING_FOODS),
        eval_foods=list(TRAINING_FOODS + UNSEEN_FOODS),
    )
    add_pipeline_arguments(parser, defaults)
    add_ray_argument(parser, "the recording attempts, training runs and evaluation episodes")
    return parser


@command(build_parser, interrupted=INTERRUPTED)
def main(args: argparse.Namespace) -> int:
    return run(args, "veragmil-study")


if __name__ == "__main__":
    sys.exit(main())
