"""
robomimic's view of a robosuite environment: its observation dictionary, its model XML, and reset_to.

The one conversion between robosuite's env and sim and what robomimic stores and reads. Datasets written by
veragmil_suite.data.recording and the environments robomimic drives through veragmil_suite.learning.robomimic_compat
both go through it, so recorded observations are exactly what policies see in rollouts and what robomimic's
dataset_states_to_obs extracts.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
import robosuite.macros
from robosuite.utils.binding_utils import MjSim

from veragmil_suite.learning.observation_sets import WRENCH_OBSERVATIONS
from veragmil_suite.utils.sim_xml import source_xml

if TYPE_CHECKING:
    from robosuite.environments.base import MujocoEnv

# observations of the torques applied in the step, not of the state alone (accelerations, the wrist's force-torque
# sensor): robomimic's dataset_states_to_obs, which sets each recorded state and reads it, cannot give them back
# (veragmil-robomimic-states-to-obs keeps the recorded values)
TORQUE_DEPENDENT_OBSERVATIONS = ("robot0_joint_acc", *WRENCH_OBSERVATIONS)


def observation(env: MujocoEnv, raw: dict | None = None, postprocess: bool = False) -> dict[str, np.ndarray]:
    """
    robomimic's observation dictionary from a robosuite environment's observations (``raw``, default: the env's
    current ones).

    Every enabled observable is kept under its own name (``robot0_eef_pos``, ``desired_pose``, ...), robosuite's
    concatenation ``object-state`` becomes ``object``, other ``*-state`` concatenations and empty observables (the
    spoon's gripper_qpos: robomimic's tensor reshapes fail on them) are left out, and camera images and depth are
    made upright (robosuite renders them upside down under its default "opengl" convention). Depth stays
    robosuite's normalized depth buffer, as policies see it in rollouts (metres:
    ``robosuite.utils.camera_utils.get_real_depth_map``). This is what datasets store; with postprocess=True, the
    rgb and depth keys robomimic's ObsUtils knows are prepared for the networks (channels first, scaled).
    """
    if raw is None:
        raw = env._get_observations(force_update=True)
    flip = robosuite.macros.IMAGE_CONVENTION == "opengl"
    obs = {}
    for key, value in raw.items():
        if key.endswith("-state"):
            if key == "object-state":
                obs["object"] = np.array(value, dtype=np.float64)
            continue
        value = np.array(value)
        if value.size == 0:
            continue
        observable = env._observables.get(key)
        if observable is not None and observable.modality == "image":
            obs[key] = np.ascontiguousarray(value[::-1]) if flip else value
        else:
            obs[key] = value.astype(np.float64)
    if postprocess:
        from robomimic.utils import obs_utils  # heavy: robomimic, imports torch

        modalities = obs_utils.OBS_KEYS_TO_MODALITIES or {}
        for key, value in obs.items():
            # dict.get: robomimic's mapping registers unknown keys as low_dim on [] lookups
            modality = dict.get(modalities, key)
            if modality in ("rgb", "depth"):
                obs[key] = obs_utils.process_obs(obs=value, obs_modality=modality)
    return obs


def observe(env: MujocoEnv) -> dict:
    """robosuite's observation of the simulation's current state, after a state was set by hand.

    The same observation ``env.step()`` returns for the state it reached (ScoopGranular observes at the end of
    each control step), so every recorded observation is a function of its recorded state: what robomimic's
    dataset_states_to_obs extracts, and what replays re-render.
    """
    env.sim.forward()
    return env._get_observations(force_update=True)


def remember_sim_xml() -> None:
    """Makes every robosuite MjSim compiled from now on keep the XML it was compiled from (see ``model_xml``)."""
    if getattr(MjSim.from_xml_string, "_keeps_source_xml", False):
        return
    compile_xml = MjSim.from_xml_string.__func__

    @functools.wraps(compile_xml)
    def from_xml_string(cls: type[MjSim], xml: str) -> MjSim:
        sim = compile_xml(cls, xml)
        sim.source_xml = xml
        return sim

    from_xml_string._keeps_source_xml = True
    MjSim.from_xml_string = classmethod(from_xml_string)


def model_xml(env: MujocoEnv) -> str:
    """
    The MJCF the env's simulation was compiled from (its XML processors, edit_model_xml among them, applied), as
    reset_to takes it and robomimic's get_state stores it.

    Not ``env.sim.model.get_xml()``: MuJoCo saves the *last XML it parsed* in the process, and a reset that settles
    a new pile or measures grain inertias (or another environment) parses models of its own. ScoopGranular's sims
    and any sim compiled after :func:`remember_sim_xml` know their own XML (``source_xml``, see
    veragmil_suite.utils.sim_xml); otherwise it is rebuilt from the env's model, which gives the same XML until a
    reset_to loads another.
    """
    xml = source_xml(env.sim)
    return xml if xml is not None else env.edit_model_xml(env.model.get_xml())


def reset_to(env: MujocoEnv, model_xml: str, state: np.ndarray) -> None:
    """robomimic's ``reset_to({"model": xml, "states": state})`` for a robosuite env: reload the XML, set the state
    (whose pose the first step holds: ScoopGranular.hold_restored_pose)."""
    env.reset_from_xml_string(env.edit_model_xml(model_xml))
    env.sim.reset()
    env.sim.set_state_from_flattened(np.asarray(state))
    env.sim.forward()


def reset_to_demo(env: MujocoEnv, model_xml: str, state: np.ndarray) -> dict:
    """reset_to for a recorded demo; returns robosuite's observation there.

    ScoopGranular finds which pile variant the demo's XML holds, so the metrics and object observations of a
    replay use that pile's grain sizes whatever the environment drew last.
    """
    reset_to(env, model_xml, state)
    return observe(env)


def restart_from_current_state(env: MujocoEnv) -> tuple[dict, str]:
    """Restart the env, right after ``env.reset()``, from its own model and state the way playback will.

    Stepping right after ``env.reset()`` and stepping after a playback's reset_to differ (the reload rebuilds the
    simulation and its controller): starting a recording here makes open-loop replay reproduce every state.

    Returns:
        2-tuple: robosuite's observation at the restarted state, and the model XML to store with the episode
    """
    xml = model_xml(env)
    reset_to(env, xml, env.sim.get_state().flatten())
    return observe(env), xml
