"""Kinds of value an option takes: argparse types that refuse a bad value in one line naming the option, the value
and what is accepted (numbers, choices from the catalogs and registries, robots, cameras, controllers).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterable
from typing import Any

from robosuite.models.robots import XArm7

from veragmil_suite.controllers.scoop_config import ROBOSUITE_CONTROL_FREQ_HZ
from veragmil_suite.devices.expert import PROFILES
from veragmil_suite.environments.arguments import MAX_IMAGE_SIDE_PX, MIN_CONTROL_FREQ_HZ
from veragmil_suite.learning import robomimic_compat
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.learning.observation_sets import OBSERVATION_SETS
from veragmil_suite.models.arena import ScoopArena
from veragmil_suite.models.foods import FOODS, PHYSICS, TRAINING_FOODS, UNSEEN_FOODS
from veragmil_suite.models.humanoid import check_robot
from veragmil_suite.models.scoop_task import PHYSICS_TIMESTEP_S, check_physics_timestep
from veragmil_suite.utils.numbers import SEED_MAX


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
    """A finite number in [low, high] (an end left out where ``open_low`` / ``open_high``), or the word ``none``
    stands for, where given: None (a setting switched off)."""

    def __init__(
        self,
        low: float | None = None,
        high: float | None = None,
        open_low: bool = False,
        open_high: bool = False,
        accepted: str | None = None,
        none: str | None = None,
    ):
        self.low, self.high, self.open_low, self.open_high = low, high, open_low, open_high
        self.none = none
        if accepted is None:
            lo = "" if low is None else f"{'(' if open_low else '['}{low:g}"
            hi = "" if high is None else f"{high:g}{')' if open_high else ']'}"
            accepted = f"a finite number in {lo or '(-inf'}, {hi or 'inf)'}" + (f", or {none}" if none else "")
        self.accepted = accepted

    def __call__(self, text: str) -> float | None:
        if self.none is not None and str(text).strip().lower() == self.none:
            return None
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
    """One of a set of names (given, or produced by a function called at each use, so that a name registered later,
    such as an operator profile, is accepted)."""

    def __init__(self, what: str, values: Iterable[str] | Callable[[], Iterable[str]]):
        self.what = what
        self._values = values

    @property
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


count = Integer(1)  # episodes, demos, steps, pixels, processes
count_or_zero = Integer(0)  # a count that may be none
image_side = Integer(1, MAX_IMAGE_SIDE_PX, accepted=f"a size in pixels in [1, {MAX_IMAGE_SIDE_PX}]")
seed = Integer(0, SEED_MAX, accepted=f"a seed in [0, {SEED_MAX}]")  # numpy's range
fraction_below_one = Real(0.0, 1.0, open_high=True)  # a validation share: some demos must be left to train on
positive = Real(0.0, open_low=True)  # a scale, a frame rate, a time constant
non_negative = Real(0.0)  # a duration that may be zero
any_number = Real()


class ControlFreq(Kind):
    """A control rate (Hz) the task runs at the physics step: at least the task's MIN_CONTROL_FREQ_HZ, and a whole
    number of physics steps per control period."""

    @property
    def accepted(self) -> str:
        return f"a control rate in Hz of at least {MIN_CONTROL_FREQ_HZ:g}"

    def __call__(self, text: str, timestep_s: float | None = None) -> float:
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


class PhysicsTimestep(Kind):
    """The task's physics step in seconds, as a number (0.00625) or a fraction (1/160), that divides the control
    period of the task's default control rate (robosuite's 20 Hz) into whole steps."""

    accepted = "seconds as a positive number or fraction (e.g. 1/240) that divides the control period"

    def __call__(self, text: str) -> float:
        numerator, slash, denominator = str(text).strip().partition("/")
        try:
            value = float(numerator) / float(denominator) if slash else float(numerator)
        except (ValueError, ZeroDivisionError):
            raise self.refuse(text) from None
        if not 0 < value < math.inf:
            raise self.refuse(text)
        try:
            check_physics_timestep(value, ROBOSUITE_CONTROL_FREQ_HZ)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return value


physics_timestep = PhysicsTimestep()


class SolverOption(Kind):
    """``KEY=VALUE``, one MuJoCo <option> attribute of the task's pile: the solver's effort (a positive number) or
    its kind (a word), as a (key, value) pair."""

    NUMBERS = ("iterations", "ls_iterations", "tolerance", "ls_tolerance")
    WORDS = {"solver": ("CG", "Newton", "PGS"), "cone": ("elliptic", "pyramidal")}

    @property
    def accepted(self) -> str:
        words = ", ".join(f"{key}={'|'.join(values)}" for key, values in self.WORDS.items())
        return f"KEY=NUMBER with KEY one of {', '.join(self.NUMBERS)} and a positive NUMBER, or {words}"

    def __call__(self, text: str) -> tuple[str, str]:
        key, _, value = str(text).partition("=")
        key, value = key.strip(), value.strip()
        if key in self.WORDS:
            if value not in self.WORDS[key]:
                raise self.refuse(text)
            return key, value
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if key not in self.NUMBERS or not 0 < number < math.inf:
            raise self.refuse(text)
        return key, value


solver_option = SolverOption()
# a cap on control steps per second: below the slowest control rate a step would wait longer than a control period
frame_rate = Real(MIN_CONTROL_FREQ_HZ, accepted=f"at least {MIN_CONTROL_FREQ_HZ:g} control step per second")


def _foods() -> list[str]:
    return list(dict.fromkeys([*TRAINING_FOODS, *UNSEEN_FOODS, *FOODS]))


def _profiles() -> list[str]:
    return sorted(PROFILES)


def _algos() -> list[str]:
    return sorted(ALGORITHMS)


def _observation_sets() -> list[str]:
    return sorted(OBSERVATION_SETS)


def _physics() -> list[str]:
    return list(PHYSICS)


def robomimic_algos() -> list[str]:
    robomimic_compat.install()  # robomimic imports torchvision and mujoco_py, which the compatibility layer bridges
    from robomimic.config.base_config import REGISTERED_CONFIGS  # heavy: robomimic, imports torch

    return sorted(REGISTERED_CONFIGS)


food = Choice("food", _foods)
profile = Choice("operator profile", _profiles)
algo = Choice("algorithm", _algos)
observation_set = Choice("observation set", _observation_sets)
physics = Choice("physics", _physics)
robomimic_algo = Choice("robomimic algorithm", robomimic_algos)
environment = Choice("environment", ["ScoopGranular"])


class Robot(Kind):
    """A robosuite robot that can carry the spoon (veragmil_suite.models.humanoid.check_robot)."""

    accepted = "a robosuite robot that can hold the spoon (XArm7, Panda, ..., G1FixedLowerBody)"

    def __call__(self, text: str) -> str:
        try:
            check_robot(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        return text


robot = Robot()


def _cameras() -> list[str]:
    """The cameras of the task's arena and of its default robot (robosuite prefixes a robot's own with robot0_)."""
    arena = [c.get("name") for c in ScoopArena().worldbody.iter("camera")]
    return arena + list(XArm7().cameras)


camera = Choice("camera", _cameras)


text = Text()
boolean = Boolean()
ray_address = RayAddress()
demo_name = Text("a demo's name, e.g. demo_0")
