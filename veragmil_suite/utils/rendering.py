"""Headless rendering: MuJoCo and PyOpenGL on OSMesa (software rendering), chosen before MuJoCo is imported.

MuJoCo's EGL contexts crashed at random in rollouts here, while OSMesa was reliable. MuJoCo and robosuite read
``MUJOCO_GL`` when they are first imported (PyOpenGL reads ``PYOPENGL_PLATFORM`` likewise), so the choice has to
be made before that; this module imports only the standard library.

Importing it as ``veragmil_suite.utils.rendering`` first runs the package's ``__init__``, which calls
``use_headless_rendering()`` when there is no display and then imports robosuite. A program that wants headless
rendering whatever the display sets ``MUJOCO_GL`` and ``PYOPENGL_PLATFORM`` to ``osmesa`` before it imports the
package (as the benchmarks in benchmarks/ do); ``vr_stream`` sets them in the environment of its renderer process, which
imports MuJoCo without this package.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping


def has_display() -> bool:
    """Whether a window can open: an X or Wayland display is set."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def use_headless_rendering(force: bool = False, environ: MutableMapping[str, str] | None = None) -> None:
    """
    Sets MuJoCo's and PyOpenGL's OpenGL platform to OSMesa.

    Args:
        force (bool): replace values already set (worker processes whose rendering must not be EGL); otherwise
            only defaults are set: MUJOCO_GL osmesa, and PYOPENGL_PLATFORM the same as MUJOCO_GL
        environ (mapping or None): the environment to change, e.g. a child process's; None: ``os.environ``
    """
    environ = os.environ if environ is None else environ
    if force:
        environ["MUJOCO_GL"] = "osmesa"
        environ["PYOPENGL_PLATFORM"] = "osmesa"
    else:
        environ.setdefault("MUJOCO_GL", "osmesa")
        environ.setdefault("PYOPENGL_PLATFORM", environ["MUJOCO_GL"])
