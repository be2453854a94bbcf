"""A stand-in ``mujoco_py`` module: robomimic 0.3.0 imports mujoco_py only to name the exception a broken simulation
raised under mujoco-py, and robosuite 1.5 runs on mujoco, where that exception is ``mujoco.FatalError``."""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
import types

import mujoco


def install_mujoco_py_stand_in() -> None:
    """Installs the stand-in when no mujoco_py exists (idempotent)."""
    if "mujoco_py" in sys.modules or importlib.util.find_spec("mujoco_py") is not None:
        return
    stand_in = types.ModuleType(
        "mujoco_py", "Stand-in from veragmil_suite.learning.mujoco_py_stand_in (robosuite 1.5 uses mujoco)"
    )
    builder = types.ModuleType("mujoco_py.builder")
    # specs, so importlib.util.find_spec("mujoco_py") answers instead of raising
    stand_in.__spec__ = importlib.machinery.ModuleSpec("mujoco_py", None, is_package=True)
    builder.__spec__ = importlib.machinery.ModuleSpec("mujoco_py.builder", None)
    builder.MujocoException = mujoco.FatalError
    stand_in.builder = builder
    sys.modules["mujoco_py"] = stand_in
    sys.modules["mujoco_py.builder"] = builder
