"""
Compatibility layer that lets robomimic 0.3.0 (the PyPI release) train, roll out and process datasets against
robosuite 1.5 and the CPU torch wheels, without editing site-packages.

robomimic 0.3.0 was written for robosuite 1.2-1.4 on mujoco-py. Each gap below was measured here; ``install()``
bridges all of them and is idempotent. Call it before importing robomimic's training or model modules (it imports
torchvision itself); the console entry points (veragmil_suite.scripts.robomimic_entry) do.

Imports:
    - ``envs/env_robosuite.py`` imports ``mujoco_py``: a stand-in module is installed when no mujoco_py exists
      (veragmil_suite.learning.mujoco_py_stand_in); its ``builder.MujocoException`` (robomimic's rollout
      exception) is ``mujoco.FatalError``.
    - torchvision from PyPI fails to import beside the CPU torch wheel ("operator torchvision::nms does not
      exist": its compiled ops do not load, yet it registers fake kernels for them). The missing op schemas are
      defined only when that import fails, then the import is retried; otherwise nothing is defined.

robosuite 1.5 environments: robomimic's EnvRobosuite is bound to veragmil_suite.learning.env_robosuite.EnvRobosuite15,
whose docstring lists the gaps it bridges, so every robomimic path (and code that builds ``EnvRobosuite(...)`` by
name) builds it. Around it:
    - ``env_name`` stored inside env_kwargs (robosuite 1.5's own collection scripts do) made environment creation
      from a dataset or checkpoint fail with a duplicate argument: it is dropped.
    - (not a gap of robomimic's, noted here because rollouts rely on it) robosuite's step() observation lags the
      state reached under lite physics and 1/240 s substeps; ScoopGranular observes at the end of each control
      step instead, so rollouts see what our datasets record and dataset_states_to_obs extracts.

Datasets of several foods (a merged file, or demos of another food or grain count appended; each demo keeps its own
env_args, and veragmil_suite.data.recording lists what differs in the file's as ``env_kwargs_variants``):
    - robomimic builds one environment from the file's env_args, the first food's. A demo's model XML is loaded
      into it as it is (ScoopGranular adopts the food and grain count of a model it loads), so playback,
      dataset_states_to_obs and reset_to work on every demo.
    - rollouts (training's and run_trained_agent's) only ever saw that first food. The env metadata read from a
      dataset carries its env_kwargs variants (from the demos' own env_args; robomimic saves it in checkpoints),
      and an environment made from it takes them in turn at every reset (EnvRobosuite15.use_variants).
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

import functools
import os
import re
import sys
from typing import TYPE_CHECKING, Any

import h5py

from veragmil_suite.data.schema import VARIANTS_KEY, demo_names, env_kwargs_variants
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.learning.mujoco_py_stand_in import install_mujoco_py_stand_in
from veragmil_suite.learning.robomimic_scripts import experiment_dirs, normalize_obs, postprocess_without_normalizing
from veragmil_suite.models.foods import with_recorded_physics

if TYPE_CHECKING:
    from robomimic.envs.env_base import EnvBase

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
    install_mujoco_py_stand_in()
    _import_torchvision()
    robomimic_obs.remember_sim_xml()

    from robomimic.algo.algo import Algo  # heavy: robomimic, imports torch
    from robomimic.envs import env_robosuite as robomimic_env_robosuite  # heavy: robomimic, imports torch
    from robomimic.envs.env_base import EnvBase  # heavy: robomimic, imports torch
    from robomimic.envs.wrappers import EnvWrapper  # heavy: robomimic, imports torch
    from robomimic.utils import env_utils, file_utils, obs_utils, train_utils  # heavy: robomimic, imports torch

    from veragmil_suite.learning.env_robosuite import EnvRobosuite15  # imports robomimic (torch)

    env_utils.create_env_from_metadata = _create_env_from_metadata(env_utils.create_env_from_metadata)
    env_utils.create_env_for_data_processing = _with_variants(env_utils.create_env_for_data_processing, in_turn=False)
    file_utils.get_env_metadata_from_dataset = _with_dataset_variants(file_utils.get_env_metadata_from_dataset)
    robomimic_env_robosuite.EnvRobosuite = EnvRobosuite15  # where get_env_class and scripts look it up
    train_utils.get_exp_dir = experiment_dirs
    obs_utils.normalize_obs = normalize_obs
    Algo.postprocess_batch_for_training = postprocess_without_normalizing(Algo.postprocess_batch_for_training)
    EnvBase.register(EnvWrapper)
    _installed = True


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


def _create_env_from_metadata(create):
    """robomimic's create_env_from_metadata, dropping an env_name stored inside env_kwargs, with env_meta's
    env_kwargs variants (see _with_variants)."""
    if getattr(create, "_drops_env_name", False):
        return create

    @functools.wraps(create)
    def create_env_from_metadata(env_meta: dict, *args: Any, **kwargs: Any) -> EnvBase:
        env_kwargs = {k: v for k, v in env_meta.get("env_kwargs", {}).items() if k != "env_name"}
        from veragmil_suite.data.schema import ENV_NAME  # schema imports robosuite, which this module patches first

        if env_meta.get("env_name") == ENV_NAME:
            env_kwargs = with_recorded_physics(env_kwargs)
        return create(dict(env_meta, env_kwargs=env_kwargs), *args, **kwargs)

    create_env_from_metadata._drops_env_name = True
    return _with_variants(create_env_from_metadata)


def _with_dataset_variants(get_env_metadata):
    """robomimic's get_env_metadata_from_dataset, plus the dataset's env_kwargs variants as its demos' own env_args
    give them (veragmil_suite.data.schema.env_kwargs_variants), or as the file lists them when no demo has its
    own."""
    if getattr(get_env_metadata, "_adds_variants", False):
        return get_env_metadata

    @functools.wraps(get_env_metadata)
    def get_env_metadata_from_dataset(dataset_path: str, *args: Any, **kwargs: Any) -> dict:
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
    env_kwargs variants, taken in turn at every reset with ``in_turn`` (EnvRobosuite15.use_variants).
    """
    if getattr(create, "_attaches_variants", False):
        return create

    @functools.wraps(create)
    def create_with_variants(env_meta: dict, *args: Any, **kwargs: Any) -> EnvBase:
        from veragmil_suite.learning.env_robosuite import EnvRobosuite15  # imports robomimic (torch)

        env = create(env_meta, *args, **kwargs)
        if isinstance(env, EnvRobosuite15):
            env.use_variants(env_meta.get(VARIANTS_KEY) or [], in_turn=in_turn)
        return env

    create_with_variants._attaches_variants = True
    return create_with_variants
