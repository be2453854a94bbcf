"""
Resuming a robomimic training run where it stopped.

robomimic 0.3.0's checkpoints hold the networks, not what training needs to go on: the optimizers' moments, the
learning-rate schedules, the random generators and the epoch. Every ``RESUME_EVERY_S`` seconds (at an epoch's
start) the run writes these beside its logs and models (``resume.pth``, replaced whole: a kill mid-write leaves the
previous one), and deletes the file once the run ends. A run started again on that folder skips the finished
epochs and restores the state before the next: robomimic draws each epoch's batches from a fresh loader iterator,
so the resumed run trains on the same batches and ends with the weights an uninterrupted run ends with.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from veragmil_suite.utils.whole_files import write_text_whole, write_whole

if TYPE_CHECKING:
    from robomimic.algo.algo import Algo
    from robomimic.config.config import Config
    from torch.utils.data import DataLoader

RESUME_FILE = "resume.pth"
# the run's config as it started, written whole: robomimic's own config.json is rewritten in place at every start
HELD_CONFIG_FILE = "config.held.json"
PARTIAL_VIDEO_DIR = ".partial"  # inside the run's videos folder: rollout videos while they are recorded
SECONDS_FILE = "training_seconds.json"  # a finished run's training time, over all its pieces
RESUME_FORMAT = 1
# seconds of training between two saves of the resume state; $VERAGMIL_RESUME_EVERY_S overrides (0: every epoch)
RESUME_EVERY_S = 120.0


class ResumeRefused(BaseException):
    """The run to resume was started with another config. A BaseException: robomimic's train script catches every
    Exception and prints it with its traceback; this one reaches the entry point, which says it in one line."""


def resume_every_s() -> float:
    """The interval between saves of the resume state: $VERAGMIL_RESUME_EVERY_S, else RESUME_EVERY_S."""
    value = os.environ.get("VERAGMIL_RESUME_EVERY_S")
    return RESUME_EVERY_S if value in (None, "") else float(value)


def _state_dicts(items):
    """The state of an algorithm's optimizers or schedulers (robomimic holds a list per ensemble network)."""
    if isinstance(items, dict):
        return {key: _state_dicts(value) for key, value in items.items()}
    if isinstance(items, (list, tuple)):
        return [_state_dicts(value) for value in items]
    return None if items is None else items.state_dict()


def _load_state_dicts(items, states) -> None:
    if isinstance(items, dict):
        for key, value in items.items():
            _load_state_dicts(value, states[key])
    elif isinstance(items, (list, tuple)):
        for value, state in zip(items, states, strict=True):
            _load_state_dicts(value, state)
    elif items is not None:
        items.load_state_dict(states)


def capture(model: Algo, epoch: int, seconds: float = 0.0) -> dict:
    """What training needs to go on after ``epoch`` finished epochs of ``model`` (a robomimic Algo), which took
    ``seconds``."""
    import torch  # heavy: torch, only when used

    rng = {"torch": torch.get_rng_state(), "numpy": np.random.get_state(), "python": random.getstate()}
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        rng["cuda"] = torch.cuda.get_rng_state_all()
    return {
        "format": RESUME_FORMAT,
        "epoch": epoch,
        "seconds": seconds,
        "model": model.serialize(),
        "optimizers": _state_dicts(model.optimizers),
        "lr_schedulers": _state_dicts(model.lr_schedulers),
        "rng": rng,
    }


def restore(model: Algo, state: dict) -> None:
    """Puts ``model`` and the random generators where ``state`` (from capture) left them."""
    import torch  # heavy: torch, only when used

    model.deserialize(state["model"])
    _load_state_dicts(model.optimizers, state["optimizers"])
    _load_state_dicts(model.lr_schedulers, state["lr_schedulers"])
    rng = state["rng"]
    torch.set_rng_state(rng["torch"])
    np.random.set_state(rng["numpy"])
    random.setstate(rng["python"])
    if "cuda" in rng and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(rng["cuda"])


def save(run_dir: str | Path, state: dict) -> None:
    """Writes ``state`` as the run's resume file."""
    import torch  # heavy: torch, only when used

    write_whole(Path(run_dir) / RESUME_FILE, lambda partial: torch.save(state, partial))


def load(run_dir: str | Path) -> dict | None:
    """The run's resume state, None when it has none."""
    import torch  # heavy: torch, only when used

    path = Path(run_dir) / RESUME_FILE
    if not path.exists():
        return None
    state = torch.load(path, map_location="cpu", weights_only=False)
    if state.get("format") != RESUME_FORMAT:
        raise ValueError(
            f"{path} is a resume state of format {state.get('format')!r}; this version reads {RESUME_FORMAT}"
        )
    return state


def resumable_run(output_dir: str | Path, name: str) -> Path | None:
    """The newest run folder of experiment ``name`` under ``output_dir`` that holds a resume state."""
    runs = [p.parent for p in Path(output_dir).expanduser().glob(f"{name}/*/{RESUME_FILE}")]
    return max(runs, key=lambda p: (p / RESUME_FILE).stat().st_mtime) if runs else None


def held_config(run_dir: str | Path) -> dict | None:
    """The config a run was started with (ours, else robomimic's config.json beside the run's logs); None when
    neither is there whole."""
    for name in (HELD_CONFIG_FILE, "config.json"):
        try:
            return json.loads((Path(run_dir) / name).read_text())
        except (OSError, ValueError):
            continue
    return None


PATH_KEYS = ("data", "output_dir")  # the train section's paths: a folder named relative or absolute is one folder


def comparable_config(config: dict) -> dict:
    """A robomimic config as plain JSON with the train section's paths absolute: two runs of one experiment compare
    equal whichever way their folders were named."""
    out = json.loads(json.dumps(config))
    train = out.get("train") if isinstance(out, dict) else None
    for key in PATH_KEYS if isinstance(train, dict) else ():
        if isinstance(train.get(key), str):
            train[key] = os.path.abspath(os.path.expanduser(train[key]))
    return out


class ResumingTrainUtils:
    """
    robomimic's train_utils module as robomimic.scripts.train sees it, for one run: its experiment folder is
    ``run_dir`` when resuming; the epochs up to ``state``'s pass without training, saving or rolling out, the state
    is restored before the next; the resume state is saved at an epoch's start once ``every_s`` seconds have passed;
    checkpoints are written under a temporary name first.
    """

    def __init__(self, train_utils, run_dir: Path | None = None, state: dict | None = None, every_s: float = 0.0):
        self._train_utils = train_utils
        self.run_dir = run_dir
        self._state = state
        self.done = state["epoch"] if state is not None else 0
        self._every_s = every_s
        self._epoch = 0
        self._started = self._saved_at = time.monotonic()
        self._seconds_before = state.get("seconds", 0.0) if state is not None else 0.0

    def seconds(self) -> float:
        """Training time of the run so far: this piece's and that of the pieces before the resumed state."""
        return self._seconds_before + time.monotonic() - self._started

    def __getattr__(self, name):
        return getattr(self._train_utils, name)

    def get_exp_dir(self, config: Config, auto_remove_exp_dir: bool = False) -> tuple[str, str | None, str]:
        """The run's folders (robomimic_scripts.experiment_dirs): ``run_dir``'s when resuming, else a new run's."""
        dirs = self._train_utils.get_exp_dir(config, auto_remove_exp_dir, run_dir=self.run_dir)
        self.run_dir = Path(dirs[0]).parent
        write_text_whole(self.run_dir / HELD_CONFIG_FILE, json.dumps(config, indent=4))
        return dirs

    def run_epoch(
        self, model: Algo, data_loader: DataLoader, epoch: int, validate: bool = False, **kwargs: Any
    ) -> dict:
        if not validate:
            self._epoch = epoch
            if epoch == 1 and self.done:
                self._skip_epoch_ends(model)
            if epoch == self.done + 1 and self._state is not None:
                restore(model, self._state)
                self._state = None
                print(f"resumed from {self.run_dir / RESUME_FILE} after epoch {self.done}")
            elif epoch > self.done + 1 and time.monotonic() - self._saved_at >= self._every_s:
                save(self.run_dir, capture(model, epoch - 1, self.seconds()))
                self._saved_at = time.monotonic()
        if epoch <= self.done:
            return {}
        return self._train_utils.run_epoch(
            model=model, data_loader=data_loader, epoch=epoch, validate=validate, **kwargs
        )

    def _skip_epoch_ends(self, model) -> None:
        """The finished epochs' ends (learning-rate steps) are in the state restored after them."""
        on_epoch_end = model.on_epoch_end

        def after_restore(epoch: int) -> None:
            if epoch > self.done:
                on_epoch_end(epoch)

        model.on_epoch_end = after_restore

    @property
    def skipping(self) -> bool:
        """Whether the loop is in an epoch the resumed state has finished."""
        return 0 < self._epoch <= self.done

    def rollout_with_stats(self, *args: Any, **kwargs: Any) -> tuple[dict, dict | None]:
        """robomimic's rollouts, their videos written whole: robomimic writes each into ``video_dir`` as it records
        (a kill leaves a torn video under the epoch's name); here into a folder inside it, each moved into place
        when the rollouts end. A folder a kill left is emptied at the next rollouts."""
        if self.skipping:
            return {}, None
        video_dir = kwargs.get("video_dir")
        if video_dir is None:
            return self._train_utils.rollout_with_stats(*args, **kwargs)
        partial = Path(video_dir) / PARTIAL_VIDEO_DIR
        shutil.rmtree(partial, ignore_errors=True)
        partial.mkdir()
        logs, paths = self._train_utils.rollout_with_stats(*args, **{**kwargs, "video_dir": str(partial)})
        whole = {}
        for env_name, path in paths.items():
            whole[env_name] = os.path.join(video_dir, os.path.basename(path))
            os.replace(path, whole[env_name])
        shutil.rmtree(partial, ignore_errors=True)
        return logs, whole

    def save_model(
        self,
        model: Algo,
        config: Config,
        env_meta: dict,
        shape_meta: dict,
        ckpt_path: str,
        obs_normalization_stats: dict | None = None,
    ) -> None:
        if self.skipping:
            return
        write_whole(
            Path(ckpt_path),
            lambda partial: self._train_utils.save_model(
                model=model,
                config=config,
                env_meta=env_meta,
                shape_meta=shape_meta,
                ckpt_path=str(partial),
                obs_normalization_stats=obs_normalization_stats,
            ),
        )

    def finished(self) -> None:
        """The run ended: its training time is written and its resume state is no longer needed."""
        if self.run_dir is not None:
            text = json.dumps({"seconds": round(self.seconds(), 1)}) + "\n"
            write_text_whole(self.run_dir / SECONDS_FILE, text)
            (self.run_dir / RESUME_FILE).unlink(missing_ok=True)


def training_seconds(run_dir: str | Path) -> float | None:
    """A finished run's training time over all its pieces (None for a run without the record)."""
    path = Path(run_dir) / SECONDS_FILE
    return json.loads(path.read_text())["seconds"] if path.exists() else None
