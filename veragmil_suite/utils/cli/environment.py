"""Kinds of value for the environment and the network: ScoopGranular keyword arguments (checked against its signature),
evaluated agents, hosts and ports.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import math
import socket
import urllib.parse
from pathlib import Path
from typing import Any

from robosuite.controllers import ALL_COMPOSITE_CONTROLLERS

from veragmil_suite.controllers.scoop_config import ARM_CONTROLLERS
from veragmil_suite.environments.arguments import MAX_GRAINS_PER_DEFAULT
from veragmil_suite.environments.scoop import ScoopGranular
from veragmil_suite.evaluation.agents import SPEC_HELP, parse_agent_argument, parse_spec
from veragmil_suite.models.foods import DEFAULT_PHYSICS, FOODS, PHYSICS
from veragmil_suite.models.scoop_task import PHYSICS_TIMESTEP_S, check_physics_timestep, check_sleep_tolerance
from veragmil_suite.utils.cli.files import checkpoint, json_file, one_line
from veragmil_suite.utils.cli.handler import UsageError
from veragmil_suite.utils.cli.kinds import (
    Integer,
    Kind,
    any_number,
    camera,
    control_freq,
    count,
    food,
    image_side,
    physics,
    robot,
    seed,
)


class Controller(Kind):
    """A controller collection can drive: OSC_POSE (the task's tuning), a robosuite composite controller (BASIC,
    ...) or a composite-controller JSON file, each with an OSC_POSE arm (every device and the expert send OSC_POSE
    deltas)."""

    accepted = "OSC_POSE, a robosuite composite controller (BASIC, ...) or a composite-controller JSON file"

    def __call__(self, text: str) -> str:
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
            raise argparse.ArgumentTypeError(f"{text!r} is not an address ({one_line(error)})") from None
        family, _, _, _, address = infos[0]
        with contextlib.closing(socket.socket(family, socket.SOCK_STREAM)) as probe:
            try:
                probe.bind((address[0], 0))
            except OSError as error:
                raise argparse.ArgumentTypeError(
                    f"{text!r} is not an address of this machine ({error.strerror}); accepted: {self.accepted}"
                ) from None
        return text


class Url(Kind):
    """A web page's address: http or https, a host, an optional port (the VR server's page)."""

    accepted = "a page's address, http(s)://HOST[:PORT]/"

    def __call__(self, text: str) -> str:
        try:
            parts = urllib.parse.urlsplit(str(text).strip())
            parts.port  # noqa: B018  (raises ValueError on a port out of range or not a number)
        except ValueError:
            raise self.refuse(text) from None
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise self.refuse(text)
        return text


port = Port()
host = Host()
url = Url()


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


def _scoop_parameters() -> dict[str, inspect.Parameter]:
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
    kinds.update(camera_heights=image_side, camera_widths=image_side)
    if name in kinds:
        # robots and the image sizes take a list too (one robot; a size per camera)
        listed = name in ("robots", "camera_heights", "camera_widths") and isinstance(value, list)
        items = value if listed else [value]
        if listed and not items:
            raise kinds[name].refuse(value)
        for item in items:
            if isinstance(item, bool) or not isinstance(item, (str, int)):
                raise kinds[name].refuse(item)
            kinds[name](str(item))
            if name in ("horizon", "pile_variants", "camera_heights", "camera_widths") and not isinstance(item, int):
                raise kinds[name].refuse(item)
        return
    if name == "n_grains":
        if value is None:
            return
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise count.refuse(value)
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


class Agent(Kind):
    """An evaluated agent, ``[NAME=]SPEC`` (veragmil_suite.evaluation.agents.parse_agent_argument), a checkpoint
    read now."""

    @property
    def accepted(self) -> str:
        return f"[NAME=]SPEC with SPEC {SPEC_HELP}"

    def __call__(self, text: str) -> str:
        try:
            _, spec = parse_agent_argument(text)
            parsed = parse_spec(spec)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
        if parsed.kind == "checkpoint":
            checkpoint(parsed.target)
        return text


agent = Agent()
