"""
veragmil-export-lerobot: a ScoopGranular demonstration file as a LeRobotDataset (format v3.0, cameras as video),
for LeRobot's training scripts; written by the lerobot-dataset package (pip install ".[lerobot]").

    veragmil-export-lerobot demos/scoop.hdf5 --output-dir lerobot/scoop
    veragmil-export-lerobot demos/scoop.hdf5 --output-dir lerobot/scoop_rice --filter-key rice --repo-id me/scoop_rice

What goes where: veragmil_suite.data.lerobot_export.
"""

from __future__ import annotations

import argparse
import sys

from veragmil_suite.data.lerobot_export import VIDEO_CODECS, export_lerobot
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import command
from veragmil_suite.utils.cli.parser import Parser

PROG = "veragmil-export-lerobot"


def build_parser() -> Parser:
    p = Parser(PROG, description=__doc__.split("\n\n")[1].strip())
    p.add_input(
        "dataset", "--dataset", cli.dataset, help="HDF5 file (robomimic's schema, as veragmil-collect writes it)"
    )
    p.add_argument(
        "--output-dir",
        "-o",
        type=cli.output_folder,
        required=True,
        help="the LeRobotDataset's folder (new unless --force)",
    )
    p.add_argument(
        "--repo-id", type=cli.text, default=None, help="the dataset's name on the hub (default: veragmil/<file>)"
    )
    p.add_argument("--filter-key", type=cli.text, default=None, help="only these demos (a mask of the file: rice, ...)")
    p.add_argument(
        "--vcodec", type=cli.Choice("video codec", VIDEO_CODECS), default=VIDEO_CODECS[0], help="video codec"
    )
    p.add_argument("--force", action="store_true", help="replace the output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


@command(build_parser)
def main(args: argparse.Namespace) -> int:
    """veragmil-export-lerobot: a demonstration file as a LeRobotDataset."""
    summary = export_lerobot(
        args.dataset, args.output_dir, args.repo_id, args.filter_key, args.vcodec, args.force, progress=not args.quiet
    )
    foods = ", ".join(f"{food} {n}" for food, n in sorted(summary.foods.items()))
    cameras = ", ".join(summary.cameras) or "none (veragmil-render-obs renders them from the states)"
    print(
        f"wrote {summary.episodes} episodes ({summary.frames} frames at {summary.fps} fps; {foods}) to {summary.root} "
        f"as LeRobotDataset {summary.repo_id}; cameras as video: {cameras}"
        + (f"; not exported: {', '.join(summary.skipped_keys)}" if summary.skipped_keys else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
