"""
The console programs' command line, in one place: the kinds of value an option takes (argparse types that refuse a
bad value in one line naming the option, the value and what is accepted), the parser every program builds (one
spelling convention, old spellings hidden), and the handler every program runs under (an expected error is one
line on stderr and exit status 2; Ctrl-C is one line and 130, the shell's status for an interrupted program).

Conventions (tests/test_cli.py walks every console program's parser and holds them):
    - an option is named in lowercase words joined by dashes, with robosuite's or robomimic's words where they have
      the option (--robots, --camera-names, --dataset); its underscore spelling is accepted as well (--max_fr,
      --n_rollouts), and so are the spellings it had before (hidden from --help, so committed commands keep running)
    - a list is given as space-separated values, commas accepted too (--foods rice pasta, --foods rice,pasta)
    - an option's value is checked by its kind, here, before anything runs
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import copy
import errno
import functools
import inspect
import json
import math
import os
import socket
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

# Suffixes our writers append to an output's name while it is written (datasets.py: ".partial"; pipeline.py:
# ".new"): an output name leaves room for the longest of them.
WRITE_SUFFIX_ROOM = len(".partial")


class UsageError(Exception):
    """Bad input found after parsing: the handler prints it as one line and exits 2."""


# errors the handler reports in one line, by class name (importing their modules here would import h5py or Ray)
EXPECTED_ERRORS = (
    "veragmil_suite.data.schema.DatasetError",
    "veragmil_suite.utils.distributed.RayMissing",
    "veragmil_suite.data.lerobot_export.ExtraNotInstalled",
)
# OSErrors about the user's files, folders, disk or addresses, not about our code
USER_ERRNOS = {
    errno.ENOENT,
    errno.EACCES,
    errno.EPERM,
    errno.EISDIR,
    errno.ENOTDIR,
    errno.ENAMETOOLONG,
    errno.EROFS,
    errno.ENOSPC,
    errno.EDQUOT,
    errno.EEXIST,
    errno.EADDRINUSE,
    errno.EADDRNOTAVAIL,
    errno.EAGAIN,
}


# ---------------------------------------------------------------------------------------------------------------- #
# Kinds of value                                                                                                   #
# ---------------------------------------------------------------------------------------------------------------- #


class Kind:
    """An argparse type for one kind of value: ``kind(text)`` is the value, or an ArgumentTypeError saying what is
    accepted. ``accepted`` describes the values (for messages and --help)."""

    accepted = "a value"

    def __call__(self, text: str) -> Any:
        raise NotImplementedError

    def refuse(self, text: Any, why: str | None = None) -> argparse.ArgumentTypeError:
        return argparse.ArgumentTypeError(f"{why or 'must be ' + self.accepted}, got {text!r}")

    def __repr__(self) -> str:  # argparse names a type by its repr in some messages
        return self.accepted


class Integer(Kind):
    """An integer in [low, high]."""

    def __init__(self, low: int | None = None, high: int | None = None, accepted: str | None = None):
        self.low, self.high = low, high
        self.accepted = accepted or _range_text("an integer", low, high)

    def __call__(self, text: str) -> int:
        try:
            value = int(str(text).strip())
        except ValueError:
            raise self.refuse(text) from None
        if (self.low is not None and value < self.low) or (self.high is not None and value > self.high):
            raise self.refuse(value)
        return value


class Real(Kind):
    """A finite number in [low, high] (an end left out where ``open_low`` / ``open_high``)."""

    def __init__(
        self,
        low: float | None = None,
        high: float | None = None,
        open_low: bool = False,
        open_high: bool = False,
        accepted: str | None = None,
    ):
        self.low, self.high, self.open_low, self.open_high = low, high, open_low, open_high
        if accepted is None:
            lo = "" if low is None else f"{'(' if open_low else '['}{low:g}"
            hi = "" if high is None else f"{high:g}{')' if open_high else ']'}"
            accepted = f"a finite number in {lo or '(-inf'}, {hi or 'inf)'}"
        self.accepted = accepted

    def __call__(self, text: str) -> float:
        try:
            value = float(str(text).strip())
        except ValueError:
            raise self.refuse(text) from None
        if not math.isfinite(value) or not self.contains(value):
            raise self.refuse(text)
        return value

    def contains(self, value: float) -> bool:
        low_ok = self.low is None or (value > self.low if self.open_low else value >= self.low)
        high_ok = self.high is None or (value < self.high if self.open_high else value <= self.high)
        return low_ok and high_ok


def _range_text(what: str, low, high) -> str:
    if low == 1 and high is None:
        return f"a positive {what.split()[-1]}"
    if low == 0 and high is None:
        return f"a non-negative {what.split()[-1]}"
    if high is None:
        return f"{what} of at least {low}"
    return f"{what} in [{low}, {high}]"


class Choice(Kind):
    """One of a set of names (given, or produced by a function called at first use, so that building a parser
    imports nothing heavy)."""

    def __init__(self, what: str, values: Iterable[str] | Callable[[], Iterable[str]]):
        self.what = what
        self._values = values

    @functools.cached_property
    def values(self) -> list[str]:
        values = self._values() if callable(self._values) else self._values
        return [str(v) for v in values]

    @property
    def accepted(self) -> str:
        return f"{self.what}, one of: {', '.join(self.values)}"

    def __call__(self, text: str) -> str:
        if text not in self.values:
            raise argparse.ArgumentTypeError(f"unknown {self.what} {text!r}; accepted: {', '.join(self.values)}")
        return text


class Text(Kind):
    """Free text on one line, not empty (a name, a label)."""

    def __init__(self, accepted: str = "non-empty text on one line"):
        self.accepted = accepted

    def __call__(self, text: str) -> str:
        if not str(text).strip() or "\n" in text or "\r" in text:
            raise self.refuse(text)
        return text


class RayAddress(Kind):
    """Where Ray runs: a cluster's head (host:port, ray://host:port, auto), or empty for this machine (what --ray
    alone gives)."""

    accepted = "a Ray address (host:port, ray://host:port or auto), or nothing for this machine"

    def __call__(self, text: str) -> str:
        if any(c.isspace() for c in str(text)):
            raise self.refuse(text)
        return text


class Boolean(Kind):
    """true or false (also yes/no, on/off, 1/0), for robosuite's options that take a bool as a value."""

    accepted = "true or false"
    WORDS = {"true": True, "yes": True, "on": True, "1": True, "false": False, "no": False, "off": False, "0": False}

    def __call__(self, text: str) -> bool:
        value = self.WORDS.get(str(text).strip().lower())
        if value is None:
            raise self.refuse(text)
        return value


class ListOf(Kind):
    """A list of another kind: the option takes several values, and a value may hold several separated by commas."""

    def __init__(self, item: Kind):
        self.item = item
        self.accepted = f"{item.accepted}; several, separated by spaces or commas"

    def __call__(self, text: str) -> list:
        parts = str(text).split(",")
        if any(not p.strip() for p in parts):
            raise argparse.ArgumentTypeError(f"an empty item in {text!r}; items are {self.item.accepted}")
        return [self.item(p.strip()) for p in parts]


class KeyValue(Kind):
    """``KEY=VALUE`` with KEY and VALUE of their own kinds, as a (key, value) pair."""

    def __init__(self, key: Kind, value: Kind, metavar: str):
        self.key, self.value, self.metavar = key, value, metavar
        self.accepted = f"{metavar} with {metavar.split('=')[0]} {key.accepted} and {metavar.split('=')[1]} " + (
            value.accepted
        )

    def __call__(self, text: str) -> tuple:
        key, sep, value = str(text).partition("=")
        if not sep:
            raise self.refuse(text)
        try:
            return self.key(key.strip()), self.value(value.strip())
        except argparse.ArgumentTypeError as error:
            raise argparse.ArgumentTypeError(f"{text!r}: {error}") from None


# -- numbers ------------------------------------------------------------------------------------------------------- #

count = Integer(1)  # episodes, demos, steps, pixels, processes
count_or_zero = Integer(0)  # a count that may be none
seed = Integer(0, 2**32 - 1, accepted="a seed in [0, 4294967295]")  # numpy's range
fraction_below_one = Real(0.0, 1.0, open_high=True)  # a validation share: some demos must be left to train on
positive = Real(0.0, open_low=True)  # a scale, a frame rate, a time constant
non_negative = Real(0.0)  # a duration that may be zero
any_number = Real()


class ControlFreq(Kind):
    """A control rate (Hz) the task runs at the physics step: at least the task's MIN_CONTROL_FREQ_HZ, and a whole
    number of physics steps per control period."""

    @property
    def accepted(self) -> str:
        from veragmil_suite.environments.scoop import MIN_CONTROL_FREQ_HZ

        return f"a control rate in Hz of at least {MIN_CONTROL_FREQ_HZ:g}"

    def __call__(self, text: str, timestep_s: float | None = None) -> float:
        from veragmil_suite.environments.scoop import MIN_CONTROL_FREQ_HZ
        from veragmil_suite.models.scoop_task import PHYSICS_TIMESTEP_S, check_physics_timestep

        try:
            value = float(str(text).strip())
        except ValueError:
            raise self.refuse(text) from None
        if not MIN_CONTROL_FREQ_HZ <= value < math.inf:
            raise self.refuse(text)
        try:
            check_physics_timestep(PHYSICS_TIMESTEP_S if timestep_s is None else timestep_s, value)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return int(value) if value == int(value) else value


control_freq = ControlFreq()


# -- task names ---------------------------------------------------------------------------------------------------- #


def _foods() -> list[str]:
    from veragmil_suite.models.foods import FOODS, TRAINING_FOODS, UNSEEN_FOODS

    return list(dict.fromkeys([*TRAINING_FOODS, *UNSEEN_FOODS, *FOODS]))


def _profiles() -> list[str]:
    from veragmil_suite.devices.expert import PROFILES

    return sorted(PROFILES)


def _algos() -> list[str]:
    from veragmil_suite.study.settings import ALGO_CONFIGS

    return sorted(ALGO_CONFIGS)


def _observation_sets() -> list[str]:
    from veragmil_suite.learning.observation_sets import OBSERVATION_SETS

    return sorted(OBSERVATION_SETS)


def _physics() -> list[str]:
    from veragmil_suite.models.foods import PHYSICS

    return list(PHYSICS)


def _robomimic_algos() -> list[str]:
    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()  # robomimic imports torchvision and mujoco_py, which the compatibility layer bridges
    from robomimic.config.base_config import REGISTERED_CONFIGS

    return sorted(REGISTERED_CONFIGS)


food = Choice("food", _foods)
profile = Choice("operator profile", _profiles)
algo = Choice("algorithm", _algos)
observation_set = Choice("observation set", _observation_sets)
physics = Choice("physics", _physics)
robomimic_algo = Choice("robomimic algorithm", _robomimic_algos)
environment = Choice("environment", ["ScoopGranular"])


class Robot(Kind):
    """A robosuite robot that can carry the spoon (veragmil_suite.models.humanoid.check_robot)."""

    accepted = "a robosuite robot that can hold the spoon (XArm7, Panda, ..., G1FixedLowerBody)"

    def __call__(self, text: str) -> str:
        from veragmil_suite.models.humanoid import check_robot

        try:
            check_robot(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return text


robot = Robot()


def _cameras() -> list[str]:
    """The cameras of the task's arena and of its default robot (robosuite prefixes a robot's own with robot0_)."""
    from robosuite.models.robots import XArm7

    from veragmil_suite.models.arena import ScoopArena

    arena = [c.get("name") for c in ScoopArena().worldbody.iter("camera")]
    return arena + list(XArm7().cameras)


camera = Choice("camera", _cameras)


class Controller(Kind):
    """A controller collection can drive: OSC_POSE (the task's tuning), a robosuite composite controller (BASIC,
    ...) or a composite-controller JSON file, each with an OSC_POSE arm (every device and the expert send OSC_POSE
    deltas)."""

    accepted = "OSC_POSE, a robosuite composite controller (BASIC, ...) or a composite-controller JSON file"

    def __call__(self, text: str) -> str:
        from robosuite.controllers import ALL_COMPOSITE_CONTROLLERS

        from veragmil_suite.controllers.scoop_config import ARM_CONTROLLERS

        if text == "OSC_POSE" or text in ALL_COMPOSITE_CONTROLLERS:
            return text
        if text in ARM_CONTROLLERS:
            raise argparse.ArgumentTypeError(
                f"collection needs OSC_POSE deltas; robosuite's devices and the scripted expert do not drive {text}"
            )
        path = Path(text)
        if path.suffix.lower() != ".json" and not path.exists():
            raise argparse.ArgumentTypeError(
                f"unknown controller {text!r}; accepted: OSC_POSE, robosuite's composite controllers "
                f"({', '.join(sorted(ALL_COMPOSITE_CONTROLLERS))}) or a composite-controller JSON file"
            )
        config = json_file(text)
        arm = config.get("body_parts", {}).get("right", {}) if isinstance(config, dict) else {}
        if not isinstance(arm, dict) or arm.get("type") != "OSC_POSE":
            kind = arm.get("type") if isinstance(arm, dict) else None
            raise argparse.ArgumentTypeError(f"{text} drives the arm with {kind!r}; collection needs OSC_POSE deltas")
        return text


controller = Controller()


# -- paths --------------------------------------------------------------------------------------------------------- #


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


class InputFile(Kind):
    """An existing, readable file; ``check(path)`` may look inside it (raising ValueError or OSError with the
    reason)."""

    def __init__(self, what: str = "file", check: Callable[[str], Any] | None = None):
        self.what = what
        self.check = check
        self.accepted = f"an existing, readable {what}"

    def __call__(self, text: str) -> Any:
        path = Path(text)
        problem = _stat_problem(path)
        if problem:
            raise argparse.ArgumentTypeError(f"{text}: {problem}")
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text}: is a directory, not a {self.what}")
        if not path.exists():
            raise argparse.ArgumentTypeError(f"{text}: no such file")
        if not os.access(path, os.R_OK):
            raise argparse.ArgumentTypeError(f"{text}: not readable (permission denied)")
        if self.check is None:
            return text
        try:
            result = self.check(text)
        except (ValueError, OSError, KeyError, TypeError) as error:
            raise argparse.ArgumentTypeError(f"{text}: not a readable {self.what} ({_one_line(error)})") from None
        return text if result is None else result


def _writable_folder(folder: Path, text: str) -> None:
    if not folder.exists():
        raise argparse.ArgumentTypeError(f"{text}: the folder {str(folder) or '.'} does not exist")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: the folder {folder} is not writable")


class OutputFile(Kind):
    """A file to write (or to append to, when it exists): not a folder, in a writable folder that exists, with a
    name short enough for the file system once our writers add their temporary suffix."""

    def __init__(self, what: str = "file"):
        self.what = what
        self.accepted = f"a {what} to write, in an existing writable folder"

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
    """A file name alone (robomimic's --output_name, written beside the dataset)."""

    accepted = "a file name without a folder"

    def __call__(self, text: str) -> str:
        if not str(text).strip() or os.sep in text or text in (".", ".."):
            raise self.refuse(text)
        if len(os.fsencode(text)) > 255 - WRITE_SUFFIX_ROOM:
            raise argparse.ArgumentTypeError(f"{text}: the file name is longer than {255 - WRITE_SUFFIX_ROOM} bytes")
        return text


def _one_line(error: BaseException) -> str:
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
    import h5py

    if not h5py.is_hdf5(path):
        raise ValueError("no HDF5 signature")


def _robomimic_hdf5(path: str) -> None:
    """An HDF5 file laid out as robomimic's datasets are: a ``data`` group of demos with the env's metadata."""
    import h5py

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
    """A robomimic config file: JSON whose algo_name robomimic knows, and whose keys its config of that algo has."""
    config = _json_value(path)
    if not isinstance(config, dict):
        raise ValueError("a robomimic config is a JSON object")
    algos = _robomimic_algos()
    if config.get("algo_name") not in algos:
        raise ValueError(f"algo_name {config.get('algo_name')!r} is not one of robomimic's: {', '.join(algos)}")
    from robomimic.config import config_factory

    base = config_factory(config["algo_name"])
    try:
        with base.values_unlocked():
            base.update(config)
    except (RuntimeError, KeyError, AttributeError) as error:
        raise ValueError(_one_line(error)) from None


CHECKPOINT_KEYS = ("algo_name", "config", "env_metadata", "shape_metadata", "model")


def _checkpoint(path: str) -> None:
    """A robomimic checkpoint: what robomimic's loader reads as a dict with the keys its tools use."""
    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()
    from robomimic.utils.file_utils import load_dict_from_checkpoint

    try:
        checkpoint = load_dict_from_checkpoint(path)
    except Exception as error:  # noqa: BLE001 - torch raises many kinds for a bad file; each is named
        raise ValueError(f"torch cannot read it: {type(error).__name__}: {_one_line(error)}") from None
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
output_video = OutputFile("video file")
output_folder = OutputFolder()
file_name = FileName()
text = Text()
boolean = Boolean()
ray_address = RayAddress()
demo_name = Text("a demo's name, e.g. demo_0")


# -- network ------------------------------------------------------------------------------------------------------- #


class Port(Integer):
    """A TCP port, 0 (any free one) to 65535."""

    def __init__(self):
        super().__init__(0, 65535, accepted="a TCP port in 0-65535")


class Host(Kind):
    """An address of this machine to serve on: a name or IP that resolves and can be bound."""

    accepted = "an address of this machine (127.0.0.1, 0.0.0.0, or one of its interfaces)"

    def __call__(self, text: str) -> str:
        try:
            infos = socket.getaddrinfo(text, None, type=socket.SOCK_STREAM)
        except (OSError, UnicodeError) as error:
            raise argparse.ArgumentTypeError(f"{text!r} is not an address ({_one_line(error)})") from None
        family, _, _, _, address = infos[0]
        with contextlib.closing(socket.socket(family, socket.SOCK_STREAM)) as probe:
            try:
                probe.bind((address[0], 0))
            except OSError as error:
                raise argparse.ArgumentTypeError(
                    f"{text!r} is not an address of this machine ({error.strerror}); accepted: {self.accepted}"
                ) from None
        return text


port = Port()
host = Host()


def check_port_free(host_name: str, number: int, option: str = "--vr-port") -> None:
    """Raises UsageError when ``number`` cannot be served on ``host_name`` now (in use by another program)."""
    if number == 0:
        return
    family = socket.getaddrinfo(host_name, None, type=socket.SOCK_STREAM)[0][0]
    with contextlib.closing(socket.socket(family, socket.SOCK_STREAM)) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host_name, number))
        except OSError as error:
            raise UsageError(
                f"{option} {number}: cannot serve on {host_name}:{number} ({error.strerror}); another program "
                "holds it: give another port, or 0 for any free one"
            ) from None


# -- environment keyword arguments --------------------------------------------------------------------------------- #


def _scoop_parameters() -> dict[str, inspect.Parameter]:
    from veragmil_suite.environments.scoop import ScoopGranular

    return {n: p for n, p in inspect.signature(ScoopGranular.__init__).parameters.items() if n != "self"}


class EnvKwargs(Kind):
    """
    A JSON object of robosuite.make keyword arguments for ScoopGranular: names from its signature, each value of
    its kind (a food, a robot, a count, a control rate...) or of its default's type. ``reserved`` maps the
    arguments the program sets itself to the option that sets them.
    """

    accepted = "a JSON object of ScoopGranular's robosuite.make keyword arguments"

    def __init__(self, reserved: dict[str, str] | None = None):
        self.reserved = dict(reserved or {})

    def __call__(self, text: str) -> dict:
        try:
            value = json.loads(text)
        except json.JSONDecodeError as error:
            raise argparse.ArgumentTypeError(f"not JSON: {error}") from None
        if not isinstance(value, dict):
            raise self.refuse(text)
        check_env_kwargs(value, self.reserved)
        return value


def check_env_kwargs(kwargs: dict, reserved: dict[str, str] | None = None) -> None:
    """Raises ArgumentTypeError naming the first keyword argument ScoopGranular would refuse, and what it takes."""
    parameters = _scoop_parameters()
    unknown = sorted(set(kwargs) - set(parameters))
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown ScoopGranular argument(s) {', '.join(unknown)}; accepted: {', '.join(parameters)}"
        )
    for name, option in (reserved or {}).items():
        if name in kwargs:
            raise argparse.ArgumentTypeError(f"{name} is set by {option}, not in the keyword arguments")
    for name, value in kwargs.items():
        try:
            _check_env_value(name, value, kwargs, parameters[name].default)
        except argparse.ArgumentTypeError as error:
            raise argparse.ArgumentTypeError(f"{name}: {error}") from None


def _check_env_value(name: str, value: Any, kwargs: dict, default: Any) -> None:
    if value is None and default is None:
        return
    kinds: dict[str, Kind] = {"food": food, "robots": robot, "horizon": count, "seed": seed, "pile_variants": count}
    kinds["physics"] = physics
    kinds.update(camera_heights=count, camera_widths=count)
    if name in kinds:
        items = value if name == "robots" and isinstance(value, list) else [value]
        for item in items:
            if isinstance(item, bool) or not isinstance(item, (str, int)):
                raise kinds[name].refuse(item)
            kinds[name](str(item))
        if name in ("horizon", "pile_variants", "camera_heights", "camera_widths") and not isinstance(value, int):
            raise kinds[name].refuse(value)
        return
    if name == "n_grains":
        if value is None:
            return
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise count.refuse(value)
        from veragmil_suite.environments.scoop import MAX_GRAINS_PER_DEFAULT
        from veragmil_suite.models.foods import DEFAULT_PHYSICS, FOODS, PHYSICS

        # the food's own limit, or without a food the largest (each food's is checked where it is known)
        foods = [FOODS[kwargs["food"]]] if kwargs.get("food") in FOODS else list(FOODS.values())
        named = kwargs.get("physics") if kwargs.get("physics") in PHYSICS else DEFAULT_PHYSICS
        spec = max(foods, key=lambda f: f.grain(named).default_grains)
        limit = MAX_GRAINS_PER_DEFAULT * spec.grain(named).default_grains
        if value > limit:
            what = spec.name if len(foods) == 1 else f"any food ({spec.name})"
            raise argparse.ArgumentTypeError(
                f"at most {limit} grains of {what}, {MAX_GRAINS_PER_DEFAULT}x its default, got {value}"
            )
        return
    if name in ("control_freq", "physics_timestep_s"):
        from veragmil_suite.models.scoop_task import PHYSICS_TIMESTEP_S, check_physics_timestep

        freq, step = kwargs.get("control_freq", 20), kwargs.get("physics_timestep_s", PHYSICS_TIMESTEP_S)
        if name == "control_freq":
            if isinstance(freq, bool) or not isinstance(freq, (int, float)):
                raise control_freq.refuse(freq)
            control_freq(str(freq), timestep_s=step if isinstance(step, (int, float)) else PHYSICS_TIMESTEP_S)
            return
        try:
            check_physics_timestep(step, freq if isinstance(freq, (int, float)) else 20)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return
    if name == "sleep_tolerance":
        from veragmil_suite.models.scoop_task import check_sleep_tolerance

        try:
            check_sleep_tolerance(value)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return
    if name == "camera_names":
        for item in value if isinstance(value, list) else [value]:
            if not isinstance(item, str):
                raise camera.refuse(item)
            camera(item)
        return
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise argparse.ArgumentTypeError(f"must be true or false, got {value!r}")
    elif isinstance(default, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise any_number.refuse(value)


# -- agents -------------------------------------------------------------------------------------------------------- #


class Agent(Kind):
    """An evaluated agent, ``[NAME=]SPEC`` (veragmil_suite.evaluation.agents.parse_agent_argument), a checkpoint
    read now."""

    @property
    def accepted(self) -> str:
        from veragmil_suite.evaluation.agents import SPEC_HELP

        return f"[NAME=]SPEC with SPEC {SPEC_HELP}"

    def __call__(self, text: str) -> str:
        from veragmil_suite.evaluation.agents import parse_agent_argument, parse_spec

        try:
            _, spec = parse_agent_argument(text)
            parsed = parse_spec(spec)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        if parsed.kind == "checkpoint":
            checkpoint(parsed.target)
        return text


agent = Agent()


# ---------------------------------------------------------------------------------------------------------------- #
# The parser                                                                                                       #
# ---------------------------------------------------------------------------------------------------------------- #


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written, defaults shown (where there is one), an option's old spellings left out."""

    def _get_help_string(self, action: argparse.Action) -> str:
        help = action.help or ""
        if "%(default)" in help or "default" in help or action.default in (None, False, argparse.SUPPRESS, []):
            return help
        default = action.default
        shown = " ".join(map(str, default)) if isinstance(default, (list, tuple)) else str(default)
        shown = shown.replace("%", "%%")
        return f"{help} (default: {shown})".strip()

    def _format_action_invocation(self, action: argparse.Action) -> str:
        hidden = getattr(action, "aliases", ())
        if hidden:
            action = copy.copy(action)
            action.option_strings = [s for s in action.option_strings if s not in hidden]
        return super()._format_action_invocation(action)


class Flatten(argparse.Action):
    """Stores the items of a ListOf option's values as one list."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, [item for value in values for item in value])


class _HeightWidth(argparse.Action):
    """An old ``--size H [W]`` option: sets camera_height and camera_width (W defaults to H)."""

    def __call__(self, parser, namespace, values, option_string=None):
        if len(values) > 2:
            parser.error(f"argument {option_string}: takes HEIGHT [WIDTH], got {len(values)} values")
        namespace.camera_height, namespace.camera_width = (list(values) * 2)[:2]


def add_image_size(parser: Parser, height: int, width: int, old: Iterable[str] = ()) -> None:
    """--camera-height and --camera-width (robomimic's names), in pixels; ``old`` spellings of a combined
    ``H [W]`` option stay accepted, hidden."""
    parser.add_argument("--camera-height", type=count, default=height, metavar="PX", help="image height, pixels")
    parser.add_argument("--camera-width", type=count, default=width, metavar="PX", help="image width, pixels")
    if old:
        parser.add_argument(*old, type=count, nargs="+", action=_HeightWidth, dest=argparse.SUPPRESS,
                            default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # fmt: skip


def option_strings(parser: argparse.ArgumentParser) -> set[str]:
    return {s for action in parser._actions for s in action.option_strings}


def respell(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with each long option spelled as ``parser`` knows it: --n-rollouts as --n_rollouts where the parser
    has the latter, and the reverse (up to a bare ``--``, after which nothing is an option)."""
    known = option_strings(parser)
    out = []
    for i, token in enumerate(argv):
        if token == "--":
            return out + list(argv[i:])
        if token.startswith("--") and len(token) > 2:
            name, eq, value = token.partition("=")
            if name not in known:
                for other in ("--" + name[2:].replace("_", "-"), "--" + name[2:].replace("-", "_")):
                    if other in known:
                        token = other + eq + value
                        break
        out.append(token)
    return out


def adopt(parser: argparse.ArgumentParser, prog: str) -> Parser:
    """An upstream script's parser (robomimic's) as one of ours: named ``prog``, each long option shown with dashes
    (--n-rollouts) and its own spelling (--n_rollouts) kept as a hidden alias, our help and spelling rule. Its
    abbreviations stay allowed, as upstream allows them."""
    parser.__class__ = Parser
    parser.prog = prog
    parser.formatter_class = HelpFormatter
    for action in parser._actions:
        dashed = [s[:2] + s[2:].replace("_", "-") if s.startswith("--") else s for s in action.option_strings]
        aliases = tuple(s for s in action.option_strings if s not in dashed)
        for name in dashed:
            parser._option_string_actions[name] = action
        action.option_strings = list(dict.fromkeys([*dashed, *aliases]))
        action.aliases = aliases
    return parser


class Parser(argparse.ArgumentParser):
    """
    The argparse parser of every console program: no abbreviated options (an abbreviation that is unique today is
    ambiguous after the next option), either spelling of an option (dashes or underscores), old spellings accepted
    but hidden (``aliases=``), and a ListOf option stored as one flat list.
    """

    def __init__(self, prog: str, description: str | None = None, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(prog=prog, description=description, allow_abbrev=False, **kwargs)

    def add_argument(self, *names: str, aliases: Iterable[str] = (), **kwargs) -> argparse.Action:
        aliases = tuple(aliases)
        kind = kwargs.get("type")
        if (
            isinstance(kind.item if isinstance(kind, ListOf) else kind, Choice)
            and kwargs.get("help") != argparse.SUPPRESS
        ):
            kwargs["help"] = f"{kwargs.get('help') or ''} (%(type)s)".strip()  # the names, listed when --help prints
        if isinstance(kind, ListOf) and kwargs.get("action") in (None, "store"):
            kwargs.setdefault("nargs", "+")
            kwargs["action"] = Flatten
        action = super().add_argument(*names, *aliases, **kwargs)
        action.aliases = aliases
        return action

    def add_input(self, dest: str, option: str, kind: Kind, many: bool = False, help: str | None = None) -> None:
        """An input given as a positional argument or as ``option`` (robomimic's --dataset), either way into
        ``dest``: one of the two is required, and not both."""
        metavar = dest.upper()
        self.add_argument(f"{dest}", nargs="*" if many else "?", type=kind, metavar=metavar, help=help)
        self.add_argument(
            option, dest=f"{dest}_option", nargs="+" if many else None, type=kind, metavar=metavar,
            help=f"the same as {metavar}",
        )  # fmt: skip
        self._inputs = [*getattr(self, "_inputs", []), (dest, option, many)]

    def parse_known_args(self, args=None, namespace=None):
        args = sys.argv[1:] if args is None else list(args)
        namespace, extras = super().parse_known_args(respell(self, args), namespace)
        for dest, option, many in getattr(self, "_inputs", []):
            given, flagged = getattr(namespace, dest, None), getattr(namespace, f"{dest}_option", None)
            if given and flagged:
                self.error(f"give {dest.upper()} or {option}, not both")
            if not given and not flagged:
                self.error(f"give {dest.upper()}{' (one or more)' if many else ''} or {option}")
            setattr(namespace, dest, given or flagged)
            delattr(namespace, f"{dest}_option")
        return namespace, extras


# ---------------------------------------------------------------------------------------------------------------- #
# Upstream scripts' parsers                                                                                        #
# ---------------------------------------------------------------------------------------------------------------- #


def main_block(module) -> object:
    """The compiled body of a script's ``if __name__ == "__main__":`` block (its argparse and its call)."""
    path = inspect.getsourcefile(module)
    with open(path) as f:
        tree = ast.parse(f.read(), filename=path)
    for node in tree.body:
        test = node.test if isinstance(node, ast.If) else None
        if (
            isinstance(test, ast.Compare)
            and isinstance(test.left, ast.Name)
            and test.left.id == "__name__"
            and isinstance(test.comparators[0], ast.Constant)
            and test.comparators[0].value == "__main__"
        ):
            return compile(ast.Module(body=node.body, type_ignores=[]), path, "exec")
    raise RuntimeError(f"{path} has no __main__ block to run")


class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser):
        self.parser = parser


@contextlib.contextmanager
def parse_args_answering(answer: Callable[[argparse.ArgumentParser], argparse.Namespace]):
    """Within: every ArgumentParser.parse_args returns ``answer(parser)`` (the script's own parser is built as
    robomimic wrote it, and what it parses is decided here)."""
    original = argparse.ArgumentParser.parse_args
    argparse.ArgumentParser.parse_args = lambda self, *args, **kwargs: answer(self)
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_args = original


def _raise_captured(parser: argparse.ArgumentParser) -> argparse.Namespace:
    raise _Captured(parser)


def script_parser(module) -> argparse.ArgumentParser:
    """The parser a script's ``if __name__ == "__main__":`` block builds (robosuite's and robomimic's scripts build
    theirs there), taken at its parse_args: nothing after that runs."""
    try:
        with parse_args_answering(_raise_captured):
            exec(main_block(module), dict(module.__dict__))
    except _Captured as captured:
        return captured.parser
    raise RuntimeError(f"{module.__name__}'s __main__ block parsed no arguments")


# ---------------------------------------------------------------------------------------------------------------- #
# The handler                                                                                                      #
# ---------------------------------------------------------------------------------------------------------------- #


def check_option(option: str, value: str, kind: Kind) -> Any:
    """``kind(value)`` for a value a program derives from its options; UsageError names ``option`` when refused."""
    try:
        return kind(value)
    except argparse.ArgumentTypeError as error:
        raise UsageError(f"{option}: {error}") from None


def _expected(error: BaseException) -> bool:
    if isinstance(error, UsageError):
        return True
    if isinstance(error, OSError):
        return error.filename is not None or error.errno in USER_ERRNOS
    return any(f"{c.__module__}.{c.__qualname__}" in EXPECTED_ERRORS for c in type(error).__mro__)


def error_line(error: BaseException) -> str:
    """An expected error as one line: an OSError as 'PATH: reason', anything else as its message."""
    if isinstance(error, OSError) and error.filename is not None and error.strerror:
        return f"{error.filename}: {error.strerror}"
    return _one_line(error)


def command(build_parser: Callable[[], argparse.ArgumentParser], interrupted: str = "interrupted"):
    """
    Makes ``run(args) -> int`` a console program's ``main(argv=None) -> int`` (the exit status, also for --help and
    a value argparse refused): parses ``argv`` with ``build_parser()`` (kept as ``main.build_parser`` for
    tests/test_cli.py), runs, and turns an expected error
    (UsageError, our dataset and Ray errors, an OSError about the user's files, disk or addresses) into one line on
    stderr and exit status 2, and Ctrl-C into one line (``interrupted``) and 130.
    """

    def decorate(run: Callable[[argparse.Namespace], int | None]) -> Callable[[list[str] | None], int]:
        @functools.wraps(run)
        def main(argv: list[str] | None = None) -> int:
            parser = build_parser()
            try:
                args = parser.parse_args(argv)
            except SystemExit as stop:  # argparse printed --help, or the bad value in one line
                return stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 2)
            try:
                return int(run(args) or 0)
            except KeyboardInterrupt:
                print(f"\n{parser.prog}: {interrupted}", file=sys.stderr)
                return 130
            except Exception as error:
                if not _expected(error):
                    raise
                print(f"{parser.prog}: {error_line(error)}", file=sys.stderr)
                return 2

        main.build_parser = build_parser
        return main

    return decorate
