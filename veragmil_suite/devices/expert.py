"""A scripted scooping demonstrator for ScoopGranular, with operator profiles, so datasets need no human.

The expert is closed-loop on the spoon's pose: every step it reads the end-effector pose and the bowl's rim from
the observation and drives the spoon toward the current phase's waypoint, placed relative to the bowl wherever it
stands. Phases: approach above the near side of the pile, dip into it at an angle, drag through it toward the far
wall, level the spoon so its bowl holds the load, lift clear of the rim, carry to the post-scoop (desired) pose,
hold there.

Operator profiles set speed and noise. The ``spacemouse`` profile imitates 3D-mouse teleoperation (one axis at a
time, coarse and jerky input); its data is scripted data all the same and is labelled so.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import robosuite.utils.transform_utils as T

from veragmil_suite.controllers.scoop_config import osc_speed_per_offset
from veragmil_suite.environments.start_pose import POST_SCOOP_EEF_ROT, PRE_SCOOP_EEF_ROT
from veragmil_suite.utils.kinematics import align_heading, turn_to
from veragmil_suite.utils.registry import Registry

# While lifting and carrying, the spoon's tip is raised a little past level, as people do, so the load rests against
# the back of the spoon's bowl instead of sliding off its tip.
TIP_BACK = T.quat2mat(T.axisangle2quat(np.array([0.0, -np.deg2rad(10.0), 0.0])))


@dataclass(frozen=True)
class OperatorProfile:
    """How the scripted operator moves.

    Attributes:
        name: label stored with the data.
        speed: scales every phase's translation and rotation speed.
        pos_noise: std of the smooth noise added to translation commands (m/s).
        rot_noise: std of the smooth noise added to rotation commands (rad/s).
        noise_time_s: correlation time of that noise (a hand's drift, not white jitter).
        plan_jitter_m: per-episode random offset of the dip and drag waypoints (no two scoops alike).
        one_axis: move along one world axis (or rotate about one) at a time, as a 3D-mouse user does.
        input_levels: snap each command to this many deflection levels per direction (0: continuous).
        release_prob: per-step chance that the operator lets go of the input for a moment (jerky motion).
        max_accel: translation acceleration limit (m/s^2); a 3D mouse has none worth the name.
        max_hold_s: longest the spoon is held at the post-scoop pose before the expert gives up (an episode normally
            ends sooner, once success has held for a moment).
        turn_drift_m: one-axis operators only: a turn stops for a translation once the spoon has drifted this far
            (m) from its waypoint (0: never). A delta-pose controller anchors each step at the pose reached, so a
            turn with no translation input lets the spoon wander, and a turn about the wrist drags the spoon's rim
            2-4 mm per degree through the pile.
        waypoint_tol_scale: phases count as reached within this multiple of their position and angle tolerances:
            coarse one-axis input settles a few millimetres off, where the expert's tolerances would time out.
        phase_time_scale: a phase is given up on (and the next begun) after this multiple of its time limit: turning
            one axis at a time, with corrections in between, takes longer than the expert's combined motion.
        let_go_tol_m: at the post-scoop pose, the operator takes the hand off the input once the spoon is this close
            (m) (0: never): coarse nudges there move the spoon faster than a held spoon moves.
        injected_noise: std of the noise added to the action executed (a fraction of full scale per axis, an
            Ornstein-Uhlenbeck process with correlation time injected_noise_time_s), while the action recorded is
            the operator's own for the state reached: noise injection (DART), so the data shows how to recover from
            the small errors a learned policy makes. 0: the executed action is the recorded one.
        injected_noise_time_s: correlation time of the injected noise (s).
    """

    name: str
    speed: float = 1.0
    pos_noise: float = 0.0
    rot_noise: float = 0.0
    noise_time_s: float = 0.4
    plan_jitter_m: float = 0.002
    one_axis: bool = False
    input_levels: int = 0
    release_prob: float = 0.0
    max_accel: float = 0.6
    max_hold_s: float = 3.0
    turn_drift_m: float = 0.0
    waypoint_tol_scale: float = 1.0
    phase_time_scale: float = 1.0
    let_go_tol_m: float = 0.0
    injected_noise: float = 0.0
    injected_noise_time_s: float = 0.3


PROFILES: Registry[OperatorProfile] = Registry("operator profile", OperatorProfile)
# --profile, veragmil-study's --profiles and the expert:<profile> agents take every registered profile
register_profile = PROFILES.register


@register_profile
def expert() -> OperatorProfile:
    """The scripted expert: smooth, noise-free, at the plan's speeds."""
    return OperatorProfile("expert")


@register_profile
def careful() -> OperatorProfile:
    """A slower, steadier hand than the expert's."""
    return OperatorProfile("careful", speed=0.7, pos_noise=0.002, rot_noise=0.01)


@register_profile
def hasty() -> OperatorProfile:
    """A faster, rougher hand, with twice the expert's waypoint jitter and acceleration."""
    return OperatorProfile("hasty", speed=1.4, pos_noise=0.006, rot_noise=0.03, plan_jitter_m=0.004, max_accel=1.2)


@register_profile
def noisy() -> OperatorProfile:
    """The expert's speed with a drifting hand."""
    return OperatorProfile("noisy", pos_noise=0.008, rot_noise=0.04, plan_jitter_m=0.004)


@register_profile
def expert_dart() -> OperatorProfile:
    """The expert executing noisy actions while its own are recorded (noise injection, DART).

    MuJoCo 3.8.1, stiff OSC_POSE, 10 seeds per training food: at 0.05 it succeeds 80-100% (pasta 80%, the expert
    90%), 2 s slower; at 0.1 it spills on the carry and cannot hold still (pasta 12%, buckwheat 38%), even with the
    hold noise-free.
    """
    return OperatorProfile("expert-dart", injected_noise=0.05)


@register_profile
def spacemouse() -> OperatorProfile:
    """3D-mouse teleoperation: one axis at a time, four deflection levels, jerky input (see OperatorProfile)."""
    return OperatorProfile(
        "spacemouse",
        speed=1.6,
        pos_noise=0.004,
        rot_noise=0.02,
        plan_jitter_m=0.004,
        one_axis=True,
        input_levels=4,
        release_prob=0.04,
        max_accel=10.0,
        max_hold_s=5.0,
        turn_drift_m=0.006,
        waypoint_tol_scale=2.0,
        phase_time_scale=1.5,
        let_go_tol_m=0.01,
    )


@dataclass(frozen=True)
class Phase:
    """One leg of the scoop: a waypoint (relative to the bowl, see ScriptedScooper._waypoint) and how to reach it."""

    name: str
    speed: float  # m/s
    turn_speed: float  # rad/s
    pos_tol: float  # m
    rot_tol: float  # rad
    max_time_s: float


PHASES = (
    Phase("approach", speed=0.10, turn_speed=0.6, pos_tol=0.006, rot_tol=0.05, max_time_s=3.0),
    Phase("dip", speed=0.04, turn_speed=0.6, pos_tol=0.004, rot_tol=0.05, max_time_s=2.0),
    Phase("drag", speed=0.03, turn_speed=0.6, pos_tol=0.004, rot_tol=0.05, max_time_s=2.5),
    Phase("level", speed=0.02, turn_speed=0.4, pos_tol=0.004, rot_tol=0.04, max_time_s=4.0),
    Phase("lift", speed=0.03, turn_speed=0.3, pos_tol=0.006, rot_tol=0.05, max_time_s=3.0),
    Phase("carry", speed=0.06, turn_speed=0.3, pos_tol=0.008, rot_tol=0.05, max_time_s=5.0),
    Phase("hold", speed=0.03, turn_speed=0.2, pos_tol=0.0, rot_tol=0.0, max_time_s=np.inf),
)
# the speed toward a waypoint falls off as this rate (1/s) times the remaining distance: no overshoot
APPROACH_RATE = 4.0
# one-axis (3D-mouse) operator: 0.1 rad of orientation error weighs like 1 cm of position error when picking the axis
ONE_AXIS_WEIGHTS = np.array([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])
# a one-axis operator correcting drift gives the turn back after this long (s), so a spoon stalled in the pile
# cannot keep the turn from ever happening
DRIFT_CORRECTION_MAX_S = 0.5
# ...and corrects down to this fraction of turn_drift_m before turning on
DRIFT_RESUME_FRACTION = 0.5
# coarse input: the largest deflection, in action units, split into ``input_levels`` steps
QUANTIZE_FULL_SCALE = 0.6


@dataclass(frozen=True)
class ScoopPlan:
    """Where the phases aim the spoon's rim centre, relative to the bowl (m): x from the rim's centre (+x away from
    the robot), z above the bowl's floor (approach: above the rim)."""

    approach_dz: float = 0.01
    dip_dx: float = -0.005  # from the floor's edge on the near side
    # a waypoint the spoon can reach: at 0.02 the spoon met the bowl 4-6 mm short on every food and the dip ended
    # by its time limit, a switch no observation shows (a cloned policy kept pushing there)
    dip_dz: float = 0.024
    drag_dx: float = -0.005
    drag_dz: float = 0.017
    # turning level while moving on scoops the pile into the spoon; large pieces (pasta) would be pushed over the far
    # rim, so the spoon reaches less far the larger the food's pieces (by this many piece radii)
    level_dx: float = 0.012
    level_dx_per_radius: float = -1.2
    level_dz: float = 0.02
    lift_dz: float = 0.04  # above the rim


SCOOP_PLAN = ScoopPlan()
# A humanoid levels the spoon by forearm roll (veragmil_suite.models.humanoid), which swings the spoon's bowl forward
# through the pile: its level waypoint stays twice as many piece radii short, or a long pasta piece goes over the far
# rim
HUMANOID_SCOOP_PLAN = replace(SCOOP_PLAN, level_dx_per_radius=2 * SCOOP_PLAN.level_dx_per_radius)


def get_profile(profile: str | OperatorProfile) -> OperatorProfile:
    """A profile by name (PROFILES) or the profile itself; a ValueError names the accepted ones."""
    if isinstance(profile, OperatorProfile):
        return profile
    if profile not in PROFILES:
        raise ValueError(f"Unknown operator profile {profile!r}; accepted profiles: {', '.join(PROFILES)}")
    return PROFILES[profile]


class ScriptedScooper:
    """
    Scripted scooping expert for ScoopGranular with an OSC_POSE (delta) arm controller.

    Args:
        env (ScoopGranular): the environment (read for the bowl's shape, the control rate and the controller frame)
        profile (str or OperatorProfile): operator profile (PROFILES) for speed and noise
        seed (None or int): seed of the profile's noise and of each episode's plan jitter

    Raises:
        ValueError: [Unknown profile, or an arm controller that does not take delta poses]
    """

    def __init__(self, env, profile: str | OperatorProfile = "expert", seed: int | None = None):
        self.env = env
        self.profile = get_profile(profile)
        self.rng = np.random.default_rng(seed)
        robot = env.robots[0]
        self.arm = robot.arms[0]
        self.controller = robot.part_controllers[self.arm]
        if getattr(self.controller, "input_type", None) != "delta" or self.controller.name != "OSC_POSE":
            raise ValueError(
                f"the scripted expert drives an OSC_POSE controller with delta input, not {self.controller.name} "
                f"({getattr(self.controller, 'input_type', '?')} input)"
            )
        self.dt = 1.0 / env.control_freq
        # action units: a command of 1 moves the goal by output_max (m, rad) per control step
        self.action_scale = np.asarray(self.controller.output_max, dtype=float)
        # axes the controller does not drive (zero stiffness): a five-joint arm's heading
        # (veragmil_suite.models.humanoid)
        kp = np.broadcast_to(np.asarray(self.controller.kp, dtype=float), (6,))
        self.driven = kp > 0
        self.free_heading = not self.driven[5]
        self.plan = SCOOP_PLAN if env.humanoid is None else HUMANOID_SCOOP_PLAN
        speed = osc_speed_per_offset(
            np.where(self.driven, kp, 1.0), np.where(self.driven, self.controller.kd, 1.0), self.dt
        )
        self.speed_to_offset = np.where(self.driven, 1.0 / speed, 0.0)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode: first phase, fresh noise, a new random plan (drawn from ``seed`` when given)."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        # the size of the food's pieces, as an operator sees it (and the piece_size observation): how far a scoop
        # may push them (read per episode: a reset may draw another pile variant)
        self.piece_radius = self.env.grain_radius_max
        self.phase_index = 0
        self.phase_steps = 0
        self.hold_steps = 0
        self.noise = np.zeros(6)
        self.injected = np.zeros(6)
        self.last_vel = np.zeros(3)
        self.axis = None
        self.drift_steps = 0
        self.drift_accepted = 0.0
        j = self.profile.plan_jitter_m
        self.jitter = dict(
            y=self.rng.uniform(-j, j),
            dip_x=self.rng.uniform(-j, j),
            dip_z=self.rng.uniform(-j / 2, j / 2),
            drag_x=self.rng.uniform(-j, j),
        )

    @property
    def phase(self) -> str:
        return PHASES[self.phase_index].name

    @property
    def done(self) -> bool:
        """True once the spoon has been held at the post-scoop pose for the profile's longest hold."""
        return self.phase == "hold" and self.hold_steps * self.dt >= self.profile.max_hold_s

    def act(self, obs: dict) -> np.ndarray:
        """The action (6-D OSC_POSE delta in [-1, 1]) for observation ``obs``; advances the phase when reached."""
        eef_pos = np.asarray(obs["robot0_eef_pos"], dtype=float)
        eef_rot = T.quat2mat(np.asarray(obs["robot0_eef_quat_site"], dtype=float))
        phase = PHASES[self.phase_index]
        target_pos, target_rot = self._waypoint(phase.name, obs)
        pos_err = target_pos - eef_pos
        rot_err = self._rotation_error(target_rot, eef_rot)
        tol = self.profile.waypoint_tol_scale
        reached = np.linalg.norm(pos_err) <= tol * phase.pos_tol and np.linalg.norm(rot_err) <= tol * phase.rot_tol
        timed_out = self.phase_steps * self.dt >= phase.max_time_s * self.profile.phase_time_scale
        if phase.name != "hold" and (reached or timed_out):
            self.phase_index += 1
            self.phase_steps = 0
            self.drift_steps, self.drift_accepted = 0, 0.0
            phase = PHASES[self.phase_index]
            target_pos, target_rot = self._waypoint(phase.name, obs)
            pos_err = target_pos - eef_pos
            rot_err = self._rotation_error(target_rot, eef_rot)
        self.phase_steps += 1
        if phase.name == "hold":
            self.hold_steps += 1
            if np.linalg.norm(pos_err) <= self.profile.let_go_tol_m:
                self.last_vel = np.zeros(3)
                return np.zeros(6)

        vel = _clip_norm(pos_err * APPROACH_RATE, phase.speed * self.profile.speed)
        dv = _clip_norm(vel - self.last_vel, self.profile.max_accel * self.dt)
        vel = self.last_vel + dv
        # never push past the waypoint: the acceleration limit must not overshoot it
        vel = _clip_norm(vel, np.linalg.norm(pos_err) * APPROACH_RATE)
        self.last_vel = vel
        ang = _clip_norm(rot_err * APPROACH_RATE, phase.turn_speed * self.profile.speed)
        cmd = np.concatenate([vel, ang]) + self._noise()
        # world frame -> the frame OSC reads deltas in
        base_rot = self._controller_frame()
        cmd = _to_frame(base_rot, cmd)
        err = _to_frame(base_rot, np.concatenate([pos_err, rot_err]))
        mask = self._one_axis(err, float(np.linalg.norm(pos_err))) if self.profile.one_axis else np.ones(6)
        # velocity -> the goal offset that OSC turns into that velocity
        action = mask * cmd * self.speed_to_offset / self.action_scale
        if self.profile.input_levels:
            action = self._quantize(action)
        if self.profile.release_prob and self.rng.random() < self.profile.release_prob:
            action = np.zeros(6)
        return np.clip(action, -1.0, 1.0)

    def executed(self, action: np.ndarray) -> np.ndarray:
        """The action to execute for the operator's ``action``: itself plus the profile's injected noise."""
        p = self.profile
        if not p.injected_noise:
            return action
        a = np.exp(-self.dt / p.injected_noise_time_s)
        self.injected = a * self.injected + np.sqrt(1 - a**2) * p.injected_noise * self.rng.standard_normal(6)
        return np.clip(action + self.injected, -1.0, 1.0)

    def agent(self, obs: dict) -> np.ndarray | None:
        """The operator as an unrecorded agent of veragmil_suite.environments.episode.run_until_done: the action it
        executes, or None once the scoop is done."""
        return None if self.done else self.executed(self.act(obs))

    def _rotation_error(self, target_rot: np.ndarray, eef_rot: np.ndarray) -> np.ndarray:
        """Axis-angle from the spoon's attitude to the target's (world frame); with a free heading, to the target
        turned to the spoon's heading, and nothing about the vertical (the arm cannot hold it)."""
        if not self.free_heading:
            return turn_to(target_rot, eef_rot)
        err = turn_to(align_heading(target_rot, eef_rot), eef_rot)
        err[2] = 0.0
        return err

    def _waypoint(self, name: str, obs: dict) -> tuple[np.ndarray, np.ndarray]:
        """Spoon (eef) target of a phase, from the bowl's rim and shape: robust to where the bowl stands."""
        rim = np.asarray(obs["bowl_pos"], dtype=float)
        shape = self.env.bowl_shape
        floor_z = rim[2] - shape.depth
        floor_r = min(shape.floor_semi_axes)
        rim_r = min(shape.rim_semi_axes)
        plan, j = self.plan, self.jitter
        y = rim[1] + j["y"]
        if name == "approach":
            return np.array([rim[0] - 0.5 * rim_r, y, rim[2] + plan.approach_dz]), PRE_SCOOP_EEF_ROT
        if name == "dip":
            x = rim[0] - floor_r + plan.dip_dx + j["dip_x"]
            return np.array([x, y, floor_z + plan.dip_dz + j["dip_z"]]), PRE_SCOOP_EEF_ROT
        if name == "drag":
            return np.array([rim[0] + plan.drag_dx + j["drag_x"], y, floor_z + plan.drag_dz]), PRE_SCOOP_EEF_ROT
        level_x = rim[0] + plan.level_dx + plan.level_dx_per_radius * self.piece_radius + j["drag_x"]
        if name == "level":
            return np.array([level_x, y, floor_z + plan.level_dz]), POST_SCOOP_EEF_ROT
        desired = np.asarray(obs["desired_pose"], dtype=float)
        desired_rot = T.quat2mat(desired[3:7])
        if name == "lift":
            return np.array([level_x, y, rim[2] + plan.lift_dz]), TIP_BACK @ desired_rot
        if name == "carry":
            return desired[:3].copy(), TIP_BACK @ desired_rot
        return desired[:3].copy(), desired_rot

    def _controller_frame(self) -> np.ndarray:
        """Rotation of the frame OSC reads deltas in (robosuite 1.5: a site on the arm's first link)."""
        composite = self.env.robots[0].composite_controller
        if getattr(self.controller, "input_ref_frame", "base") == "world":
            return np.eye(3)
        return composite.get_controller_base_pose(self.arm)[1]

    def _noise(self) -> np.ndarray:
        """Ornstein-Uhlenbeck noise: a slowly wandering hand, not white jitter."""
        p = self.profile
        if not (p.pos_noise or p.rot_noise):
            return np.zeros(6)
        a = np.exp(-self.dt / p.noise_time_s)
        std = np.array([p.pos_noise] * 3 + [p.rot_noise] * 3)
        self.noise = a * self.noise + np.sqrt(1 - a**2) * std * self.rng.standard_normal(6)
        return self.noise

    def _one_axis(self, err: np.ndarray, pos_dist: float) -> np.ndarray:
        """A one-hot mask: the input axis with the largest remaining error (sticky, as a hand on a 3D mouse is);
        a spoon drifted more than turn_drift_m is brought back before turning on, for a while at most."""
        weighted = np.abs(err) * ONE_AXIS_WEIGHTS
        turning = weighted[3:].max() > weighted[:3].max()
        limit = self.profile.turn_drift_m
        if pos_dist < DRIFT_RESUME_FRACTION * limit:
            self.drift_accepted = 0.0
        if turning and 0.0 < limit and pos_dist > self.drift_accepted + limit and not self.drift_steps:
            self.drift_steps = 1  # start correcting the drift
        elif self.drift_steps:
            # correct to half the limit, so the turn gets more than one step before the next correction; a spoon
            # stalled in the pile keeps the drift it has and turns on
            stalled = self.drift_steps * self.dt > DRIFT_CORRECTION_MAX_S
            if stalled:
                self.drift_accepted = pos_dist
            done = pos_dist < DRIFT_RESUME_FRACTION * limit or stalled or not turning
            self.drift_steps = 0 if done else self.drift_steps + 1
        if self.drift_steps:
            weighted[3:] = 0.0
            if self.axis is not None and self.axis >= 3:
                self.axis = None
        if self.axis is None or weighted[self.axis] < 0.3 * weighted.max() or weighted[self.axis] < 0.002:
            self.axis = int(np.argmax(weighted))
        mask = np.zeros(6)
        mask[self.axis] = 1.0
        return mask

    def _quantize(self, action: np.ndarray) -> np.ndarray:
        """Coarse input: each component snapped to a few deflection levels, small ones to nothing (a dead band)."""
        step = QUANTIZE_FULL_SCALE / self.profile.input_levels
        return np.clip(np.round(action / step), -self.profile.input_levels, self.profile.input_levels) * step


def _to_frame(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A (linear, angular) 6-vector expressed in the frame whose world rotation is ``rot``."""
    return np.concatenate([rot.T @ v[:3], rot.T @ v[3:]])


def _clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    n = np.linalg.norm(v)
    return v if n <= limit or n == 0 else v * (limit / n)


def with_overrides(profile: str | OperatorProfile, **changes: Any) -> OperatorProfile:
    """A profile with some fields changed (e.g. a slower expert: ``with_overrides("expert", speed=0.5)``)."""
    return replace(get_profile(profile), **changes)
