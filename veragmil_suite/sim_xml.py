"""
A simulation that answers ``sim.model.get_xml()`` with its own model, whatever else the process compiled since.

robosuite's ``MjModel.get_xml`` calls MuJoCo's ``mj_saveLastXML``, which writes the *last XML parsed in the
process* (mj_loadXML, ``MjModel.from_xml_string``) with the given model's values copied in, and silently writes
that other model when the two differ: after a reset that settled a new pile (veragmil_suite.settling compiles a
model of its own), measured grain inertias, or made another environment, robosuite's DataCollectionWrapper stored
the wrong scene. The simulation here keeps the XML it was compiled from and parses it again before saving, so
MuJoCo's last XML is its own.
"""

from __future__ import annotations

import weakref

import mujoco


def keep_sim_xml(sim, xml: str) -> None:
    """
    Makes ``sim.model.get_xml()`` save ``sim``'s own model, and keeps ``xml`` (the MJCF ``sim`` was compiled from)
    as ``sim.source_xml`` (veragmil_suite.robomimic_obs.model_xml stores it in datasets).

    The re-parse costs one compile of the scene per call (a fraction of a second for a pile of hundreds of
    grains); robosuite asks once per episode.
    """
    model = weakref.ref(sim.model)  # the model keeps this function: no reference cycle through it
    save_last_xml = type(sim.model).get_xml

    def get_xml() -> str:
        mujoco.MjModel.from_xml_string(xml)  # MuJoCo's last parsed XML is this simulation's again
        return save_last_xml(model())

    sim.source_xml = xml
    sim.model.get_xml = get_xml
