"""
The low-dim observation sets a policy can be trained on, by name: what veragmil-study's ``--obs-sets`` trains with
and what its tables name in every model's column.

ScoopGranular's task observables (modality "object", ``_setup_observables`` of veragmil_suite.environments.scoop)
are ``desired_pose`` (the post-scoop spoon pose, a fixed offset from the bowl's rim), ``bowl_pos`` (the centre of
the bowl's rim), ``spoon_to_desired_pos`` (the desired position less the spoon's), ``spoon_load`` (the grains in the
spoon and the grains spilled) and, with ``use_food_params_obs``, ``food_params`` (the food's grain size, friction,
restitution and density); robosuite concatenates them, in that order, into ``object``. Grain counts and the food's
physical parameters are privileged: no real robot observes them.

- ``no-load``: what a real robot could have: its end-effector pose (proprioception), the desired pose and the
  bowl's position (a camera finds the bowl) and the spoon's offset from the desired position (the same two combined).
- ``no-load-rot``: ``no-load`` and ``spoon_to_desired_rot``, the turn from the spoon's orientation to the post-scoop
  one (axis times angle, world frame; modality "goal", outside ``object``): the orientation twin of
  ``spoon_to_desired_pos``, in the frame of the OSC's rotation actions. Data recorded before it existed lacks it.
- ``no-load-size`` (the low-dim configs' keys): ``no-load`` and ``piece_size``, the largest piece's length and
  thickness (m; modality "goal"), which a camera over the bowl sees: how far a scoop may reach before large pieces go
  over the rim depends on it, and without it a policy trained on rice and pasta reaches as far in pasta as in rice.
  Data recorded before it existed lacks it.
- ``wrench``: ``no-load`` and the wrist force-torque sensor (``robot0_eef_force``, ``robot0_eef_torque``): the spoon's
  weight and its contacts with grains and bowl, the sense a real robot has of what the grain counts say. The sensor
  reads the torques applied in a step, not the state alone: ScoopGranular observes it only with
  ``use_wrench_obs``, and its data must be recorded, not extracted from states.
- ``object``: the end-effector pose and ``object``, grain counts included.
"""

from __future__ import annotations

# the observables robosuite concatenates into ``object`` (without use_food_params_obs), in order
OBJECT_OBSERVABLES = ("desired_pose", "bowl_pos", "spoon_to_desired_pos", "spoon_load")
# the task's observables outside ``object`` (modality "goal": added after datasets of ``object`` were recorded)
GOAL_OBSERVABLES = ("spoon_to_desired_rot", "piece_size")
# observations no real robot has: grain counts, the food's physical parameters, and ``object``, which holds the counts
PRIVILEGED_OBSERVATIONS = ("spoon_load", "food_params", "object")

WRENCH_OBSERVATIONS = ("robot0_eef_force", "robot0_eef_torque")
NO_LOAD = ("robot0_eef_pos", "robot0_eef_quat", "desired_pose", "bowl_pos", "spoon_to_desired_pos")
OBSERVATION_SETS: dict[str, tuple[str, ...]] = {
    "object": ("robot0_eef_pos", "robot0_eef_quat", "object"),
    "no-load": NO_LOAD,
    "no-load-rot": NO_LOAD + ("spoon_to_desired_rot",),
    "no-load-size": NO_LOAD + ("piece_size",),
    "wrench": NO_LOAD + WRENCH_OBSERVATIONS,
}
# the set of the low-dim configs in configs/json (tests/test_configs.py holds them to it): BC scored as well without
# grain counts as with them (results/grid_calibrated_noload/), and better with the piece size than without
# (results/grid_size_expert_bc/)
DEFAULT_OBSERVATION_SET = "no-load-size"
# the set every training run had before sets had names: its runs' folders carry no suffix, so those studies resume
UNNAMED_RUNS_OBSERVATION_SET = "object"


def check_observation_set(name: str) -> str:
    """``name`` if it is an observation set; a ValueError naming the accepted ones otherwise."""
    if name not in OBSERVATION_SETS:
        raise ValueError(f"unknown observation set {name!r}; accepted: {sorted(OBSERVATION_SETS)}")
    return name


def needs_wrench(names: list[str] | tuple[str, ...]) -> bool:
    """Whether any of the observation sets ``names`` reads the wrist sensor (its data: ScoopGranular's
    ``use_wrench_obs``)."""
    return any(set(OBSERVATION_SETS[check_observation_set(name)]) & set(WRENCH_OBSERVATIONS) for name in names)


def with_observation_set(config: dict, name: str) -> dict:
    """A robomimic config (a JSON dict, changed in place and returned) whose low-dim observations are the set's."""
    config["observation"]["modalities"]["obs"]["low_dim"] = list(OBSERVATION_SETS[check_observation_set(name)])
    return config
