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
import sys
from dataclasses import fields

from veragmil_suite.models.foods import TRAINING_FOODS, UNSEEN_FOODS
from veragmil_suite.study.pipeline import run_pipeline
from veragmil_suite.study.settings import PipelineSettings, StageError
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.distributed import add_ray_argument, check_ray_argument

# Ctrl-C: what is finished stays, and the same command picks up from there
INTERRUPTED = "interrupted; run the same command (same --output-dir) again to resume: finished pieces are kept"


def add_pipeline_arguments(p: Parser, defaults: PipelineSettings) -> None:
    """The options study and quickstart share, one per PipelineSettings field that has an Option, with
    ``defaults`` shown in --help."""
    p.set_defaults(pipeline_defaults=defaults)
    for f in fields(PipelineSettings):
        option = f.metadata.get("option")
        if option is None:
            continue
        default = getattr(defaults, f.name)
        kwargs = {"type": option.kind, "action": option.action, "metavar": option.metavar, "dest": f.name}
        p.add_argument(
            *(option.flags or ("--" + f.name.replace("_", "-"),)),
            aliases=option.aliases,
            default=argparse.SUPPRESS if option.parse else default,
            help=option.help.replace("{default}", option.show(default)),
            **{k: v for k, v in kwargs.items() if v is not None},
        )
    p.add_argument(
        "--verbose",
        "-v",
        action="store_true",
        help="also show what each recording and training prints (logged beside its results either way)",
    )


def settings_from_args(args: argparse.Namespace) -> PipelineSettings:
    """The settings the options give: each field its option's value (through the option's ``parse``), the ones
    without an option of their own (--ray) from an argument of the same name, the rest the parser's defaults."""
    defaults = args.pipeline_defaults
    values = {}
    for f in fields(PipelineSettings):
        option = f.metadata.get("option")
        if option is not None and option.parse:
            values[f.name] = option.parse(getattr(args, f.name, None), getattr(defaults, f.name))
        else:
            values[f.name] = getattr(args, f.name, getattr(defaults, f.name))
    return PipelineSettings(**values)


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
