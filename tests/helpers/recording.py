"""Small demonstration files for the recording, collection and dataset-tool tests: a few short scripted episodes
in a light scene (a dozen pasta pieces, one pile variant), so each file takes seconds to make."""

from __future__ import annotations

import os

import numpy as np
import robosuite

import veragmil_suite  # noqa: F401
from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.data.schema import env_meta, provenance
from veragmil_suite.data.writer import DemoWriter
from veragmil_suite.devices.expert import ScriptedScooper

CAMERA_SIZE = 32


def tiny_env_kwargs(food: str = "pasta", cameras=("overhead",), depth: bool = True, **changes) -> dict:
    """JSON-serializable robosuite.make kwargs of a light scene (what a dataset's env_args stores)."""
    kwargs = dict(
        robots="XArm7",
        food=food,
        n_grains=12,
        pile_variants=1,
        controller_configs=load_scoop_controller_config("OSC_POSE", robot="XArm7"),
        control_freq=20,
        horizon=400,
        ignore_done=False,
        use_object_obs=True,
        use_camera_obs=bool(cameras),
        has_offscreen_renderer=bool(cameras),
        camera_names=list(cameras) or "overhead",
        camera_heights=CAMERA_SIZE,
        camera_widths=CAMERA_SIZE,
        camera_depths=depth and bool(cameras),
    )
    kwargs.update(changes)
    return kwargs


def make_env(env_kwargs: dict, seed: int = 0):
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    return robosuite.make("ScoopGranular", **env_kwargs, has_renderer=False, seed=seed)


def record_file(
    path,
    episodes: int = 2,
    steps: int = 12,
    seed: int = 0,
    env_kwargs: dict | None = None,
    device: str = "scripted",
    operator: str = "scripted-expert",
) -> list:
    """Record ``episodes`` scripted episodes of ``steps`` steps into ``path`` (appending); returns the episodes."""
    env_kwargs = env_kwargs or tiny_env_kwargs()
    env = make_env(env_kwargs, seed)
    writer = DemoWriter(
        path,
        env_meta(env_kwargs),
        provenance(device=device, operator=operator, food=env_kwargs["food"], robot="XArm7", source="scripted"),
    )
    recorder = EpisodeRecorder(env)
    expert = ScriptedScooper(env, "noisy", seed=seed)
    episodes_out = []
    for _ in range(episodes):
        obs = recorder.reset()
        expert.reset()
        for _ in range(steps):
            obs, _, _, _ = recorder.step(expert.act(obs))
        episode = recorder.episode(attrs=dict(pile_variant=int(env.pile_variant)))
        writer.write(episode)
        episodes_out.append(episode)
    env.close()
    return episodes_out


def states_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b))


def synthetic_episode(steps: int = 20, seed: int = 0, **changes):
    """An Episode of the file's form without an env (random values, actions within [-1, 1]): for tests of the
    writer itself, which need many writes fast."""
    from veragmil_suite.data.recording import Episode

    rng = np.random.default_rng(seed)

    def obs():
        return {
            "robot0_eef_pos": rng.normal(size=(steps, 3)),
            "overhead_image": rng.integers(0, 255, (steps, CAMERA_SIZE, CAMERA_SIZE, 3), dtype=np.uint8),
        }

    fields = dict(
        actions=rng.uniform(-1, 1, (steps, 6)),
        states=rng.normal(size=(steps, 120)),
        rewards=np.zeros(steps),
        dones=np.r_[np.zeros(steps - 1, dtype=np.int64), 1] if steps else np.zeros(0, dtype=np.int64),
        obs=obs(),
        next_obs=obs(),
        model_file="<mujoco model='synthetic'/>",
        metrics=dict(success=False, grains_spilled=0, physics_error="", stage="approach"),
        attrs=dict(seed=seed),
    )
    fields.update(changes)
    return Episode(**fields)


def synthetic_writer(path, **kwargs):
    """A DemoWriter of a light scene's metadata (no env is built)."""
    env_kwargs = tiny_env_kwargs()
    return DemoWriter(
        path, env_meta(env_kwargs), provenance("scripted", "tester", env_kwargs["food"], "XArm7"), **kwargs
    )
