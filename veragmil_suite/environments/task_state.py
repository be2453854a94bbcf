"""ScoopGranular's task state: where the grains are, the scoop's stage, reward, success, info and observables."""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
import robosuite.utils.transform_utils as T
from robosuite.utils.observables import Observable, sensor

from veragmil_suite.environments.stages import SCOOP_STAGES
from veragmil_suite.environments.start_pose import POST_SCOOP_EEF_ROT, rotation_to_post_scoop
from veragmil_suite.models.humanoid import SPOON_ARM
from veragmil_suite.models.spoon_gripper import SPOON_SHAPE

if TYPE_CHECKING:
    from robosuite.utils.binding_utils import MjData

# what the success rule's spill limit is a fraction of: the volume lifted out of the bowl, or all the food in the
# bowl (the paper's "less than 5% of the total volume spilled" read literally)
SPILL_LIMIT_REFERENCES = ("scooped", "bowl")
# ScoopGranular's default; every episode scored before the choice existed was scored under it
DEFAULT_SPILL_LIMIT = "scooped"


def check_spill_limit(spill_limit_of: str) -> str:
    """ScoopGranular's spill_limit_of, checked (a ValueError names the accepted values)."""
    if spill_limit_of not in SPILL_LIMIT_REFERENCES:
        raise ValueError(f"spill_limit_of {spill_limit_of!r}; accepted: {', '.join(SPILL_LIMIT_REFERENCES)}")
    return spill_limit_of


M3_PER_CM3 = 1e-6

_INSTABILITY_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)


def instability_warnings(data: MjData) -> int:
    """How many times MuJoCo found non-finite or huge state and reset itself (it does so silently)."""
    return sum(data.warning[w].number for w in _INSTABILITY_WARNINGS)


class TaskStateMixin:
    """What ScoopGranular measures in a state: the grains in the bowl, in the spoon and spilled, the scoop's stage, its
    reward and success, and the task's observables."""

    def reward(self, action: np.ndarray | None = None) -> float:
        """
        Reward function for the task.

        Sparse un-normalized reward:

            - a discrete reward of 1.0 is provided on success

        Un-normalized summed components if using reward shaping (each in [0, 1], weighted to sum to at most 1):

            - Loading: 0.4 x the fraction of the minimum portion in the spoon
            - Carrying: 0.4 x loading x closeness of the spoon to the post-scoop position
            - Leveling: 0.1 x loading x how level the spoon is
            - Clean: 0.1 x (1 - spilled fraction)

        Note that the final reward is scaled by reward_scale.

        Args:
            action (np array): [NOT USED]

        Returns:
            float: reward value
        """
        if self._check_success():
            reward = 1.0
        elif self.reward_shaping:
            m = self._scoop_metrics()
            load = min(1.0, m["spoon_volume_m3"] / self.min_portion_m3)
            dist = np.linalg.norm(m["spoon_pos"] - self._desired_pos())
            reward = 0.4 * load + 0.4 * load * (1 - np.tanh(10.0 * dist))
            reward += 0.1 * load * (1 - min(1.0, m["spoon_tilt"] / (np.pi / 2)))
            reward += 0.1 * (1 - m["spill_fraction"])
            reward = min(reward, 0.99)
        else:
            reward = 0.0
        if self.reward_scale is not None:
            reward *= self.reward_scale
        return reward

    def _check_success(self):
        """
        Success: the spoon is held at the post-scoop pose (within position and tilt tolerances, slower than
        success_max_speed) carrying at least min_portion_cm3 of food, with spilled volume under
        max_spill_fraction of the volume scooped (spill_limit_of "scooped") or of the food in the bowl ("bowl").

        Returns:
            bool: True if the task succeeded
        """
        m = self._scoop_metrics()
        return bool(
            np.linalg.norm(m["spoon_pos"] - self._desired_pos()) <= self.success_pos_tolerance
            and m["spoon_tilt"] <= self.success_tilt_tolerance
            and m["spoon_speed"] <= self.success_max_speed
            and m["spoon_volume_m3"] >= self.min_portion_m3
            and self._spill_within_limit(m)
        )

    def _spill_within_limit(self, m: dict) -> bool:
        if self.spill_limit_of == "bowl":
            return m["spilled_volume_m3"] < self.max_spill_fraction * self.food_volume_m3
        return m["spill_fraction"] < self.max_spill_fraction

    def _rim_center(self) -> np.ndarray:
        """Centre of the bowl's rim in the world (the bowl may be nudged)."""
        pos = self.sim.data.body_xpos[self.bowl_body_id]
        mat = self.sim.data.body_xmat[self.bowl_body_id].reshape(3, 3)
        return pos + mat @ self.bowl.rim_offset

    def _desired_pos(self) -> np.ndarray:
        """Post-scoop position of the spoon: a fixed offset from the bowl's rim (a function of the state alone)."""
        return self._rim_center() + self.post_scoop_offset

    def _scoop_metrics(self) -> dict:
        """Where every grain is (bowl, spoon, spilled), computed once per simulation time."""
        data = self.sim.data
        stamp = (data.time, hash(data.qpos.tobytes()))  # hand-set states (tests, reset_to) change qpos, not time
        if self._metrics_time == stamp and self._metrics is not None:
            return self._metrics
        pos = data.body_xpos[self.grain_body_ids]
        rim = self._rim_center()
        bowl_axis = data.body_xmat[self.bowl_body_id].reshape(3, 3)[:, 2]
        rel = pos - rim
        radial = rel - np.outer(rel @ bowl_axis, bowl_axis)
        in_bowl = np.linalg.norm(radial, axis=1) <= min(self.bowl_shape.rim_semi_axes)

        spoon_pos = data.site_xpos[self.spoon_site_id]
        spoon_rot = data.site_xmat[self.spoon_site_id].reshape(3, 3)
        local = (pos - spoon_pos) @ spoon_rot
        margin = self.grain_radius_max
        in_spoon = SPOON_SHAPE.holds(local, margin=margin, above=3 * margin)
        spilled = ~in_bowl & ~in_spoon
        vol = self.grain_volumes_m3
        spoon_volume = float(vol[in_spoon].sum())
        spilled_volume = float(vol[spilled].sum())
        mass = self.grain_masses_kg
        lifted = float(vol[~in_bowl].sum()) + float(vol[in_spoon & in_bowl].sum())
        spoon_vel = np.zeros(6)
        mujoco.mj_objectVelocity(
            self.sim.model._model, data._data, mujoco.mjtObj.mjOBJ_SITE, self.spoon_site_id, spoon_vel, 0
        )
        self._metrics = dict(
            in_bowl=in_bowl,
            in_spoon=in_spoon,
            spilled=spilled,
            grains_in_spoon=int(in_spoon.sum()),
            grains_spilled=int(spilled.sum()),
            spoon_volume_m3=spoon_volume,
            spilled_volume_m3=spilled_volume,
            spoon_mass_kg=float(mass[in_spoon].sum()),
            spilled_mass_kg=float(mass[spilled].sum()),
            lifted_volume_m3=lifted,
            spill_fraction=spilled_volume / lifted if lifted > 0 else 0.0,
            spoon_pos=spoon_pos.copy(),
            spoon_tilt=float(np.arccos(np.clip(spoon_rot[2, 2], -1.0, 1.0))),
            spoon_speed=float(np.linalg.norm(spoon_vel[3:])),
        )
        self._metrics_time = stamp
        return self._metrics

    def _physics_check(self) -> str:
        """A description of a physics blow-up, or "" when the simulation is sound."""
        data = self.sim.data
        if instability_warnings(data) > self._badqacc_seen:
            return "MuJoCo reported unstable positions, velocities or accelerations and reset the simulation"
        if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
            return "non-finite positions or velocities"
        pos = data.body_xpos[self.grain_body_ids]
        far = np.linalg.norm(pos[:, :2] - self.table_offset[:2], axis=1) > 2.0
        if far.any() or (pos[:, 2] < -0.1).any():
            return f"{int(far.sum() + (pos[:, 2] < -0.1).sum())} grains left the workspace"
        return ""

    def scoop_info(self) -> dict:
        """The task's metrics now: grains in the spoon and spilled, spilled volume, completion time, success."""
        elapsed = self.timestep * self.control_timestep
        if self._physics_error:
            return dict(
                grains_in_spoon=0,
                grains_spilled=0,
                spilled_volume_cm3=0.0,
                spill_fraction=0.0,
                scooped_volume_cm3=0.0,
                spoon_mass_g=0.0,
                spilled_mass_g=0.0,
                completion_time_s=elapsed,
                success=False,
                stage=SCOOP_STAGES[0],
                physics_error=self._physics_error,
            )
        m = self._scoop_metrics()
        success = self._check_success()
        if success and self._success_time is None:
            self._success_time = elapsed
        return dict(
            grains_in_spoon=m["grains_in_spoon"],
            grains_spilled=m["grains_spilled"],
            spilled_volume_cm3=m["spilled_volume_m3"] / M3_PER_CM3,
            spill_fraction=m["spill_fraction"],
            scooped_volume_cm3=m["lifted_volume_m3"] / M3_PER_CM3,
            spoon_volume_cm3=m["spoon_volume_m3"] / M3_PER_CM3,
            spoon_mass_g=1000.0 * m["spoon_mass_kg"],
            spilled_mass_g=1000.0 * m["spilled_mass_kg"],
            completion_time_s=self._success_time if self._success_time is not None else elapsed,
            success=success,
            stage=self.scoop_stage(),
            physics_error="",
        )

    def scoop_stage(self) -> str:
        """
        The furthest stage of SCOOP_STAGES this state shows, short of "held" (success held over time, which the
        episode loop decides): the spoon at the post-scoop pose (position and tilt within the success
        tolerances) carrying the minimum portion; that portion lifted clear of the rim (every grain in the
        spoon above the rim by a grain's radius); the minimum portion in the spoon; the spoon touching a grain.
        """
        m = self._scoop_metrics()
        loaded = m["spoon_volume_m3"] >= self.min_portion_m3
        if loaded:
            at_pose = (
                np.linalg.norm(m["spoon_pos"] - self._desired_pos()) <= self.success_pos_tolerance
                and m["spoon_tilt"] <= self.success_tilt_tolerance
            )
            if at_pose:
                return SCOOP_STAGES[4]
            data = self.sim.data
            bowl_axis = data.body_xmat[self.bowl_body_id].reshape(3, 3)[:, 2]
            heights = (data.body_xpos[self.grain_body_ids[m["in_spoon"]]] - self._rim_center()) @ bowl_axis
            return SCOOP_STAGES[3] if heights.min() > self.grain_radius_max else SCOOP_STAGES[2]
        return SCOOP_STAGES[1] if self._spoon_touches_grain() else SCOOP_STAGES[0]

    def _spoon_touches_grain(self) -> bool:
        """Whether a contact of the last collision pass joins a spoon geom and a grain."""
        data = self.sim.data._data
        if data.ncon == 0:
            return False
        geoms = data.contact.geom[: data.ncon]
        spoon = np.isin(geoms, self.spoon_geom_ids)
        grain = np.isin(geoms, self.grain_geom_ids)
        return bool(((spoon[:, 0] & grain[:, 1]) | (spoon[:, 1] & grain[:, 0])).any())

    def _setup_observables(self):
        """
        Sets up observables to be used for this environment. Creates object-based observables if enabled

        Returns:
            OrderedDict: Dictionary mapping observable names to its corresponding Observable object
        """
        observables = super()._setup_observables()

        robot = self.robots[0]
        if len(robot.arms) > 1:
            # a two-armed robot's spoon arm under the single-arm names, so the expert, policies and robomimic
            # configs read the spoon's pose under the same keys on every robot (robosuite adds right_/left_)
            pf = robot.robot_model.naming_prefix
            for name in ("eef_pos", "eef_quat", "eef_quat_site"):
                source = observables[f"{pf}{SPOON_ARM}_{name}"]
                observables[f"{pf}{name}"] = Observable(
                    name=f"{pf}{name}", sensor=source._sensor, sampling_rate=self.control_freq
                )
        if self.use_wrench_obs:
            observables.update(self._wrist_wrench_observables())

        if self.use_object_obs:
            modality = "object"

            @sensor(modality=modality)
            def desired_pose(obs_cache: dict | None) -> np.ndarray:
                pos = self._desired_pos()
                return np.concatenate([pos, T.mat2quat(POST_SCOOP_EEF_ROT)])

            @sensor(modality=modality)
            def bowl_pos(obs_cache: dict | None) -> np.ndarray:
                return self._rim_center()

            @sensor(modality=modality)
            def spoon_to_desired_pos(obs_cache: dict | None) -> np.ndarray:
                return self._desired_pos() - self.sim.data.site_xpos[self.eef_site_id]

            @sensor(modality=modality)
            def spoon_load(obs_cache: dict | None) -> np.ndarray:
                # grains in the spoon, grains spilled (a vector: robosuite squeezes one-element observations)
                m = self._scoop_metrics()
                return np.array([m["grains_in_spoon"], m["grains_spilled"]], dtype=float)

            sensors = [desired_pose, bowl_pos, spoon_to_desired_pos, spoon_load]

            if self.use_food_params_obs:

                @sensor(modality=modality)
                def food_params(obs_cache: dict | None) -> np.ndarray:
                    g = self.grain
                    return np.array([g.mean_size_m, g.friction, g.restitution, g.density_kg_m3 / 1000.0])

                sensors.append(food_params)

            for s in sensors:
                observables[s.__name__] = Observable(name=s.__name__, sensor=s, sampling_rate=self.control_freq)

            # the orientation twin of spoon_to_desired_pos, in a modality of its own so that ``object`` (which
            # datasets and checkpoints of the "object" set hold) keeps its layout
            @sensor(modality="goal")
            def spoon_to_desired_rot(obs_cache: dict | None) -> np.ndarray:
                return rotation_to_post_scoop(self.sim.data.site_xmat[self.eef_site_id])

            # the food's piece size, which a camera over the bowl sees (its identity and physics stay unobserved):
            # where a scoop can reach before large pieces go over the rim depends on it
            @sensor(modality="goal")
            def piece_size(obs_cache: dict | None) -> np.ndarray:
                return self.piece_size_m.copy()

            for s in (spoon_to_desired_rot, piece_size):
                observables[s.__name__] = Observable(name=s.__name__, sensor=s, sampling_rate=self.control_freq)

        return observables

    def _wrist_wrench_observables(self) -> dict[str, Observable]:
        """
        The spoon's wrist force-torque sensor (the gripper's ``force_ee`` and ``torque_ee`` at its ``ft_frame``,
        in that frame; N and N m): what a wrist F/T sensor, an option of the xArm7 and the usual sense of feeding
        robots, reads. It holds the spoon's weight and every contact the spoon makes, grains and bowl included.
        Their own modality keeps robosuite's ``robot0_proprio-state`` as it was.
        """
        robot = self.robots[0]
        pf = robot.robot_model.naming_prefix
        modality = f"{pf}wrench"

        @sensor(modality=modality)
        def eef_force(obs_cache: dict | None) -> np.ndarray:
            return np.array(robot.ee_force[SPOON_ARM])

        @sensor(modality=modality)
        def eef_torque(obs_cache: dict | None) -> np.ndarray:
            return np.array(robot.ee_torque[SPOON_ARM])

        return {
            f"{pf}{s.__name__}": Observable(name=f"{pf}{s.__name__}", sensor=s, sampling_rate=self.control_freq)
            for s in (eef_force, eef_torque)
        }

    def _update_observables(self, force=False):
        """
        Samples observables once per control step, at its end (see _get_observations).

        robosuite samples them inside the substep loop, where float time sums (12 x 1/240 s falls just short of
        1/20 s) move the sample to the second substep of the period: step() would return an observation almost a
        control step old, and cameras would render twice per step.
        """
        if force:
            super()._update_observables(force=True)

    def _get_observations(self, force_update=False):
        """Observations of the state reached, so an observation is a function of the recorded state."""
        return super()._get_observations(force_update=True)
