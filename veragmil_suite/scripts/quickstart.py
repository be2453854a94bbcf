"""
veragmil-quickstart: the main job on a small default, headless.

Records a few scripted demonstrations of each training food, trains robomimic's BC on them briefly, evaluates that
checkpoint, a BC checkpoint shipped with the package (trained longer on more demos, see
models/checkpoints/README.md) and the scripted expert itself on a seen food (rice) and an unseen one (peas), and
prints the paper's tables. Every stage is one of our console programs; larger runs: veragmil-study (README).
"""

from __future__ import annotations

import argparse
import sys

from veragmil_suite.asset_paths import checkpoint_path
from veragmil_suite.pipeline import PipelineSettings
from veragmil_suite.scripts.study import add_pipeline_arguments, run

# the shipped checkpoint the quickstart scores beside its own briefly trained one, and its column in the tables
PRETRAINED = "bc_expert_30demos"
PRETRAINED_LABEL = "BC pretrained (shipped)"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="veragmil-quickstart",
        description=__doc__.split("\n\n")[1].strip(),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    defaults = PipelineSettings(
        output_dir="runs/quickstart", profiles=["expert"], algos=["bc"], eval_foods=["rice", "peas"]
    )
    add_pipeline_arguments(parser, defaults)
    parser.add_argument(
        "--no-pretrained", action="store_true", help=f"leave out the shipped checkpoint ({PRETRAINED_LABEL})"
    )
    return run(parser, argv, lambda args: {} if args.no_pretrained else {PRETRAINED_LABEL: checkpoint_path(PRETRAINED)})


if __name__ == "__main__":
    sys.exit(main())
