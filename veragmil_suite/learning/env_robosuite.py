"""
robomimic's environment wrapper for robosuite 1.5: robomimic 0.3.0's EnvRobosuite, written for robosuite 1.2-1.4 on
mujoco-py, with each gap measured here bridged in a class of its own.

robomimic 0.3.0 has no registry of environment classes: ``env_utils.get_env_class`` imports ``EnvRobosuite`` from
``robomimic.envs.env_robosuite`` for every robosuite env, and scripts build ``EnvRobosuite(...)`` by that name.
``robomimic_compat.install()`` binds EnvRobosuite15 to that name, so every robomimic path builds this class.

The gaps (observations and model XML come from veragmil_suite.learning.robomimic_obs, the conversion the dataset
recorder uses too):
    - controller configs of robosuite <= 1.4 (one arm part, e.g. {"type": "OSC_POSE"}) are converted to 1.5's
      composite form with robosuite's own converter.
    - ``camera_depths`` was forced off, and cameras render only for rgb policies: depth observations are rendered
      when the policy uses a depth key or the dataset recorded depth.
    - observations kept only robot-prefixed keys and rgb images: task observables such as ``desired_pose`` were
      dropped (KeyError in rollouts). Every enabled observable is kept; ``object-state`` becomes ``object``.
    - empty observables (a gripper with no joints, like the spoon: robot0_gripper_qpos has shape (0,)) broke the
      recurrent and BCQ policies in rollouts (a reshape of 0 elements): they are left out.
    - images were flipped whatever robosuite's IMAGE_CONVENTION: they are flipped only for "opengl", so
      observations are upright under either convention.
    - ``get_state`` saved ``sim.model.get_xml()``, which in robosuite 1.5 returns the XML of the model compiled
      last in the process (mj_saveLastXML), not this simulation's: each sim remembers its source XML.
    - ``step`` always reported done=False: an environment's own termination (a physics blow-up in ScoopGranular)
      ends the rollout instead of stepping a broken simulation to the horizon.
    - every offscreen renderer probed for EGL GPUs (egl_probe), even with MUJOCO_GL=osmesa: only EGL probes.

Datasets of several foods (see veragmil_suite.data.schema.env_kwargs_variants): robomimic builds one environment
from a file's env_args, the first food's. An environment given the file's env_kwargs variants (``use_variants``)
goes to the next variant at every reset, so rollouts go through the dataset's foods in turn, and ``serialize``
keeps the variants, which robomimic writes into checkpoints and the files it makes.
"""

from __future__ import annotations

import copy
import os
from typing import TYPE_CHECKING

import numpy as np
import robosuite
from robosuite.controllers.composite.composite_controller_factory import refactor_composite_controller_config

from veragmil_suite.data.schema import VARIANTS_KEY
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.learning.mujoco_py_stand_in import install_mujoco_py_stand_in
from veragmil_suite.utils.canonical import canonical

install_mujoco_py_stand_in()  # robomimic's env_robosuite imports mujoco_py

import robomimic.utils.obs_utils as ObsUtils  # noqa: E402
from robomimic.envs.env_robosuite import EnvRobosuite  # noqa: E402

if TYPE_CHECKING:
    from robosuite.environments.base import MujocoEnv


def make_robosuite_env(env_name: str, kwargs: dict) -> MujocoEnv:
    """robosuite.make, with every joint-position observable active (robomimic's datasets use them)."""
    env = robosuite.make(env_name, **kwargs)
    for name in env.observation_names:
        if "joint_pos" in name:
            env.modify_observable(observable_name=name, attribute="active", modifier=True)
    return env


class EnvRobosuite15(EnvRobosuite):
    """Wrapper class for robosuite 1.5 environments, with robomimic's EnvRobosuite API."""

    def __init__(
        self,
        env_name,
        render=False,
        render_offscreen=False,
        use_image_obs=False,
        postprocess_visual_obs=True,
        **kwargs,
    ):
        """
        Args:
            env_name (str): robosuite environment name
            render (bool): on-screen rendering
            render_offscreen (bool): off-screen rendering (videos)
            use_image_obs (bool): render camera observations on every step
            postprocess_visual_obs (bool): prepare images for the networks (False when writing datasets)
            kwargs: the environment's keyword arguments (env_kwargs of a dataset's env_args)
        """
        major, minor = (int(part) for part in robosuite.__version__.split(".")[:2])
        if major != 1 or minor < 5:
            raise RuntimeError(f"veragmil_suite's robomimic layer targets robosuite 1.5, found {robosuite.__version__}")
        kwargs = copy.deepcopy(kwargs)
        depth_keys = list((ObsUtils.OBS_MODALITIES_TO_KEYS or {}).get("depth", []))
        use_cameras = bool(use_image_obs or depth_keys)
        kwargs.update(
            has_renderer=render,
            has_offscreen_renderer=bool(render_offscreen or use_cameras),
            ignore_done=True,
            use_object_obs=True,
            use_camera_obs=use_cameras,
            camera_depths=bool(use_cameras and (depth_keys or kwargs.get("camera_depths", False))),
        )
        controller = kwargs.get("controller_configs")
        if isinstance(controller, dict) and "robots" in kwargs:
            robots = kwargs["robots"]
            robot = robots if isinstance(robots, str) else robots[0]
            kwargs["controller_configs"] = refactor_composite_controller_config(controller, robot, ["right"])
        if kwargs["has_offscreen_renderer"] and os.environ.get("MUJOCO_GL", "").lower() == "egl":
            import egl_probe  # only with MUJOCO_GL=egl (robomimic's dependency)

            devices = egl_probe.get_available_devices()
            if devices:
                kwargs["render_gpu_device_id"] = devices[0]

        self.postprocess_visual_obs = postprocess_visual_obs
        self._is_v1 = True
        self._env_name = env_name
        self._init_kwargs = copy.deepcopy(kwargs)
        self.env = make_robosuite_env(env_name, kwargs)
        self.use_variants([], in_turn=False)

    def use_variants(self, variants: list[dict], in_turn: bool) -> None:
        """Keeps a dataset's env_kwargs variants (serialize); with ``in_turn``, every reset moves to the next one (made
        when first needed), starting with the first demo's. Data processing loads each demo's own model (reset_to),
        so it stays with one environment."""
        self.env_kwargs_variants = copy.deepcopy(list(variants or []))
        self._variants_in_turn = in_turn
        self._variant_index = -1
        self._variant_envs = {canonical(self._init_kwargs): self.env}
        self._holding_variant = False

    def reset(self) -> dict:
        """Resets the environment, first moving to the next env_kwargs variant when taking them in turn."""
        if self.env_kwargs_variants and self._variants_in_turn and not self._holding_variant:
            self._variant_index = (self._variant_index + 1) % len(self.env_kwargs_variants)
            kwargs = copy.deepcopy(self._init_kwargs)
            for key, value in self.env_kwargs_variants[self._variant_index]["env_kwargs"].items():
                if value is None:
                    kwargs.pop(key, None)  # not given in that demo's env_kwargs: the environment's default
                else:
                    kwargs[key] = value
            key = canonical(kwargs)
            if key not in self._variant_envs:
                self._variant_envs[key] = make_robosuite_env(self._env_name, kwargs)
            self.env = self._variant_envs[key]
        return super().reset()

    def reset_to(self, state: dict) -> dict | None:
        """Resets to a saved state; its own reset stays with the current variant (the state is its episode's)."""
        holding = self._holding_variant
        self._holding_variant = True
        try:
            return super().reset_to(state)
        finally:
            self._holding_variant = holding

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, dict]:
        """Steps the environment; done is the environment's own termination (the horizon is the caller's)."""
        raw, reward, done, info = self.env.step(action)
        return self.get_observation(raw), reward, bool(done) or self.is_done(), info

    def get_observation(self, di: dict | None = None) -> dict[str, np.ndarray]:
        """Observation dictionary (see veragmil_suite.learning.robomimic_obs.observation)."""
        return robomimic_obs.observation(self.env, di, postprocess=self.postprocess_visual_obs)

    def get_state(self) -> dict:
        """The simulation's own XML and flattened state, as reset_to expects them."""
        return dict(model=robomimic_obs.model_xml(self.env), states=np.array(self.env.sim.get_state().flatten()))

    def serialize(self) -> dict:
        """robomimic's env metadata, with the env_kwargs variants."""
        meta = super().serialize()
        if self.env_kwargs_variants:
            meta[VARIANTS_KEY] = copy.deepcopy(self.env_kwargs_variants)
        return meta
