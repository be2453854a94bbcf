"""Recording one episode: the steps, states and observations of an env, as the file stores them (data.schema)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from veragmil_suite.data.schema import METRIC_KEYS
from veragmil_suite.environments.stages import StageTracker
from veragmil_suite.learning import robomimic_obs


@dataclass
class Episode:
    """One recorded episode, robomimic arrays plus what replays it."""

    actions: np.ndarray
    states: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    obs: dict
    next_obs: dict
    model_file: str
    metrics: dict
    attrs: dict = field(default_factory=dict)
    executed_actions: np.ndarray | None = None  # when not the actions stored for learning (injected noise)
    action_bounds: tuple[np.ndarray, np.ndarray] | None = None  # the env's action space (low, high), when known

    @property
    def num_samples(self) -> int:
        return int(self.actions.shape[0])


class EpisodeRecorder:
    """
    Steps a ScoopGranular env and keeps what the dataset needs: the state before each action, the action, reward,
    observations before and after, and the final metrics.

    Args:
        env (ScoopGranular): the environment to record
    """

    def __init__(self, env):
        self.env = env
        self._clear()

    def _clear(self):
        self._states, self._actions, self._rewards, self._successes = [], [], [], []
        self._executed = []
        self._obs, self._next_obs = [], []
        self._info = {}
        self._stages = StageTracker()
        self.model_file = None
        self.pile_key = ""
        self.obs = None
        self._converted = None

    def reset(self, seed: int | None = None) -> dict:
        """Reset the env (seeded first when ``seed`` is given) and restart it as playback will; returns robosuite's
        observation."""
        self._clear()
        self.env.reset(seed=seed)
        self.pile_key = self.env.pile_key  # the restart below loads a state, which names no settled pile
        raw, self.model_file = robomimic_obs.restart_from_current_state(self.env)
        self.obs = raw
        self._converted = robomimic_obs.observation(self.env, raw)
        return raw

    def step(self, action: np.ndarray, label: np.ndarray | None = None) -> tuple[dict, float, bool, dict]:
        """
        env.step(action), recorded. Returns (obs, reward, done, info), obs that of the state reached.

        An action outside the env's action space is clipped to it before it is executed, as the controller clips
        its input: what is executed and stored is what the robot applied. ``label`` is the action stored for
        learning when it is not the one executed (injected noise), clipped alike: the executed one is kept as well,
        in executed_actions, so the demo still replays. A non-finite action is not executed (env.step ends the
        episode with a physics_error that says why) and not stored; the episode's metrics carry that error.
        """
        if self.obs is None:
            raise RuntimeError("EpisodeRecorder.reset() must come before step()")
        if label is not None and not np.isfinite(np.asarray(label, dtype=np.float64)).all():
            raise ValueError(f"non-finite action label {np.asarray(label).tolist()}: labels must be finite numbers")
        action = self._clipped(action)
        stored = action if label is None else self._clipped(label)
        state = self.env.sim.get_state().flatten()
        raw, reward, done, info = self.env.step(action)
        if not np.isfinite(action).all():
            self._info = info  # not executed, not stored: the episode ends here, and its metrics say why
            return raw, reward, done, info
        after = robomimic_obs.observation(self.env, raw)
        self._states.append(state)
        self._executed.append(action.copy())
        self._actions.append(stored.copy())
        self._rewards.append(float(reward))
        self._successes.append(bool(info.get("success", False)))
        self._obs.append(self._converted)
        self._next_obs.append(after)
        self._info = info
        self._stages.update(info)
        self.obs, self._converted = raw, after
        return raw, reward, done, info

    def _clipped(self, action) -> np.ndarray:
        """``action`` within the env's action space (one of another size is left to env.step to refuse)."""
        action = np.asarray(action, dtype=np.float64)
        low, high = self.env.action_spec
        if action.shape != np.shape(low) or not np.isfinite(action).all():
            return action  # env.step refuses it, or ends the episode saying why
        return np.clip(action, low, high)

    @property
    def num_steps(self) -> int:
        return len(self._actions)

    def episode(self, attrs: dict | None = None) -> Episode:
        """The episode so far, as arrays (robomimic's done_mode 2: done at success and at the end); its attrs name
        the settled pile it started on (``pile``: a recording made on piles this code no longer settles is known)."""
        if not self._actions:
            raise RuntimeError("no steps recorded")
        dones = np.array(self._successes, dtype=np.int64)
        dones[-1] = 1
        actions, executed = np.stack(self._actions), np.stack(self._executed)
        return Episode(
            actions=actions,
            executed_actions=None if np.array_equal(actions, executed) else executed,
            states=np.stack(self._states),
            rewards=np.array(self._rewards, dtype=np.float64),
            dones=dones,
            obs={k: np.stack([o[k] for o in self._obs]) for k in self._obs[0]},
            next_obs={k: np.stack([o[k] for o in self._next_obs]) for k in self._next_obs[0]},
            model_file=self.model_file,
            metrics=episode_metrics(self._info, self._stages.stage),
            attrs={"pile": self.pile_key, **(attrs or {})},
            action_bounds=tuple(np.asarray(b, dtype=np.float64) for b in self.env.action_spec),
        )


def episode_metrics(info: dict, stage: str) -> dict:
    """The paper's per-episode metrics from the last step's info (success, spilled pieces and volume, time), and
    the furthest stage the episode reached (environments.stages.StageTracker)."""
    out = {"stage": str(stage)}
    for key in METRIC_KEYS:
        if key == "stage":
            continue
        value = info.get(key, "" if key == "physics_error" else 0)
        if isinstance(value, (bool, np.bool_)):
            out[key] = bool(value)
        elif isinstance(value, (int, np.integer)):
            out[key] = int(value)
        elif isinstance(value, (float, np.floating)):
            out[key] = float(value)
        else:
            out[key] = str(value)
    return out
