"""Kinds of value that name files and folders: inputs that must exist and hold what they claim (JSON, HDF5, robomimic
configs and checkpoints), outputs whose folder can be written and whose name leaves room for a write's suffix.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py

from veragmil_suite.learning.checkpoints import read_checkpoint
from veragmil_suite.learning.config_values import build_config, value_problem
from veragmil_suite.utils.cli.kinds import Kind, robomimic_algos

# Suffixes our writers append to an output's name while it is written (datasets.py: ".partial"; pipeline.py:
# ".new"): an output name leaves room for the longest of them.
WRITE_SUFFIX_ROOM = len(".partial")


def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder if folder.is_dir() else ".", "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _stat_problem(path: Path) -> str | None:
    """Why ``path`` cannot be looked at (a name too long, a file where a folder should be), else None."""
    try:
        path.stat()
    except FileNotFoundError:
        return None
    except OSError as error:
        return error.strerror.lower() if error.strerror else str(error)
    return None


def _readable(text: str, folder: bool, what: str) -> Path:
    """``text`` as a path that exists, is a folder (else a file) and can be read: the one line why not, else the
    path."""
    path = Path(text)
    problem = _stat_problem(path)
    if problem:
        raise argparse.ArgumentTypeError(f"{text}: {problem}")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such {'folder' if folder else 'file'}")
    if path.is_dir() != folder:
        raise argparse.ArgumentTypeError(f"{text}: is a {'file' if folder else 'directory'}, not a {what}")
    if not os.access(path, os.R_OK | (os.X_OK if folder else 0)):
        raise argparse.ArgumentTypeError(f"{text}: not readable (permission denied)")
    return path


class InputFile(Kind):
    """An existing, readable file; ``check(path)`` may look inside it (raising ValueError or OSError with the
    reason)."""

    def __init__(self, what: str = "file", check: Callable[[str], Any] | None = None):
        self.what = what
        self.check = check
        self.accepted = f"an existing, readable {what}"

    def __call__(self, text: str) -> Any:
        _readable(text, False, self.what)
        if self.check is None:
            return text
        try:
            result = self.check(text)
        except (ValueError, OSError, KeyError, TypeError) as error:
            raise argparse.ArgumentTypeError(f"{text}: not a readable {self.what} ({one_line(error)})") from None
        return text if result is None else result


class InputFolder(Kind):
    """An existing, readable folder, holding ``holds`` (a path inside it) when given: a checkout's top level, a
    folder put on a path."""

    def __init__(self, what: str = "folder", holds: str | None = None):
        self.what = what
        self.holds = holds
        self.accepted = f"an existing {what}" + (f" holding {holds}" if holds else "")

    def __call__(self, text: str) -> str:
        if not str(text).strip():
            raise self.refuse(text)
        path = _readable(text, True, self.what)
        if self.holds and not (path / self.holds).is_file():
            raise argparse.ArgumentTypeError(f"{text}: holds no {self.holds}; must be {self.accepted}")
        return text


def _writable_folder(folder: Path, text: str) -> None:
    if not folder.exists():
        raise argparse.ArgumentTypeError(f"{text}: the folder {str(folder) or '.'} does not exist")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: the folder {folder} is not writable")


# what imageio's ffmpeg and pillow plugins write here (webm, m4v, mpg and others fail or write nothing)
VIDEO_SUFFIXES = (".mp4", ".gif", ".avi", ".mov", ".mkv")


class OutputFile(Kind):
    """A file to write (or to append to, when it exists): not a folder, in a writable folder that exists, with a
    name short enough for the file system once our writers add their temporary suffix, and one of ``suffixes`` when
    given (a video's: a dataset's name given by mistake is refused before imageio empties that file and fails)."""

    def __init__(self, what: str = "file", suffixes: tuple[str, ...] = ()):
        self.what = what
        self.suffixes = suffixes
        ending = f" ({', '.join(suffixes)})" if suffixes else ""
        self.accepted = f"a {what}{ending} to write, in an existing writable folder"

    def __call__(self, text: str) -> str:
        if not str(text).strip():
            raise self.refuse(text)
        path = Path(text)
        limit = _name_max(path.parent) - WRITE_SUFFIX_ROOM
        if len(os.fsencode(path.name)) > limit:
            raise argparse.ArgumentTypeError(f"{text}: the file name is longer than {limit} bytes")
        problem = _stat_problem(path)
        if problem:
            raise argparse.ArgumentTypeError(f"{text}: {problem}")
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text}: is a directory, not a {self.what}")
        _writable_folder(path.parent, text)
        if path.exists() and not os.access(path, os.W_OK):
            raise argparse.ArgumentTypeError(f"{text}: exists and is not writable")
        if self.suffixes and path.suffix.lower() not in self.suffixes:
            raise argparse.ArgumentTypeError(f"{text}: not a {self.what} name; accepted: {', '.join(self.suffixes)}")
        return text


class OutputFolder(Kind):
    """A folder to write into: an existing writable folder, or a new one whose parent exists and is writable."""

    accepted = "a folder to write into (existing, or new in an existing writable folder)"

    def __call__(self, text: str) -> str:
        if not str(text).strip():
            raise self.refuse(text)
        path = Path(text)
        if len(os.fsencode(path.name)) > _name_max(path.parent) - WRITE_SUFFIX_ROOM:
            raise argparse.ArgumentTypeError(f"{text}: the folder name is too long")
        problem = _stat_problem(path)
        if problem:
            raise argparse.ArgumentTypeError(f"{text}: {problem}")
        if path.exists():
            if not path.is_dir():
                raise argparse.ArgumentTypeError(f"{text}: is a file, not a folder")
            if not os.access(path, os.W_OK | os.X_OK):
                raise argparse.ArgumentTypeError(f"{text}: the folder is not writable")
            return text
        parent = next((p for p in path.absolute().parents if p.exists()), Path("/"))
        _writable_folder(parent, text)
        return text


class FileName(Kind):
    """A file or folder name alone, no path: robomimic's --output_name (written beside the dataset), an experiment's
    name (its folder under the output folder)."""

    def __init__(self, what: str = "file name", accepted: str = "a file name without a folder") -> None:
        self.what = what
        self.accepted = accepted

    def __call__(self, text: str) -> str:
        if not isinstance(text, str) or not text.strip() or os.sep in text or text in (".", "..") or "\n" in text:
            raise self.refuse(text)
        if len(os.fsencode(text)) > 255 - WRITE_SUFFIX_ROOM:
            raise argparse.ArgumentTypeError(f"{text}: the {self.what} is longer than {255 - WRITE_SUFFIX_ROOM} bytes")
        return text


def one_line(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return " ".join(text.split())


def _json_value(path: str) -> Any:
    try:
        with open(path) as f:
            return json.load(f)
    except UnicodeDecodeError as error:
        raise ValueError(f"not text: {error}") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"not JSON: {error}") from None


def _hdf5(path: str) -> None:
    if not h5py.is_hdf5(path):
        raise ValueError("no HDF5 signature")


def _robomimic_hdf5(path: str) -> None:
    """An HDF5 file laid out as robomimic's datasets are: a ``data`` group of demos with the env's metadata."""
    _hdf5(path)
    with h5py.File(path, "r") as f:
        data = f.get("data")
        if not isinstance(data, h5py.Group):
            raise ValueError("robomimic's layout needs a 'data' group of demos")
        if "env_args" not in data.attrs:
            raise ValueError("its 'data' group has no env_args attribute (robomimic's environment metadata)")
        for name in data:
            demo = data[name]
            if not isinstance(demo, h5py.Group) or "actions" not in demo:
                raise ValueError(f"data/{name} is not a demo (a group with actions)")
            if "obs" in demo and not isinstance(demo["obs"], h5py.Group):
                raise ValueError(f"data/{name}/obs is not a group of observation keys")


def _robomimic_config(path: str) -> None:
    """A robomimic config file: JSON whose algo_name robomimic knows, whose keys its config of that algo has, and whose
    values it can train with (veragmil_suite.learning.config_values)."""
    config = _json_value(path)
    if not isinstance(config, dict):
        raise ValueError("a robomimic config is a JSON object")
    algos = robomimic_algos()
    if config.get("algo_name") not in algos:
        raise ValueError(f"algo_name {config.get('algo_name')!r} is not one of robomimic's: {', '.join(algos)}")
    from robomimic.config import config_factory  # heavy: robomimic, imports torch

    defaults = json.loads(config_factory(config["algo_name"]).dump())
    try:
        build_config(config)
    except (RuntimeError, KeyError, AttributeError) as error:
        raise ValueError(one_line(error)) from None
    problem = value_problem(config, defaults)
    if problem:
        raise ValueError(problem)


CHECKPOINT_KEYS = ("algo_name", "config", "env_metadata", "shape_metadata", "model")


def _checkpoint(path: str) -> None:
    """A robomimic checkpoint: what robomimic's loader reads as a dict with the keys its tools use."""
    try:
        checkpoint = read_checkpoint(path, weights=False)
    except Exception as error:  # noqa: BLE001 - torch raises many kinds for a bad file; each is named
        raise ValueError(f"torch cannot read it: {type(error).__name__}: {one_line(error)}") from None
    if not isinstance(checkpoint, dict):
        raise ValueError(f"it holds a {type(checkpoint).__name__}, not a checkpoint dict")
    missing = [k for k in CHECKPOINT_KEYS if k not in checkpoint]
    if missing:
        raise ValueError(f"it lacks {', '.join(missing)}")


json_file = InputFile("JSON file", check=_json_value)
# our datasets' content is checked where they are opened (veragmil_suite.data.schema.open_dataset: one DatasetError
# line naming what is wrong), which also knows what an interrupted write left
dataset = InputFile("dataset file")
robomimic_dataset = InputFile("robomimic dataset (HDF5)", check=_robomimic_hdf5)
robomimic_config = InputFile("robomimic config (JSON)", check=_robomimic_config)
checkpoint = InputFile("robomimic checkpoint (.pth)", check=_checkpoint)
output_dataset = OutputFile("dataset file")
output_video = OutputFile("video file", suffixes=VIDEO_SUFFIXES)
output_folder = OutputFolder()
file_name = FileName()
experiment_name = FileName("experiment name", "an experiment name: one folder's name, no path")
