"""
veragmil-publish-results: copy a study's tables and records into results/ with the command that made them, the
host, the package versions and the wall times; datasets and checkpoints stay behind.

    veragmil-publish-results runs/grid --output-dir results/grid --command "veragmil-study --output-dir runs/grid ..."
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from veragmil_suite.study.publish import publish
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.whole_files import same_file


def build_parser() -> Parser:
    p = Parser(
        "veragmil-publish-results", description=__doc__.split("\n\n")[0].strip(), epilog=__doc__.split("\n\n", 1)[1]
    )
    p.add_argument("study_dir", type=cli.Text("a veragmil-study --output-dir"), help="a veragmil-study --output-dir")
    p.add_argument("--output-dir", type=cli.output_folder, required=True, help="a folder under results/")
    p.add_argument(
        "--command",
        type=cli.Text("the command on one line"),
        required=True,
        help="the exact command that made the study",
    )
    p.add_argument("--force", action="store_true", help="overwrite what an earlier publication left in --output-dir")
    return p


@command(build_parser)
def main(args: argparse.Namespace) -> int:
    source = Path(args.study_dir) / "eval"
    if same_file(args.output_dir, source):
        raise UsageError(f"--output-dir {args.output_dir} is the study's own evaluation folder: publish to another one")
    cli.refuse_existing(str(Path(args.output_dir) / "RUN.md"), args.force)
    try:
        written = publish(Path(args.study_dir), Path(args.output_dir), args.command)
    except ValueError as e:
        raise UsageError(str(e)) from None
    for name in written:
        print(Path(args.output_dir) / name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
