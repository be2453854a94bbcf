"""Shared test setup: headless rendering and quiet device drivers, set before robosuite is imported."""

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")  # EGL crashed at random in rollouts here; osmesa is reliable
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
os.environ.setdefault("PYNPUT_BACKEND", "dummy")  # robosuite.devices imports pynput, which needs X otherwise
