"""Where the package's data is (MuJoCo assets, robomimic configs), installed or in a source checkout."""

from __future__ import annotations

from pathlib import Path


def assets_root() -> Path:
    """``veragmil_suite/assets`` when installed from a wheel, else the checkout's top-level ``models/assets``."""
    package = Path(__file__).resolve().parents[1]
    installed = package / "assets"
    return installed if installed.is_dir() else package.parent / "models" / "assets"


def asset_path(relative: str) -> str:
    """Absolute path of an asset, e.g. ``asset_path("grippers/spoon_gripper.xml")``."""
    path = assets_root() / relative
    if not path.exists():
        raise FileNotFoundError(f"veragmil_suite asset {relative!r} not found under {assets_root()}")
    return str(path)


def configs_root() -> Path:
    """``veragmil_suite/configs`` when installed from a wheel, else the checkout's top-level ``configs/json``."""
    package = Path(__file__).resolve().parents[1]
    installed = package / "configs"
    return installed if installed.is_dir() else package.parent / "configs" / "json"


def config_path(name: str) -> str:
    """Absolute path of one of our robomimic configs, e.g. ``config_path("bc_rnn")``."""
    path = configs_root() / f"{name}.json"
    if not path.exists():
        accepted = sorted(p.stem for p in configs_root().glob("*.json"))
        raise FileNotFoundError(f"no robomimic config {name!r} under {configs_root()}; accepted: {accepted}")
    return str(path)


def pretrained_checkpoint(name: str) -> Path | None:
    """A robomimic checkpoint shipped in the checkout's ``models/checkpoints`` (None in an installed wheel, which
    leaves them out: they are results, remade by the command in that folder's README)."""
    path = Path(__file__).resolve().parents[2] / "models" / "checkpoints" / name
    return path if path.is_file() else None
