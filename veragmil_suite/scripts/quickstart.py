"""
veragmil-quickstart: the main job on a small default, headless.

Records a few scripted demonstrations of each training food, trains robomimic's BC on them briefly, evaluates the
checkpoint, the scripted expert itself and the shipped BC-RNN checkpoint trained at the study's size (30 expert
demos per food, 50k gradient steps; models/checkpoints/README.md) on a seen food (rice) and an unseen one (peas),
and prints the paper's tables. Every stage is one of our console programs; larger runs: veragmil-study (docs/study.md).
"""

from __future__ import annotations

import argparse
import sys

from veragmil_suite.scripts.study import INTERRUPTED, add_pipeline_arguments, run
from veragmil_suite.study.settings import PipelineSettings
from veragmil_suite.utils.asset_paths import pretrained_checkpoint
from veragmil_suite.utils.cli.handler import command
from veragmil_suite.utils.cli.parser import Parser

# BC-RNN trained by veragmil-study on 30 expert demos per training food for 50k gradient steps, with the configs'
# observations (no grain counts), on the calibrated physics (models/checkpoints)
PRETRAINED = "bc_rnn_no-load-size_expert_30demos_50k.pth"
PRETRAINED_NAME = "pretrained BC-RNN no-load-size obs 50k"


def build_parser() -> Parser:
    parser = Parser("veragmil-quickstart", description=__doc__.split("\n\n")[1].strip())
    shipped = pretrained_checkpoint(PRETRAINED)
    defaults = PipelineSettings(
        output_dir="runs/quickstart",
        profiles=["expert"],
        algos=["bc"],
        eval_foods=["rice", "peas"],
        agents={PRETRAINED_NAME: str(shipped)} if shipped else {},
    )
    add_pipeline_arguments(parser, defaults)
    return parser


@command(build_parser, interrupted=INTERRUPTED)
def main(args: argparse.Namespace) -> int:
    return run(args, "veragmil-quickstart")


if __name__ == "__main__":
    sys.exit(main())
