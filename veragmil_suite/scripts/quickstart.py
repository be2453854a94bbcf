"""
veragmil-quickstart: the main job on a small default, headless.

Records a few scripted demonstrations of each training food, trains robomimic's BC on them briefly, evaluates the
checkpoint and the scripted expert itself on a seen food (rice) and an unseen one (peas), and prints the
paper's tables. Every stage is one of our console programs; larger runs: veragmil-study (README).
"""

from __future__ import annotations

import argparse
import sys

from veragmil_suite.pipeline import PipelineSettings
from veragmil_suite.scripts.study import add_pipeline_arguments, run


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
    return run(parser, argv)


if __name__ == "__main__":
    sys.exit(main())
