"""
Compatibility layer that lets robomimic 0.3.0 (the PyPI release) train, roll out and process datasets against
robosuite 1.5 and the CPU torch wheels, without editing site-packages.

robomimic 0.3.0 was written for robosuite 1.2-1.4 on mujoco-py. Each gap below was measured here; ``install()``
bridges all of them and is idempotent. Call it before importing robomimic's training or model modules (it imports
torchvision itself); the console entry points (veragmil_suite.scripts.robomimic_entry) do.

Imports:
    - ``envs/env_robosuite.py`` imports ``mujoco_py``: a stand-in module is installed when no mujoco_py exists;
      its ``builder.MujocoException`` (robomimic's rollout exception) is ``mujoco.FatalError``.
    - torchvision from PyPI fails to import beside the CPU torch wheel ("operator torchvision::nms does not
      exist": its compiled ops do not load, yet it registers fake kernels for them). The missing op schemas are
      defined only when that import fails, then the import is retried; otherwise nothing is defined.

robosuite 1.5 environments (EnvRobosuite's methods are replaced, so every robomimic path uses them; observations
and model XML come from veragmil_suite.learning.robomimic_obs, the conversion the dataset recorder uses too). Not a
subclass of our own: robomimic 0.3.0 picks the class from a fixed switch on the env type (env_utils.get_env_class,
no registry), and its users and scripts build ``EnvRobosuite(...)`` by name, which a subclass would leave broken:
    - ``env_name`` stored inside env_kwargs (robosuite 1.5's own collection scripts do) made environment creation
      from a dataset or checkpoint fail with a duplicate argument: it is dropped.
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
      last in the process (mj_saveLastXML), not this simulation's: each sim now remembers its source XML.
    - (not a gap of robomimic's, noted here because rollouts rely on it) robosuite's step() observation lags the
      state reached under lite physics and 1/240 s substeps; ScoopGranular observes at the end of each control
      step instead, so rollouts see what our datasets record and dataset_states_to_obs extracts.
    - ``step`` always reported done=False: an environment's own termination (a physics blow-up in ScoopGranular)
      now ends the rollout instead of stepping a broken simulation to the horizon.
    - every offscreen renderer probed for EGL GPUs (egl_probe), even with MUJOCO_GL=osmesa: only EGL probes.

Datasets of several foods (a merged file, or demos of another food or grain count appended; each demo keeps its own
env_args, and veragmil_suite.data.recording lists what differs in the file's as ``env_kwargs_variants``):
    - robomimic builds one environment from the file's env_args, the first food's. A demo's model XML is loaded
      into it as it is (ScoopGranular adopts the food and grain count of a model it loads), so playback,
      dataset_states_to_obs and reset_to work on every demo.
    - rollouts (training's and run_trained_agent's) only ever saw that first food. The env metadata read from a
      dataset carries its env_kwargs variants (from the demos' own env_args; robomimic saves it in checkpoints),
      and an environment made from it goes to the next variant at every reset: successive episodes go through the
      dataset's foods in turn. serialize() keeps the variants.
    - dataset_states_to_obs wrote its output in place, leaving a partial file when it failed, and dropped every
      demo's attributes but model_file and num_samples: it writes a temporary file, renamed over the output only
      once complete, and each demo keeps its attributes (its env_args with the processing's camera settings).

robomimic's train.py:
    - a relative ``train.output_dir`` resolved against robomimic's package folder (site-packages): it resolves
      against the working directory.
    - an existing experiment folder made it wait on ``input()``: runs never prompt, never delete, and two runs
      started in the same second no longer collide.
    - the validation loader dropped its last batch, so a validation split smaller than a batch gave no batch at
      all and the run failed: validation keeps every sample. A training split smaller than one batch fails with
      a clear message instead of a bare StopIteration.
    - the torch thread count is fixed at 2: with 2 cores and any other process running, OpenMP threads stall (1
      thread trained BC 5-10x faster here under load). $VERAGMIL_TORCH_THREADS sets it (unset: robomimic's 2).
    - observation normalization (``train.hdf5_normalize_obs``) failed on the first batch: the dataset normalizes
      each sample, run_epoch normalizes the batch a second time, and ``normalize_obs`` rejects any leading
      dimension but one of size 1 (a batch, BC-RNN's time axis). Fixed upstream after 0.3.0 (robomimic pull
      requests 81 and 82); here too: observations are normalized over any leading dimensions, once, by the
      dataset in training and by RolloutPolicy in rollouts.
    - every training error was caught and the process still exited 0: ``prepare_train_script`` records it so the
      entry point exits non-zero.
    - robomimic's scripts cannot see a plugin environment (no import hook): importing this module imports the
      veragmil_suite package first, which registers ScoopGranular, and the entry points run the scripts here.

robomimic's run_trained_agent.py:
    - its rollout asserted an EnvBase, while env_from_checkpoint wraps the env of a frame-stacking policy
      (train.frame_stack > 1, e.g. Diffusion Policy) in a FrameStackWrapper, which is none (robomimic's train loop
      accepts either): robomimic's EnvWrapper is registered as a virtual subclass of EnvBase.
"""

from __future__ import annotations

import copy
import functools
import importlib.machinery
import importlib.util
import os
import re
import sys
import types

import h5py
import mujoco
import numpy as np
import robosuite
from robosuite.controllers.composite.composite_controller_factory import refactor_composite_controller_config

from veragmil_suite.data.schema import VARIANTS_KEY, demo_names, env_kwargs_variants
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.learning.robomimic_scripts import experiment_dirs, normalize_obs, postprocess_without_normalizing
from veragmil_suite.models.foods import with_recorded_physics
from veragmil_suite.utils.canonical import canonical

# Schemas of the torchvision ops whose fake kernels torchvision registers even when its compiled library did not
# load (the same signatures as torchvision's C++ registrations).
_TORCHVISION_OP_SCHEMAS = {
    "nms": "nms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor",
    "qnms": "qnms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor",
}
_MISSING_OP = re.compile(r"operator torchvision::(\w+) does not exist")

# torchvision ops this process had to define (empty when torchvision imported by itself)
DEFINED_TORCHVISION_OPS: list[str] = []
_torchvision_library = None  # the torch.library fragment must stay alive for its definitions to stay registered
_installed = False


def install() -> None:
    """Bridges every gap listed in the module docstring (idempotent)."""
    global _installed
    if _installed:
        return
    _install_mujoco_py_stand_in()
    _import_torchvision()
    robomimic_obs.remember_sim_xml()

    from robomimic.algo.algo import Algo  # heavy: robomimic, imports torch
    from robomimic.envs.env_base import EnvBase  # heavy: robomimic, imports torch
    from robomimic.envs.env_robosuite import EnvRobosuite  # heavy: robomimic, imports torch
    from robomimic.envs.wrappers import EnvWrapper  # heavy: robomimic, imports torch
    from robomimic.utils import env_utils, file_utils, obs_utils, train_utils  # heavy: robomimic, imports torch

    env_utils.create_env_from_metadata = _create_env_from_metadata(env_utils.create_env_from_metadata)
    env_utils.create_env_for_data_processing = _with_variants(env_utils.create_env_for_data_processing, in_turn=False)
    file_utils.get_env_metadata_from_dataset = _with_dataset_variants(file_utils.get_env_metadata_from_dataset)
    EnvRobosuite.__init__ = _env_init
    EnvRobosuite.reset = _next_variant_at_reset(EnvRobosuite.reset)
    EnvRobosuite.reset_to = _same_variant_in_reset_to(EnvRobosuite.reset_to)
    EnvRobosuite.serialize = _serialize_with_variants(EnvRobosuite.serialize)
    EnvRobosuite.step = _env_step
    EnvRobosuite.get_observation = _env_get_observation
    EnvRobosuite.get_state = _env_get_state
    train_utils.get_exp_dir = experiment_dirs
    obs_utils.normalize_obs = normalize_obs
    Algo.postprocess_batch_for_training = postprocess_without_normalizing(Algo.postprocess_batch_for_training)
    EnvBase.register(EnvWrapper)
    _installed = True


def _install_mujoco_py_stand_in() -> None:
    """robomimic imports mujoco_py only to name the exception a broken simulation raised under mujoco-py."""
    if "mujoco_py" in sys.modules or importlib.util.find_spec("mujoco_py") is not None:
        return
    stand_in = types.ModuleType(
        "mujoco_py", "Stand-in from veragmil_suite.learning.robomimic_compat (robosuite 1.5 uses mujoco)"
    )
    builder = types.ModuleType("mujoco_py.builder")
    # specs, so importlib.util.find_spec("mujoco_py") answers instead of raising
    stand_in.__spec__ = importlib.machinery.ModuleSpec("mujoco_py", None, is_package=True)
    builder.__spec__ = importlib.machinery.ModuleSpec("mujoco_py.builder", None)
    builder.MujocoException = mujoco.FatalError
    stand_in.builder = builder
    sys.modules["mujoco_py"] = stand_in
    sys.modules["mujoco_py.builder"] = builder


def _import_torchvision() -> None:
    """Imports torchvision; defines the op schemas it expects only if the import fails for their absence."""
    global _torchvision_library
    for _ in range(len(_TORCHVISION_OP_SCHEMAS) + 1):
        try:
            import torchvision  # noqa: F401

            return
        except RuntimeError as err:
            match = _MISSING_OP.search(str(err))
            name = match.group(1) if match else None
            if name not in _TORCHVISION_OP_SCHEMAS or name in DEFINED_TORCHVISION_OPS:
                raise
            # the failed import left half-initialised torchvision modules behind
            for module_name in [m for m in sys.modules if m == "torchvision" or m.startswith("torchvision.")]:
                del sys.modules[module_name]
            import torch  # heavy: torch, only when used

            if _torchvision_library is None:
                _torchvision_library = torch.library.Library("torchvision", "FRAGMENT")
            _torchvision_library.define(_TORCHVISION_OP_SCHEMAS[name])
            DEFINED_TORCHVISION_OPS.append(name)


def _registered_keys(modality: str) -> list[str]:
    from robomimic.utils import obs_utils  # heavy: robomimic, imports torch

    return list((obs_utils.OBS_MODALITIES_TO_KEYS or {}).get(modality, []))


def _create_env_from_metadata(create):
    """robomimic's create_env_from_metadata, dropping an env_name stored inside env_kwargs, with env_meta's
    env_kwargs variants (see _with_variants)."""
    if getattr(create, "_drops_env_name", False):
        return create

    @functools.wraps(create)
    def create_env_from_metadata(env_meta, *args, **kwargs):
        env_kwargs = {k: v for k, v in env_meta.get("env_kwargs", {}).items() if k != "env_name"}
        from veragmil_suite.data.schema import ENV_NAME  # schema imports robosuite, which this module patches first

        if env_meta.get("env_name") == ENV_NAME:
            env_kwargs = with_recorded_physics(env_kwargs)
        return create(dict(env_meta, env_kwargs=env_kwargs), *args, **kwargs)

    create_env_from_metadata._drops_env_name = True
    return _with_variants(create_env_from_metadata)


def _env_init(
    self,
    env_name,
    render=False,
    render_offscreen=False,
    use_image_obs=False,
    postprocess_visual_obs=True,
    **kwargs,
):
    """
    EnvRobosuite.__init__ for robosuite 1.5 (same arguments as robomimic's).

    Args:
        env_name (str): robosuite environment name
        render (bool): on-screen rendering
        render_offscreen (bool): off-screen rendering (videos)
        use_image_obs (bool): render camera observations on every step
        postprocess_visual_obs (bool): prepare images for the networks (False when writing datasets)
        kwargs: the environment's keyword arguments (env_kwargs of a dataset's env_args)
    """
    if int(robosuite.__version__.split(".")[0]) != 1 or int(robosuite.__version__.split(".")[1]) < 5:
        raise RuntimeError(f"veragmil_suite's robomimic layer targets robosuite 1.5, found {robosuite.__version__}")
    kwargs = copy.deepcopy(kwargs)
    depth_keys = _registered_keys("depth")
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
    self.env = _make_robosuite_env(env_name, kwargs)
    self.env_kwargs_variants = []


def _make_robosuite_env(env_name: str, kwargs: dict):
    env = robosuite.make(env_name, **kwargs)
    # robomimic's datasets use joint positions, which robosuite may leave inactive
    for name in env.observation_names:
        if "joint_pos" in name:
            env.modify_observable(observable_name=name, attribute="active", modifier=True)
    return env


def _with_dataset_variants(get_env_metadata):
    """robomimic's get_env_metadata_from_dataset, plus the dataset's env_kwargs variants as its demos' own env_args
    give them (veragmil_suite.data.schema.env_kwargs_variants), or as the file lists them when no demo has its
    own."""
    if getattr(get_env_metadata, "_adds_variants", False):
        return get_env_metadata

    @functools.wraps(get_env_metadata)
    def get_env_metadata_from_dataset(dataset_path, *args, **kwargs):
        env_meta = get_env_metadata(dataset_path, *args, **kwargs)
        with h5py.File(os.path.expanduser(dataset_path), "r") as f:
            if any("env_args" in f["data"][name].attrs for name in demo_names(f)):
                env_meta.pop(VARIANTS_KEY, None)
                variants = env_kwargs_variants(f)
                if variants:
                    env_meta[VARIANTS_KEY] = variants
        return env_meta

    get_env_metadata_from_dataset._adds_variants = True
    return get_env_metadata_from_dataset


def _with_variants(create, in_turn: bool = True):
    """
    A robomimic env factory (create_env_from_metadata, create_env_for_data_processing) whose envs keep env_meta's
    env_kwargs variants (serialize), and with ``in_turn`` take them in turn at every reset (_next_variant_at_reset).
    Data processing loads each demo's own model (reset_to): it stays with one environment.
    """
    if getattr(create, "_attaches_variants", False):
        return create

    @functools.wraps(create)
    def create_with_variants(env_meta, *args, **kwargs):
        from robomimic.envs.env_robosuite import EnvRobosuite  # heavy: robomimic, imports torch

        env = create(env_meta, *args, **kwargs)
        if isinstance(env, EnvRobosuite):
            env.env_kwargs_variants = copy.deepcopy(env_meta.get(VARIANTS_KEY) or [])
            env._variants_in_turn = in_turn
            env._variant_index = -1
            env._variant_envs = {canonical(env._init_kwargs): env.env}
        return env

    create_with_variants._attaches_variants = True
    return create_with_variants


def _next_variant_at_reset(reset):
    """EnvRobosuite.reset, first moving an env with env_kwargs variants to the next one (made when first needed):
    rollouts go through a multi-food dataset's foods in turn, starting with its first demo's."""

    @functools.wraps(reset)
    def reset_next_variant(self):
        variants = getattr(self, "env_kwargs_variants", None)
        if variants and getattr(self, "_variants_in_turn", False) and not getattr(self, "_holding_variant", False):
            self._variant_index = (self._variant_index + 1) % len(variants)
            kwargs = copy.deepcopy(self._init_kwargs)
            for key, value in variants[self._variant_index]["env_kwargs"].items():
                if value is None:
                    kwargs.pop(key, None)  # not given in that demo's env_kwargs: the environment's default
                else:
                    kwargs[key] = value
            key = canonical(kwargs)
            if key not in self._variant_envs:
                self._variant_envs[key] = _make_robosuite_env(self._env_name, kwargs)
            self.env = self._variant_envs[key]
        return reset(self)

    return reset_next_variant


def _same_variant_in_reset_to(reset_to):
    """EnvRobosuite.reset_to, whose own reset stays with the current variant (the state loaded is its episode's)."""

    @functools.wraps(reset_to)
    def reset_to_same_variant(self, state):
        holding = getattr(self, "_holding_variant", False)
        self._holding_variant = True
        try:
            return reset_to(self, state)
        finally:
            self._holding_variant = holding

    return reset_to_same_variant


def _serialize_with_variants(serialize):
    """EnvRobosuite.serialize, keeping the env_kwargs variants (robomimic writes it into the files it makes)."""

    @functools.wraps(serialize)
    def serialize_with_variants(self):
        meta = serialize(self)
        if getattr(self, "env_kwargs_variants", None):
            meta[VARIANTS_KEY] = copy.deepcopy(self.env_kwargs_variants)
        return meta

    return serialize_with_variants


def _env_step(self, action):
    """Steps the environment; done is the environment's own termination (the horizon is the caller's)."""
    raw, reward, done, info = self.env.step(action)
    return self.get_observation(raw), reward, bool(done) or self.is_done(), info


def _env_get_observation(self, di=None):
    """Observation dictionary (see veragmil_suite.learning.robomimic_obs.observation)."""
    return robomimic_obs.observation(self.env, di, postprocess=self.postprocess_visual_obs)


def _env_get_state(self):
    """The simulation's own XML and flattened state, as reset_to expects them."""
    return dict(model=robomimic_obs.model_xml(self.env), states=np.array(self.env.sim.get_state().flatten()))
