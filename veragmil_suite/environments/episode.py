"""
The episode loop of ScoopGranular, shared by veragmil-collect and veragmil-evaluate so that a recorded
demonstration and a scored rollout end by the same rule.

An episode ends once success has held ``success_hold_s`` (``round(success_hold_s * control_freq)`` consecutive
successful steps, at least one), at a physics error, at the horizon (the env's done, or ``horizon`` steps taken),
or when the agent returns no action (a scripted agent gave up, a human operator stopped). The end reasons are
"success", "physics", "horizon" and the one the caller names for an agent that stops ("gave up" by default).
The success rule is :class:`SuccessHold`, which the Gymnasium environment (veragmil_suite.wrappers.gym_env) ends its
episodes by as well.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from veragmil_suite.environments.stages import StageTracker
from veragmil_suite.utils.numbers import is_number

# how long success must hold to end an episode (veragmil-collect's default --success-hold, veragmil-evaluate's rule)
SUCCESS_HOLD_S = 1.0


class SuccessHold:
    """
    Whether success has held ``success_hold_s``: ``round(success_hold_s * control_freq)`` consecutive successful
    steps, at least one. The one rule by which every episode of the suite ends in success.

    Args:
        control_freq: control steps per second
        success_hold_s: seconds success must hold; None or <= 0: success never ends an episode (``update`` is
            always False)
    """

    def __init__(self, control_freq: float, success_hold_s: float | None = SUCCESS_HOLD_S):
        if success_hold_s is not None and not is_number(success_hold_s):
            raise ValueError(f"success_hold_s must be None or a finite number of seconds, got {success_hold_s!r}")
        self.steps = None  # consecutive successful steps that end the episode
        if success_hold_s is not None and success_hold_s > 0:
            self.steps = max(1, int(round(success_hold_s * control_freq)))
        self.streak = 0

    def reset(self) -> None:
        self.streak = 0

    def update(self, info: dict) -> bool:
        """Counts one step's ``info["success"]``; returns whether success has now held long enough."""
        self.streak = self.streak + 1 if info.get("success") else 0
        return self.steps is not None and self.streak >= self.steps


@dataclass(frozen=True)
class EpisodeEnd:
    """
    How an episode ended: why (end reason), after how many steps, with which last info, the furthest stage it
    reached (SCOOP_STAGES) and the largest spoon load it had (a load lost before the end still shows here).
    """

    reason: str
    steps: int
    info: dict
    stage: str
    peak_grains_in_spoon: int


def run_until_done(
    act: Callable[[dict], np.ndarray | None],
    step: Callable[[np.ndarray], tuple],
    obs: dict,
    control_freq: float,
    horizon: int,
    success_hold_s: float | None = SUCCESS_HOLD_S,
    on_step: Callable[[], None] | None = None,
    realtime: bool = False,
    stopped: str = "gave up",
) -> EpisodeEnd:
    """
    Steps an agent from ``obs`` until the episode ends (see the module's docstring); returns how it ended.

    Args:
        act: the agent, observation -> action, or None when it stops (ends with reason ``stopped``)
        step: env.step or a recorder's step, action -> (obs, reward, done, info)
        obs: the observation the first action is chosen from
        control_freq: control steps per second, to turn ``success_hold_s`` into steps and to pace ``realtime``
        horizon: the most steps taken
        success_hold_s: seconds success must hold to end the episode; None or <= 0: success does not end it
        on_step: called after every step (a live render, a video frame)
        realtime: each step takes at least 1 / ``control_freq`` seconds, so a human sees the robot at its speed
        stopped: the end reason when ``act`` returns None
    """
    hold = SuccessHold(control_freq, success_hold_s)
    steps, peak, info, reason = 0, 0, {}, "horizon"
    stages = StageTracker()
    while steps < horizon:
        start = time.perf_counter()
        action = act(obs)
        if action is None:
            reason = stopped
            break
        obs, _, done, info = step(action)
        steps += 1
        if on_step is not None:
            on_step()
        peak = max(peak, int(info.get("grains_in_spoon", 0)))
        stages.update(info)
        held = hold.update(info)
        if info.get("physics_error"):
            reason = "physics"
            break
        if held:
            reason = "success"
            break
        if done:
            break
        if realtime and steps < horizon:
            time.sleep(max(0.0, 1.0 / control_freq - (time.perf_counter() - start)))
    return EpisodeEnd(reason=reason, steps=steps, info=info, stage=stages.stage, peak_grains_in_spoon=peak)
