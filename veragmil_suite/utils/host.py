"""The machine and software a measurement ran on: what results record beside their figures, and what decides
whether an episode scored on one machine ends the same way on another."""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

# the packages whose versions results record
RECORDED_PACKAGES = ("veragmil_suite", "robosuite", "robomimic", "mujoco", "torch", "numpy")
# the packages whose arithmetic decides an episode's outcome: the simulation's, the policies' and the arrays'
OUTCOME_PACKAGES = ("mujoco", "torch", "numpy")


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo), else what the platform module knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def host() -> dict:
    """The CPU model, core count, OS and Python of this machine."""
    return dict(cpu=cpu_model(), cores=os.cpu_count(), os=platform.platform(), python=platform.python_version())


def versions(packages: tuple[str, ...] = RECORDED_PACKAGES) -> dict[str, str]:
    """The installed version of each package ("not installed" for one that is not)."""
    out = {}
    for package in packages:
        try:
            out[package] = version(package)
        except PackageNotFoundError:
            out[package] = "not installed"
    return out


def outcome_platform() -> dict:
    """What besides the episode itself decides how it ends: the CPU, Python and the numerical packages. The same
    policy on the same seeded episodes ended differently in 13 of 83 episodes on a GPU machine (torch 2.11, NumPy 2.5,
    Python 3.12) and on this project's CPU host (results/grid_calibrated_diffusion_seeds/cross_platform.txt)."""
    return dict(cpu=cpu_model(), python=platform.python_version(), **versions(OUTCOME_PACKAGES))
