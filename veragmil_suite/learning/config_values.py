"""The values a robomimic config may hold, checked before a training starts, and the config a training builds of them.

robomimic's ``Config.update`` checks a config's keys, not its values: a batch size of ``"abc"`` or a sequence length
of 0 reach torch after the dataset has loaded (a TypeError, an AssertionError), and a negative epoch count trains
nothing and reports success. Each value is checked against the kind of robomimic's default for its key, and the
counts a training cannot run without against their ranges.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from veragmil_suite.utils.numbers import is_number, is_whole

if TYPE_CHECKING:
    from robomimic.config.config import Config


@dataclass(frozen=True)
class Bound:
    """A number a key must hold: ``whole`` or real, at least ``low`` (or above it when ``strict``), at most ``high``,
    ``None`` allowed where robomimic reads it as "off" or "a full pass"."""

    low: float
    whole: bool = True
    strict: bool = False
    nullable: bool = False
    high: float | None = None

    def accepts(self, value: Any) -> bool:
        if value is None:
            return self.nullable
        if not (is_whole(value) if self.whole else is_number(value)):
            return False
        if self.high is not None and value > self.high:
            return False
        return value > self.low if self.strict else value >= self.low

    def describe(self) -> str:
        kind = "a whole number" if self.whole else "a finite number"
        text = f"{kind} {'above' if self.strict else 'of at least'} {_number(self.low)}"
        if self.high is not None:
            text += f" and at most {_number(self.high)}"
        return text + (", or null" if self.nullable else "")


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


_COUNT = Bound(1)
_COUNT_OR_NULL = Bound(1, nullable=True)
_PERIOD_OR_NULL = Bound(0, whole=False, strict=True, nullable=True)
_RATE = Bound(0, whole=False, strict=True)

# dotted keys (fnmatch patterns) whose numbers robomimic's training needs in range
BOUNDS: dict[str, Bound] = {
    "train.num_epochs": _COUNT,
    "train.batch_size": _COUNT,
    "train.seq_length": _COUNT,
    "train.frame_stack": _COUNT,
    "train.num_data_workers": Bound(0),
    "train.seed": Bound(0, high=2**32 - 1),  # numpy's seeds
    "experiment.epoch_every_n_steps": _COUNT_OR_NULL,
    "experiment.validation_epoch_every_n_steps": _COUNT_OR_NULL,
    "experiment.rollout.n": _COUNT,
    "experiment.rollout.horizon": _COUNT,
    "experiment.rollout.rate": _COUNT,
    "experiment.rollout.warmstart": Bound(0),
    "experiment.save.every_n_epochs": _COUNT_OR_NULL,
    "experiment.save.every_n_seconds": _PERIOD_OR_NULL,
    "experiment.video_skip": _COUNT,
    "algo.optim_params.*.learning_rate.initial": _RATE,
    "algo.rnn.horizon": _COUNT,
    "algo.rnn.hidden_dim": _COUNT,
    "algo.rnn.num_layers": _COUNT,
    "algo.gmm.num_modes": _COUNT,
    "algo.horizon.*_horizon": _COUNT,
    "algo.ddpm.num_train_timesteps": _COUNT,
    "algo.ddpm.num_inference_timesteps": _COUNT,
    "algo.ddim.num_train_timesteps": _COUNT,
    "algo.ddim.num_inference_timesteps": _COUNT,
}


# keys whose robomimic default is None but whose values have one kind, by an example of it
OPEN_DEFAULTS: dict[str, Any] = {
    "train.data": "",
    "train.hdf5_filter_key": "",
    "train.hdf5_validation_filter_key": "",
    "train.goal_mode": "",
    "experiment.env": "",
    "experiment.additional_envs": [],
}


def _kind_of(default: Any) -> tuple[str, Any] | None:
    """What a value must be where robomimic's default is ``default``: a name for messages and a test; None where any
    value may stand (robomimic's default None, whose kind it leaves open)."""
    if isinstance(default, bool):
        return "true or false", lambda v: isinstance(v, bool)
    if isinstance(default, int):
        return "a whole number", is_whole
    if isinstance(default, float):
        return "a finite number", is_number
    if isinstance(default, str):
        return "a string", lambda v: isinstance(v, str)
    if isinstance(default, (list, tuple)):
        return "a list", lambda v: isinstance(v, (list, tuple))
    return None


def leaves(values: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """Each value of a nested config under its dotted key (``train.batch_size``)."""
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            yield from leaves(value, f"{name}.")
        else:
            yield name, value


def _lookup(values: Mapping[str, Any], name: str) -> tuple[bool, Any]:
    node: Any = values
    for part in name.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return False, None
        node = node[part]
    return True, node


def value_problem(config: Mapping[str, Any], defaults: Mapping[str, Any]) -> str | None:
    """The first value of ``config`` (a robomimic config as JSON gives it) that robomimic cannot train with, named
    with what its key accepts; None when every value can stand. ``defaults`` is robomimic's config of the same algo
    as a dict. A value may be null (robomimic's "off") except where a bound says otherwise."""
    for name, value in leaves(config):
        bound = next((b for pattern, b in BOUNDS.items() if fnmatch.fnmatchcase(name, pattern)), None)
        if bound is not None:
            if not bound.accepts(value):
                return f"{name} is {value!r}: it must be {bound.describe()}"
            continue
        if name in OPEN_DEFAULTS:
            kind, reason = _kind_of(OPEN_DEFAULTS[name]), " or null"
        else:
            known, default = _lookup(defaults, name)
            kind, reason = (_kind_of(default) if known else None), f", as robomimic's default {default!r} is"
        if kind is not None and value is not None and not kind[1](value):
            return f"{name} is {value!r}: it must be {kind[0]}{reason}"
    return None


def build_config(values: Mapping[str, Any]) -> Config:
    """robomimic's config of ``values``' algo_name with ``values`` written over its defaults, as robomimic's train.py
    builds it (robomimic raises on a key its config lacks)."""
    from robomimic.config import config_factory  # heavy: robomimic, imports torch

    config = config_factory(values["algo_name"])
    with config.values_unlocked():
        config.update(values)
    return config
