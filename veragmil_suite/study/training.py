"""The study's training stage: a robomimic config per run from configs/json, and training runs that resume or are
skipped when complete.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from veragmil_suite.data.schema import demo_names, open_dataset
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.learning.observation_sets import with_observation_set
from veragmil_suite.learning.training_resume import comparable_config, training_seconds
from veragmil_suite.study.logged_run import TRAINING_PROGRESS, LogProgress, console, run_logged
from veragmil_suite.study.settings import ROBOMIMIC_TORCH_THREADS, StageError
from veragmil_suite.utils.distributed import Resources, cluster_resources
from veragmil_suite.utils.whole_files import write_text_whole


def training_config(
    algo: str,
    dataset: Path,
    output_dir: Path,
    name: str,
    epochs: int,
    steps_per_epoch: int,
    seed: int = 1,
    filter_key: str | None = None,
    save_epochs: list[int] | None = None,
    obs_set: str | None = None,
) -> dict:
    """Our stock config of ``algo`` (configs/json) shortened to ``epochs`` x ``steps_per_epoch`` gradient steps,
    trained on the demos of ``filter_key`` (all when None), with the low-dim observations of ``obs_set``
    (veragmil_suite.learning.observation_sets; None: the config's own).

    Rollouts during training are off (the evaluation scores checkpoints on every food afterwards); the last epoch
    and ``save_epochs`` are saved.
    """
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; accepted: {sorted(ALGORITHMS)}")
    config = ALGORITHMS[algo].stock_config()
    experiment = config["experiment"]
    experiment.update(name=name, epoch_every_n_steps=steps_per_epoch, validate=False, render_video=False)
    experiment["rollout"]["enabled"] = False
    experiment["save"].update(enabled=True, every_n_epochs=epochs, on_best_rollout_success_rate=False)
    experiment["save"]["epochs"] = sorted(set(save_epochs or []) - {epochs})
    config["train"].update(data=str(dataset), output_dir=str(output_dir), num_epochs=epochs, seed=seed)
    config["train"]["hdf5_filter_key"] = filter_key
    return with_observation_set(config, obs_set) if obs_set is not None else config


def _checkpoints(config: dict) -> dict[int, Path]:
    """The saved checkpoints of a training run by epoch (its newest run folder)."""
    name = config["experiment"]["name"]
    runs = sorted(Path(config["train"]["output_dir"]).glob(f"{name}/*/models"), key=lambda p: p.stat().st_mtime)
    if not runs:
        return {}
    return {int(p.stem.split("_")[-1]): p for p in runs[-1].glob("model_epoch_*.pth")}


def _what_is_trained(config: dict) -> dict:
    """The config less its extra checkpoint epochs (they change what is saved, not what is trained), its paths
    absolute."""
    out = comparable_config(config)
    if isinstance(out, dict):
        out.get("experiment", {}).get("save", {}).pop("epochs", None)
    return out


def training_data_digest(config: dict) -> str:
    """What a run trains on, as a digest: the demos of its filter key in order, each one's steps and actions. A
    recording made again from the same seeds gives the same digest; a cut by another rule or other demos do not."""
    path = Path(config["train"]["data"]).resolve()
    stat = path.stat()
    return _digest(str(path), stat.st_ino, stat.st_size, stat.st_mtime_ns, config["train"].get("hdf5_filter_key"))


@functools.lru_cache(maxsize=64)
def _digest(path: str, inode: int, size: int, mtime_ns: int, key: str | None) -> str:
    """training_data_digest of one version of a file (a study asks for it several times a run: 0.3 s each for
    the 300 MB spacemouse recording)."""
    digest = hashlib.sha256()
    with open_dataset(path) as f:
        names = [n.decode() for n in f["mask"][key][()]] if key else demo_names(f)
        for name in names:
            actions = np.ascontiguousarray(f["data"][name]["actions"][()])
            digest.update(f"{name}:{len(actions)}:".encode())
            digest.update(actions.tobytes())
    return digest.hexdigest()


def _data_file(config: dict, work_dir: Path) -> Path:
    return Path(work_dir) / f"{config['experiment']['name']}.data.json"


def trained_on_other_data(config: dict, work_dir: Path) -> bool:
    """Whether the run of this config in ``work_dir`` trained on data that has changed since (its data file made
    again from other recordings, or cut by another rule). A run from before the digest was kept counts as not."""
    held = _data_file(config, work_dir)
    if not held.exists() or not Path(config["train"]["data"]).exists():
        return False
    return json.loads(held.read_text()).get("digest") != training_data_digest(config)


def finished_training(config: dict, work_dir: Path) -> dict[int, Path] | None:
    """
    The checkpoints by epoch of a finished run of this config that holds every checkpoint asked for, trained on
    the data as it is now; None when it is to be trained.

    Raises:
        StageError: [the run's folder holds another config]
    """
    config_file = Path(work_dir) / f"{config['experiment']['name']}.json"
    if not config_file.exists():
        return None
    held = json.loads(config_file.read_text())
    if _what_is_trained(held) != _what_is_trained(config):
        name = config["experiment"]["name"]
        raise StageError(f"{config_file} holds another config for {name}; use another output directory")
    found = _checkpoints(config)
    wanted = {int(config["train"]["num_epochs"]), *config["experiment"]["save"].get("epochs", [])}
    return found if wanted <= set(found) and not trained_on_other_data(config, work_dir) else None


def train_checkpoint(
    config: dict,
    work_dir: Path,
    say: Callable[[str], None] = print,
    torch_threads: int | None = None,
    progress: bool = False,
    echo: bool = False,
) -> tuple[dict[int, Path], float | None]:
    """
    Trains with veragmil-train (with ``torch_threads`` torch threads when given, else $VERAGMIL_TORCH_THREADS or
    robomimic's 2; with ``progress``, a bar of its epochs, and with ``echo`` robomimic's output) unless a finished
    run of the same config holding every checkpoint asked for is there; a killed run of the same config goes on
    from its resume state. A run whose data changed since it trained (``trained_on_other_data``) is trained again
    from the start. Returns the checkpoints by epoch and the wall time (None when skipped; for a resumed run, its
    training time over all pieces).

    Raises:
        StageError: [training failed or wrote no last checkpoint, or the run's folder holds another config]
    """
    work_dir = Path(work_dir)
    name = config["experiment"]["name"]
    config_file = work_dir / f"{name}.json"
    epochs = int(config["train"]["num_epochs"])
    wanted = {epochs, *config["experiment"]["save"].get("epochs", [])}
    found = finished_training(config, work_dir)
    if found is not None:
        say(f"skipping training {name}: its checkpoints are there ({found[epochs].parent})")
        return found, None
    resume = False
    if config_file.exists():
        held = json.loads(config_file.read_text())
        if comparable_config(held) == comparable_config(config) and not trained_on_other_data(config, work_dir):
            resume = True  # killed: veragmil-train goes on from the run's resume state, when it saved one
        else:
            # saved at other epochs (train again, saving both), or trained on other data
            saved = set(held["experiment"]["save"].get("epochs", [])) | set(config["experiment"]["save"]["epochs"])
            config = json.loads(json.dumps(config))
            config["experiment"]["save"]["epochs"] = sorted(saved - {epochs})
            shutil.rmtree(Path(config["train"]["output_dir"]) / name, ignore_errors=True)
    write_text_whole(config_file, json.dumps(config, indent=4))
    if Path(config["train"]["data"]).exists():  # robomimic names a missing one
        data = dict(data=config["train"]["data"], filter_key=config["train"]["hdf5_filter_key"])
        write_text_whole(
            _data_file(config, work_dir), json.dumps(dict(data, digest=training_data_digest(config)), indent=2)
        )
    environ = {}
    if torch_threads is not None:
        environ = {"VERAGMIL_TORCH_THREADS": str(torch_threads), "OMP_NUM_THREADS": str(torch_threads)}
    command = [*console("veragmil-train"), "--config", str(config_file), *(["--resume"] if resume else [])]
    bar = LogProgress(epochs, TRAINING_PROGRESS, name, "epoch", echo) if progress else None
    seconds = run_logged(command, work_dir / f"{name}.log", f"training {name}", environ=environ, progress=bar)
    found = _checkpoints(config)
    if not wanted <= set(found):
        raise StageError(f"training {name} wrote no last checkpoint under {config['train']['output_dir']}/{name}")
    if resume:  # the run's own record covers the pieces before this one too
        seconds = training_seconds(found[epochs].parent.parent) or seconds
    return found, seconds


def train_piece(context: tuple[Path, int | None, bool, bool], config: dict) -> tuple[dict[int, Path], float | None]:
    """A training run as a piece (veragmil_suite.utils.distributed): ``context`` is (work_dir, torch threads, whether to
    show a progress bar, whether to show robomimic's output)."""
    work_dir, threads, progress, echo = context
    return train_checkpoint(config, work_dir, say=lambda _: None, torch_threads=threads, progress=progress, echo=echo)


def training_resources() -> Resources:
    """What a training run holds on a Ray node: a CPU per torch thread ($VERAGMIL_TORCH_THREADS, else robomimic's
    2), and a GPU when the cluster has one (robomimic trains on it)."""
    threads = int(os.environ.get("VERAGMIL_TORCH_THREADS") or ROBOMIMIC_TORCH_THREADS)
    return Resources(cpus=threads, gpus=1 if cluster_resources().get("GPU", 0) >= 1 else 0)
