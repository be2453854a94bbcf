"""Where the package's MuJoCo assets are, installed or in a source checkout."""

from __future__ import annotations

from pathlib import Path


def assets_root() -> Path:
    """``veragmil_suite/assets`` when installed from a wheel, else the checkout's top-level ``models/assets``."""
    package = Path(__file__).resolve().parent
    installed = package / "assets"
    return installed if installed.is_dir() else package.parent / "models" / "assets"


def asset_path(relative: str) -> str:
    """Absolute path of an asset, e.g. ``asset_path("grippers/spoon_gripper.xml")``."""
    path = assets_root() / relative
    if not path.exists():
        raise FileNotFoundError(f"veragmil_suite asset {relative!r} not found under {assets_root()}")
    return str(path)
