"""Where the package's MuJoCo assets are, installed or in a source checkout."""

from __future__ import annotations

from pathlib import Path


def assets_root() -> Path:
    """The ``models/assets`` folder: package data of ``veragmil_suite.assets`` once installed."""
    try:
        import veragmil_suite.assets as installed

        return Path(next(iter(installed.__path__)))
    except (ImportError, StopIteration):
        return Path(__file__).resolve().parent.parent / "models" / "assets"


def asset_path(relative: str) -> str:
    """Absolute path of an asset, e.g. ``asset_path("grippers/spoon_gripper.xml")``."""
    path = assets_root() / relative
    if not path.exists():
        raise FileNotFoundError(f"veragmil_suite asset {relative!r} not found under {assets_root()}")
    return str(path)
