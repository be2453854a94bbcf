"""robomimic 0.3.0's own scripts run by our entry points (veragmil_suite.scripts.robomimic_entry), with the gaps
of robomimic_compat's list that live in the scripts bridged: train.py's experiment folders and exit status, its
prompts, dataset_states_to_obs.py's dataset attributes and the observations it cannot extract, and the scripts'
output files written whole (a killed or failed run leaves the file that was there).
"""

from __future__ import annotations

import builtins
import contextlib
import functools
import json
import os
import time
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NoReturn

import h5py
import numpy as np

from veragmil_suite.data import safe_hdf5
from veragmil_suite.data.schema import VARIANTS_KEY
from veragmil_suite.data.writer import write_lock
from veragmil_suite.learning import training_resume
from veragmil_suite.learning.robomimic_obs import TORQUE_DEPENDENT_OBSERVATIONS
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.whole_files import written_whole

if TYPE_CHECKING:
    import argparse

    import torch
    from robomimic.algo.algo import Algo
    from robomimic.config.config import Config
    from torch.utils.data import DataLoader, Dataset


def prepare_states_to_obs_script(module: types.ModuleType) -> None:
    """
    Patches the namespace of robomimic.scripts.dataset_states_to_obs (imported, not yet run) for one run: its
    output is written whole (dataset_written_whole), and each demo keeps the input's attributes (see
    _carry_attributes) and its recorded torque-dependent observations (see _carry_recorded_observations).
    """
    robomimic_states_to_obs = getattr(module.dataset_states_to_obs, "__wrapped__", module.dataset_states_to_obs)

    @functools.wraps(robomimic_states_to_obs)
    def dataset_states_to_obs(args: argparse.Namespace) -> None:
        folder = os.path.dirname(args.dataset)
        output = os.path.join(folder, args.output_name)
        with dataset_written_whole(output) as partial:
            args.output_name = os.path.relpath(partial, folder or ".")
            try:
                robomimic_states_to_obs(args)
            finally:
                args.output_name = os.path.relpath(output, folder or ".")
            _carry_attributes(args.dataset, partial)
            carried = _carry_recorded_observations(args.dataset, partial)
            if carried:
                print(f"kept the recorded {', '.join(carried)}: they read a step's torques, not its state")

    module.dataset_states_to_obs = dataset_states_to_obs


@contextlib.contextmanager
def dataset_written_whole(output: str) -> Iterator[str]:
    """
    Yields the path of a working copy of the dataset ``output`` for a robomimic script to write, renamed onto
    ``output`` when the block ends, under the file's write lock: a failed run leaves ``output`` as it was; a killed
    one's copy is reported by veragmil-dataset-info and removed by --clean or the next write.
    """
    with write_lock(output):
        safe_hdf5.remove_working_copies(output)  # what killed runs left
        partial = str(safe_hdf5.working_copy_path(output))
        try:
            yield partial
            if os.path.exists(partial):  # a run that wrote nothing leaves ``output`` as it was
                os.replace(partial, os.path.realpath(output))  # a link's file, as safe_hdf5 replaces
                print(f"renamed {os.path.basename(partial)} to {output} (written under that name until complete)")
        finally:
            if os.path.exists(partial):
                os.remove(partial)


def prepare_outputs_whole(module: types.ModuleType, function: str, datasets: tuple[str, ...] = ()) -> None:
    """
    Patches the script's ``function`` (run on its parsed arguments) so that the files its ``video_path`` and its
    ``datasets`` options name are written under temporary names beside them and renamed onto them when it returns:
    robomimic opens them in place, and a kill or an error part-way would leave half a file, or an emptied one where
    --force let it replace a file.
    """
    robomimic_function = getattr(getattr(module, function), "__wrapped__", getattr(module, function))

    @functools.wraps(robomimic_function)
    def written_whole_run(args: argparse.Namespace) -> Any:
        named = {dest: getattr(args, dest, None) for dest in ("video_path", *datasets)}
        with contextlib.ExitStack() as outputs:
            for dest, path in named.items():
                if path is not None:
                    partial = dataset_written_whole(path) if dest in datasets else written_whole(path, True)
                    setattr(args, dest, str(outputs.enter_context(partial)))
            try:
                return robomimic_function(args)
            finally:
                for dest, path in named.items():
                    setattr(args, dest, path)

    setattr(module, function, written_whole_run)


def _carry_attributes(source: str, output: str) -> None:
    """
    Gives ``output``'s data group and demos the attributes of ``source``'s that robomimic did not write (provenance,
    food, metrics, each demo's env_args); a demo's env_args take the env_kwargs robomimic's processing changed or
    dropped (cameras, reward shaping) from the output's own env_args.
    """
    with h5py.File(source, "r") as fin, h5py.File(output, "a") as fout:
        data_in, data_out = fin["data"], fout["data"]
        before = json.loads(data_in.attrs["env_args"])["env_kwargs"]
        after = json.loads(data_out.attrs["env_args"])["env_kwargs"]
        processing = {k: v for k, v in after.items() if canonical(v) != canonical(before.get(k))}
        dropped = before.keys() - after.keys()  # robomimic drops the camera settings when it renders no camera
        for key, value in data_in.attrs.items():
            if key not in data_out.attrs:
                data_out.attrs[key] = value
        for name in data_out:
            if name not in data_in:
                continue
            attrs_in, attrs_out = data_in[name].attrs, data_out[name].attrs
            for key, value in attrs_in.items():
                if key not in attrs_out:
                    attrs_out[key] = value
            if "env_args" in attrs_in:
                meta = json.loads(attrs_in["env_args"])
                meta.pop(VARIANTS_KEY, None)
                meta["env_kwargs"].update(processing)
                for key in dropped:
                    meta["env_kwargs"].pop(key, None)
                attrs_out["env_args"] = json.dumps(meta)


def _carry_recorded_observations(source: str, output: str) -> list[str]:
    """
    Writes ``source``'s recorded values of the torque-dependent observations (robomimic_obs.
    TORQUE_DEPENDENT_OBSERVATIONS) over what robomimic read after setting each state, which is not what the robot
    measured; returns the keys carried. A demo's next_obs the source lacks, or holds in another shape, are its obs one
    step on; an obs of another shape is left as robomimic read it.
    """
    carried = set()
    with h5py.File(source, "r") as fin, h5py.File(output, "a") as fout:
        data_in, data_out = fin["data"], fout["data"]
        for name in data_out:
            if name not in data_in:
                continue
            demo_in, demo_out = data_in[name], data_out[name]
            for key in TORQUE_DEPENDENT_OBSERVATIONS:
                if f"obs/{key}" not in demo_in or f"obs/{key}" not in demo_out:
                    continue
                recorded = demo_in[f"obs/{key}"][()]
                if recorded.shape != demo_out[f"obs/{key}"].shape:
                    continue
                demo_out[f"obs/{key}"][...] = recorded
                if f"next_obs/{key}" in demo_out:
                    target = demo_out[f"next_obs/{key}"]
                    if f"next_obs/{key}" in demo_in and demo_in[f"next_obs/{key}"].shape == target.shape:
                        target[...] = demo_in[f"next_obs/{key}"][()]
                    else:
                        target[:-1] = recorded[1:]
                carried.add(key)
    return [key for key in TORQUE_DEPENDENT_OBSERVATIONS if key in carried]


def _new_run_folder(config) -> str:
    """Creates <output_dir>/<experiment name>/<timestamp>[_N], N numbering runs started in the same second."""
    base = os.path.join(os.path.abspath(os.path.expanduser(config.train.output_dir)), config.experiment.name)
    stamp = time.strftime("%Y%m%d%H%M%S")
    os.makedirs(base, exist_ok=True)
    run_dir, suffix = os.path.join(base, stamp), 0
    while True:
        try:
            os.makedirs(run_dir)
            return run_dir
        except FileExistsError:
            suffix += 1
            run_dir = os.path.join(base, f"{stamp}_{suffix}")


def experiment_dirs(
    config: Config, auto_remove_exp_dir: bool = False, run_dir: str | os.PathLike | None = None
) -> tuple[str, str | None, str]:
    """
    Replaces robomimic's get_exp_dir: <output_dir>/<experiment name>/<timestamp>/{logs, models, videos}.

    A relative output_dir is taken from the working directory (robomimic took it from its own package folder in
    site-packages). An existing experiment folder is kept and the run goes into a new timestamped folder beside
    the earlier ones: no prompt, no deletion (auto_remove_exp_dir is accepted and ignored). Runs started in the
    same second get a numbered suffix. ``run_dir``: an existing run folder to go on in (a resumed run), its
    folders kept.

    Returns:
        3-tuple: log folder, model folder (None when saving is disabled), video folder
    """
    if run_dir is None:
        run_dir = _new_run_folder(config)
    model_dir = os.path.join(run_dir, "models") if config.experiment.save.enabled else None
    log_dir = os.path.join(run_dir, "logs")
    video_dir = os.path.join(run_dir, "videos")
    for folder in (model_dir, log_dir, video_dir):
        if folder is not None:
            os.makedirs(folder, exist_ok=True)
    return log_dir, model_dir, video_dir


@dataclass
class TrainOutcome:
    """What robomimic's train() did: it swallows its errors, so the entry point reads them here."""

    config: object = None
    error: BaseException | None = None

    @property
    def failed(self) -> bool:
        return self.error is not None


def prepare_train_script(module: types.ModuleType, resume: bool = False) -> TrainOutcome:
    """
    Patches the namespace of robomimic.scripts.train (imported, not yet run) for one run.

    Its train() is wrapped to record any error (its main() prints the error and returns normally) and to run
    with $VERAGMIL_TORCH_THREADS torch threads when that is set; its DataLoader keeps the last validation batch
    and rejects a training split smaller than one batch; its train_utils save the run's resume state and write
    checkpoints whole (veragmil_suite.learning.training_resume). With ``resume`` the newest run of the experiment
    that holds a resume state goes on from it, when its config is this one (else ResumeRefused); a new run starts
    when there is none.
    """
    import torch  # heavy: torch, only when used

    outcome = TrainOutcome()
    robomimic_train = getattr(module.train, "__wrapped__", module.train)
    train_utils = getattr(module, "TrainUtils", None)
    train_utils = getattr(train_utils, "_train_utils", train_utils)  # robomimic's, under a wrapper of an earlier run
    threads = os.environ.get("VERAGMIL_TORCH_THREADS")

    @functools.wraps(robomimic_train)
    def train(config: Config, device: torch.device) -> None:
        outcome.config = config
        set_num_threads = torch.set_num_threads
        if threads:
            # train() calls torch.set_num_threads(2) itself: that call takes our count instead
            torch.set_num_threads = lambda _: set_num_threads(int(threads))
        try:
            utils = _resuming_train_utils(config, resume)
            module.TrainUtils = utils
            result = robomimic_train(config, device=device)
            utils.finished()
            return result
        except Exception as err:
            outcome.error = err
            raise
        finally:
            torch.set_num_threads = set_num_threads
            if train_utils is not None:
                module.TrainUtils = train_utils

    def _resuming_train_utils(config, resume: bool) -> training_resume.ResumingTrainUtils:
        every_s = training_resume.resume_every_s()
        run_dir = training_resume.resumable_run(config.train.output_dir, config.experiment.name) if resume else None
        if run_dir is None:
            if resume:
                print(f"nothing to resume under {config.train.output_dir}/{config.experiment.name}: a new run")
            return training_resume.ResumingTrainUtils(train_utils, every_s=every_s)
        held = training_resume.held_config(run_dir)
        if held is None:
            raise training_resume.ResumeRefused(
                f"{run_dir} holds no readable record of the config it was trained with; train without --resume "
                "(a new run)"
            )
        if training_resume.comparable_config(held) != training_resume.comparable_config(config):
            raise training_resume.ResumeRefused(
                f"{run_dir} was trained with another config; train this one without --resume (a new run)"
            )
        return training_resume.ResumingTrainUtils(train_utils, run_dir, training_resume.load(run_dir), every_s)

    def data_loader(dataset: Dataset, batch_size: int = 1, drop_last: bool = False, **kwargs: Any) -> DataLoader:
        from torch.utils.data import DataLoader  # heavy: torch, only when used

        config = outcome.config
        if config is not None and config.experiment.validate:
            valid_key = config.train.hdf5_validation_filter_key
            if getattr(dataset, "filter_by_attribute", None) == valid_key:
                drop_last = False
        if drop_last and len(dataset) < batch_size:
            raise ValueError(
                f"the training split holds {len(dataset)} samples, fewer than one batch (train.batch_size = "
                f"{batch_size}): record more data or lower the batch size"
            )
        return DataLoader(dataset, batch_size=batch_size, drop_last=drop_last, **kwargs)

    module.train = train
    module.DataLoader = data_loader
    return outcome


def normalize_obs(obs_dict: dict, obs_normalization_stats: dict) -> dict:
    """robomimic's ``ObsUtils.normalize_obs`` (the same stats, of shape (1, ...)) over any leading dimensions of the
    observations: none (a rollout step), a batch, a batch and time. Keys without statistics (an environment's extra
    observables in rollouts) pass unchanged; a new dict is returned, the caller's is left as it was."""
    out = dict(obs_dict)
    for key in obs_dict.keys() & obs_normalization_stats.keys():
        mean = np.asarray(obs_normalization_stats[key]["mean"])[0]
        std = np.asarray(obs_normalization_stats[key]["std"])[0]
        shape = tuple(obs_dict[key].shape)
        if shape[len(shape) - mean.ndim :] != mean.shape:
            raise ValueError(f"observation {key!r} of shape {shape} does not end in its statistics' {mean.shape}")
        out[key] = (obs_dict[key] - mean) / std
    return out


def postprocess_without_normalizing(postprocess: Callable[..., dict]) -> Callable[..., dict]:
    """Algo.postprocess_batch_for_training, less its second normalization: the dataset normalized each sample."""

    @functools.wraps(postprocess)
    def postprocess_batch_for_training(self: Algo, batch: dict, obs_normalization_stats: dict | None) -> dict:
        return postprocess(self, batch, obs_normalization_stats=None)

    return postprocess_batch_for_training


@contextlib.contextmanager
def no_prompts() -> Iterator[None]:
    """Turns any input() robomimic might call into an error: console commands must never wait on a prompt."""

    def refuse(prompt: object = "") -> NoReturn:
        raise RuntimeError(f"robomimic asked interactively ({str(prompt).strip()!r}); veragmil commands never prompt")

    saved = builtins.input
    builtins.input = refuse
    try:
        yield
    finally:
        builtins.input = saved
