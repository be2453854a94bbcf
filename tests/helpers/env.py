"""Small helpers shared by the environment tests."""

import re
from pathlib import Path

import numpy as np
import robosuite

import veragmil_suite  # noqa: F401


def pinned_mujoco_version() -> str:
    """The MuJoCo setup.py pins (the one demos are recorded and replayed with)."""
    setup = (Path(__file__).resolve().parents[2] / "setup.py").read_text()
    return re.search(r'^MUJOCO_VERSION = "([^"]+)"', setup, re.M).group(1)


def make_env(food="rice", robot="XArm7", seed=0, **kwargs):
    kwargs.setdefault("pile_variants", 1)
    return robosuite.make(
        "ScoopGranular",
        robots=robot,
        food=food,
        has_renderer=False,
        has_offscreen_renderer=kwargs.pop("has_offscreen_renderer", False),
        use_camera_obs=kwargs.pop("use_camera_obs", False),
        seed=seed,
        **kwargs,
    )


def grain_positions(env) -> np.ndarray:
    return env.sim.data.body_xpos[env.grain_body_ids].copy()
