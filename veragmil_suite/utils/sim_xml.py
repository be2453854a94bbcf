"""
A simulation that answers ``sim.model.get_xml()`` with its own model, whatever else the process compiled since.

robosuite's ``MjModel.get_xml`` calls MuJoCo's ``mj_saveLastXML``, which writes the *last XML parsed in the
process* (mj_loadXML, ``MjModel.from_xml_string``) with the given model's values copied in, and silently writes
that other model when the two differ: after a reset that settled a new pile (veragmil_suite.environments.settling
compiles a model of its own), measured grain inertias, or made another environment, robosuite's DataCollectionWrapper
stored the wrong scene. The simulation here knows the XML it was compiled from and parses it again before saving, so
MuJoCo's last XML is its own.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING

import mujoco

if TYPE_CHECKING:
    from robosuite.utils.binding_utils import MjSim


def keep_sim_xml(sim: MjSim, compiled_xml: Callable[[], str]) -> None:
    """
    Makes ``sim.model.get_xml()`` save ``sim``'s own model. ``compiled_xml`` gives the MJCF ``sim`` was compiled
    from; it is called once, when first needed (see source_xml), unless the sim already keeps it
    (veragmil_suite.learning.robomimic_obs.remember_sim_xml): most simulations never need it.

    The re-parse costs one compile of the scene per get_xml (a fraction of a second for a pile of hundreds of
    grains); robosuite asks once per episode.
    """
    model = weakref.ref(sim.model)  # the model keeps get_xml: no reference cycle through it
    save_last_xml = type(sim.model).get_xml
    if getattr(sim, "source_xml", None) is None:
        sim.compiled_xml = _once(compiled_xml)

    def get_xml() -> str:
        mujoco.MjModel.from_xml_string(source_xml(sim))  # MuJoCo's last parsed XML is this simulation's again
        return save_last_xml(model())

    sim.model.get_xml = get_xml


def source_xml(sim: MjSim) -> str | None:
    """The MJCF ``sim`` was compiled from, when it is known (keep_sim_xml, robomimic_obs.remember_sim_xml)."""
    known = getattr(sim, "source_xml", None)
    if known is None and hasattr(sim, "compiled_xml"):
        known = sim.source_xml = sim.compiled_xml()
    return known


def _once(make: Callable[[], str]) -> Callable[[], str]:
    kept: list[str] = []

    def once() -> str:
        if not kept:
            kept.append(make())
        return kept[0]

    return once
