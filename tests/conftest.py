"""Shared test setup: headless rendering and quiet device drivers, set before robosuite is imported."""

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")  # EGL crashed at random in rollouts here; osmesa is reliable
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
os.environ.setdefault("PYNPUT_BACKEND", "dummy")  # robosuite.devices imports pynput, which needs X otherwise


def pytest_configure(config):
    # make test runs the rest in two xdist workers, then these in one process with the machine to themselves: their
    # deadlines (staleness, heartbeats, a browser's pace) measure real time, which a neighbouring test would steal
    config.addinivalue_line("markers", "realtime: measures real time; run without other tests beside it")
