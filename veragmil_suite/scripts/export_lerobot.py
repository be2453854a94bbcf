"""
veragmil-export-lerobot: a ScoopGranular demonstration file as a LeRobotDataset (format v3.0, cameras as video),
for LeRobot's training scripts; written by the lerobot-dataset package (pip install ".[lerobot]").

    veragmil-export-lerobot demos/scoop.hdf5 --output lerobot/scoop
    veragmil-export-lerobot demos/scoop.hdf5 --output lerobot/scoop_rice --filter-key rice --repo-id me/scoop_rice

What goes where: veragmil_suite.lerobot_export.
"""

from __future__ import annotations

import argparse
import sys

from veragmil_suite.lerobot_export import VIDEO_CODECS, ExtraNotInstalled, export_lerobot
from veragmil_suite.recording import DatasetError

PROG = "veragmil-export-lerobot"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog=PROG,
        description=__doc__.split("\n\n")[1].strip(),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("dataset", help="HDF5 file (robomimic's schema, as veragmil-collect writes it)")
    p.add_argument("--output", "-o", required=True, help="the LeRobotDataset's folder (must not exist unless --force)")
    p.add_argument("--repo-id", default=None, help="the dataset's name on the hub (default: veragmil/<file name>)")
    p.add_argument("--filter-key", default=None, help="only these demos (a mask of the file: success, rice, ...)")
    p.add_argument("--vcodec", choices=VIDEO_CODECS, default=VIDEO_CODECS[0], help="video codec of the cameras")
    p.add_argument("--force", action="store_true", help="replace --output")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    args = p.parse_args(argv)
    try:
        summary = export_lerobot(
            args.dataset, args.output, args.repo_id, args.filter_key, args.vcodec, args.force, progress=not args.quiet
        )
    except (DatasetError, ExtraNotInstalled) as error:
        print(f"{PROG}: {error}", file=sys.stderr)
        return 2
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
