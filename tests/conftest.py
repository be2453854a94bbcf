"""Shared test setup: headless rendering and quiet device drivers, set before robosuite is imported."""

import os

os.environ.setdefault("MUJOCO_GL", "osmesa")  # EGL crashed at random in rollouts here; osmesa is reliable
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
os.environ.setdefault("PYNPUT_BACKEND", "dummy")  # robosuite.devices imports pynput, which needs X otherwise
if os.environ.get("PYTEST_XDIST_WORKER"):
    # two workers share two cores: a training run a test starts takes one torch thread (robomimic asks for two, and
    # two trainings of two threads each on two cores ran 9x slower than one alone)
    os.environ.setdefault("VERAGMIL_TORCH_THREADS", "1")


def pytest_configure(config):
    # make test runs these in one process at normal priority and the rest beside them under SCHED_IDLE: their
    # deadlines (staleness, heartbeats, a browser's pace) measure real time, which a neighbouring test would steal
    config.addinivalue_line("markers", "realtime: measures real time; run with no other test competing for the CPU")


def pytest_ignore_collect(collection_path, config):
    """``-m realtime`` (make test's real-time run) imports only the test files that name the marker: importing the
    others (torch, robomimic, robosuite) cost 8 of the run's 10 seconds of collection, for tests it then deselects."""
    if config.getoption("markexpr") != "realtime" or not collection_path.name.startswith("test_"):
        return None
    if collection_path.suffix == ".py" and "realtime" not in collection_path.read_text():
        return True
    return None
