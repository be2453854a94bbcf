"""Demonstrations played again from their states: videos of the replay, and a copy of a file with camera
observations rendered (veragmil-replay, veragmil-render-obs).
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
import robosuite
import robosuite.macros

from veragmil_suite.data.schema import (
    DatasetError,
    attr_text,
    demo_names,
    filter_key_demos,
    open_dataset,
    write_masks,
)
from veragmil_suite.data.writer import updated_file
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.models.foods import with_recorded_physics
from veragmil_suite.utils.canonical import canonical
from veragmil_suite.utils.numbers import is_number, is_whole
from veragmil_suite.utils.whole_files import same_file, written_whole

if TYPE_CHECKING:
    from robosuite.environments.base import MujocoEnv


class DemoEnvs:
    """Environments for a file's demos, built from each demo's own env_args (a merged file may mix foods)."""

    def __init__(self, f: h5py.File, **overrides):
        self.file_meta = json.loads(f["data"].attrs["env_args"])
        self.overrides = overrides
        self._key = None
        self.env = None

    def for_demo(self, g: h5py.Group) -> MujocoEnv:
        """The env for this demo's env_args and the overrides: the current one unless they differ."""
        meta = json.loads(g.attrs["env_args"]) if "env_args" in g.attrs else self.file_meta
        kwargs = with_recorded_physics({k: v for k, v in meta["env_kwargs"].items() if k not in ("env_name",)})
        kwargs.update(self.overrides)
        kwargs.update(has_renderer=False, ignore_done=True)
        key = canonical(kwargs)
        if key != self._key:
            self.close()
            import veragmil_suite  # noqa: F401  (registers ScoopGranular)

            self.env = robosuite.make(meta["env_name"], **kwargs)
            self.env.reset()
            self._key = key
        return self.env

    def start(self, g: h5py.Group) -> tuple:
        """The demo's env, reset to its first state; returns (env, observation)."""
        env = self.for_demo(g)
        obs = robomimic_obs.reset_to_demo(env, attr_text(g.attrs["model_file"]), g["states"][0])
        return env, obs

    def close(self) -> None:
        if self.env is not None:
            self.env.close()
            self.env = None


def _render(env, camera: str, height: int, width: int) -> np.ndarray:
    frame = env.sim.render(camera_name=camera, height=height, width=width)
    return frame[::-1] if robosuite.macros.IMAGE_CONVENTION == "opengl" else frame


def _check_camera(env, camera: str) -> None:
    names = [env.sim.model.camera_id2name(i) for i in range(env.sim.model.ncam)]
    if camera not in names:
        raise DatasetError(f"no camera {camera!r} in this scene; cameras: {', '.join(names)}")


def _select_demos(f: h5py.File, demos: list[str] | None, n: int | None, filter_key: str | None = None) -> list[str]:
    names = demo_names(f)
    if filter_key:
        keep = set(filter_key_demos(f, filter_key))
        names = [x for x in names if x in keep]
    if demos:
        missing = [d for d in demos if d not in names]
        if missing:
            raise DatasetError(
                f"no demo {', '.join(missing)} (demos: {', '.join(names[:10])}{'...' if len(names) > 10 else ''})"
            )
        names = list(demos)
    return names[:n] if n else names


def replay_demos(
    path: str | Path,
    video: str | Path | None,
    demos: list[str] | None = None,
    n: int | None = None,
    camera: str = "agentview",
    height: int = 480,
    width: int = 640,
    fps: float | None = None,
    skip: int = 1,
    use_actions: bool = False,
) -> list[dict]:
    """Replay demos to one mp4, from their states or (use_actions) their actions open loop.

    Returns, per demo: its name, steps, and with use_actions the largest state error against the recorded
    states (0.0 when replay is exact) and the final metrics of the replay.
    """
    import imageio  # imageio takes ~80 ms to import: only when writing videos

    if video is not None and same_file(path, video):
        raise DatasetError(f"{video} is also the input: write the video to a new file")
    for name, value in (("n", n), ("skip", skip), ("height", height), ("width", width)):
        if (value is not None or name != "n") and not (is_whole(value) and value > 0):
            raise DatasetError(
                f"{name} must be a positive integer{' or None (all)' if name == 'n' else ''}, got {value!r}"
            )
    if fps is not None and not (is_number(fps) and fps > 0):
        raise DatasetError(f"fps must be a positive number or None (real time), got {fps!r}")
    with open_dataset(path) as f, contextlib.ExitStack() as stack:
        # the video is written whole: an earlier one stays until this one is complete
        target = None if video is None else stack.enter_context(written_whole(video, keep_suffix=True))
        names = _select_demos(f, demos, n)
        envs = DemoEnvs(f, has_offscreen_renderer=video is not None, use_camera_obs=False)
        writer = None
        results = []
        try:
            for name in names:
                g = f["data"][name]
                env, _ = envs.start(g)
                if video is not None:
                    _check_camera(env, camera)
                    if writer is None:
                        writer = imageio.get_writer(str(target), fps=fps or env.control_freq / skip, macro_block_size=1)
                states = g["states"][()]
                # what was executed: the operator's own actions under injected noise are the labels, not these
                actions = g["executed_actions" if "executed_actions" in g else "actions"][()]
                result = dict(demo=name, steps=len(actions))
                errors = []
                info = {}
                for t in range(len(actions)):
                    if use_actions:
                        if t > 0:
                            errors.append(float(np.abs(env.sim.get_state().flatten() - states[t]).max()))
                    else:
                        env.sim.set_state_from_flattened(states[t])
                        env.sim.forward()
                    if writer is not None and t % skip == 0:
                        writer.append_data(_render(env, camera, height, width))
                    if use_actions:
                        _, _, _, info = env.step(actions[t])
                if use_actions:
                    result["max_state_error"] = max(errors) if errors else 0.0
                    result["success"] = bool(info.get("success", False))
                    result["grains_in_spoon"] = int(info.get("grains_in_spoon", 0))
                    result["grains_spilled"] = int(info.get("grains_spilled", 0))
                results.append(result)
        finally:
            if writer is not None:
                writer.close()
            envs.close()
    return results


def render_observations(
    path: str | Path,
    output: str | Path,
    cameras: list[str],
    height: int,
    width: int,
    depth: bool = False,
    demos: list[str] | None = None,
) -> int:
    """Copy a dataset with its camera observations re-rendered from the states; returns the number of demos.

    Everything else (actions, states, rewards, dones, low-dim observations, attributes, masks) is copied as is.
    next_obs of the last step comes from replaying the last action (as robomimic's dataset_states_to_obs does).
    """
    output = Path(output)
    if same_file(path, output):
        raise DatasetError(f"{output} is also the input: write the re-rendered dataset to a new file")
    overrides = dict(
        use_camera_obs=True,
        has_offscreen_renderer=True,
        camera_names=list(cameras),
        camera_heights=height,
        camera_widths=width,
        camera_depths=depth,
    )
    with open_dataset(path) as fin, updated_file(output, new=True) as working:
        fout = working.file
        names = _select_demos(fin, demos, None)
        data_in = fin["data"]
        data_out = fout.create_group("data")
        for key, value in data_in.attrs.items():
            data_out.attrs[key] = value
        data_out.attrs["env_args"] = _with_cameras(attr_text(data_in.attrs["env_args"]), overrides)
        envs = DemoEnvs(fin, **overrides)
        try:
            for name in names:
                g = data_in[name]
                env, _ = envs.start(g)
                for cam in cameras:
                    _check_camera(env, cam)
                out = data_out.create_group(name)
                for key in ("actions", "executed_actions", "states", "rewards", "dones"):
                    if key in g:
                        fin.copy(g[key], out, name=key)
                for key, value in g.attrs.items():
                    out.attrs[key] = value
                if "env_args" in g.attrs:
                    out.attrs["env_args"] = _with_cameras(attr_text(g.attrs["env_args"]), overrides)
                executed = g["executed_actions" if "executed_actions" in g else "actions"][()]
                images = _render_images(env, g["states"][()], executed)
                for group in ("obs", "next_obs"):
                    og = out.create_group(group)
                    for key, d in g[group].items():
                        if not _is_camera_key(key):
                            fin.copy(d, og, name=key)
                    for key, frames in images[group].items():
                        og.create_dataset(key, data=frames, compression="gzip", compression_opts=4, shuffle=True)
                working.check()  # a full disk stops the job at the demo it refused
        finally:
            envs.close()
        if "mask" in fin:
            fin.copy(fin["mask"], fout, name="mask")
        if demos:
            write_masks(fout)
    return len(names)


def _is_camera_key(key: str) -> bool:
    return key.endswith("_image") or key.endswith("_depth")


def _camera_observations(env) -> dict:
    obs = robomimic_obs.observation(env, robomimic_obs.observe(env))
    return {k: v for k, v in obs.items() if _is_camera_key(k)}


def _render_images(env, states: np.ndarray, actions: np.ndarray) -> dict:
    # the controllers as the recording had them: at its first state's posture (the last step is simulated again)
    env.sim.set_state_from_flattened(states[0])
    env.hold_restored_pose()
    frames = []
    for state in states:
        env.sim.set_state_from_flattened(state)
        frames.append(_camera_observations(env))
    env.sim.set_state_from_flattened(states[-1])
    env.hold_restored_pose(episode_start=False)  # the step starts here, not where the controllers last looked
    env.step(actions[-1])
    last = _camera_observations(env)
    keys = frames[0].keys()
    obs = {k: np.stack([fr[k] for fr in frames]) for k in keys}
    next_obs = {k: np.concatenate([obs[k][1:], last[k][None]]) for k in keys}
    return dict(obs=obs, next_obs=next_obs)


def _with_cameras(env_args_json: str, overrides: dict) -> str:
    meta = json.loads(env_args_json)
    meta["env_kwargs"].update({k: v for k, v in overrides.items() if k != "has_offscreen_renderer"})
    meta["env_kwargs"]["has_offscreen_renderer"] = True
    return json.dumps(meta, indent=4)
