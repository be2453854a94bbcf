"""Where the package's data is (MuJoCo assets, robomimic configs, pretrained checkpoints), installed or in a source
checkout."""

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


def configs_root() -> Path:
    """``veragmil_suite/configs`` when installed from a wheel, else the checkout's top-level ``configs/json``."""
    package = Path(__file__).resolve().parent
    installed = package / "configs"
    return installed if installed.is_dir() else package.parent / "configs" / "json"


def config_path(name: str) -> str:
    """Absolute path of one of our robomimic configs, e.g. ``config_path("bc_rnn")``."""
    path = configs_root() / f"{name}.json"
    if not path.exists():
        accepted = sorted(p.stem for p in configs_root().glob("*.json"))
        raise FileNotFoundError(f"no robomimic config {name!r} under {configs_root()}; accepted: {accepted}")
    return str(path)


def checkpoints_root() -> Path:
    """``veragmil_suite/checkpoints`` when installed from a wheel, else the checkout's ``models/checkpoints``."""
    package = Path(__file__).resolve().parent
    installed = package / "checkpoints"
    return installed if installed.is_dir() else package.parent / "models" / "checkpoints"


def checkpoint_path(name: str) -> str:
    """Absolute path of a robomimic checkpoint shipped with the package (models/checkpoints/README.md says how each
    was made), e.g. ``checkpoint_path("bc_expert_30demos")``."""
    path = checkpoints_root() / f"{name}.pth"
    if not path.exists():
        accepted = sorted(p.stem for p in checkpoints_root().glob("*.pth"))
        raise FileNotFoundError(f"no shipped checkpoint {name!r} under {checkpoints_root()}; accepted: {accepted}")
    return str(path)
