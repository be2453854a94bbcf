"""
Records a tiny dataset in robomimic's HDF5 schema from short episodes of any robosuite environment.

The environment is built and observed through robomimic's own EnvRobosuite (with veragmil_suite's compatibility
layer), so the file's env_args are exactly what robomimic recreates for rollouts, and each observation is that of
the recorded state: what policies see in rollouts and what robomimic's dataset_states_to_obs extracts. Actions are
a smooth random walk: the data only has to have the right form.
"""

from __future__ import annotations

import json

import h5py
import numpy as np

from veragmil_suite.learning import robomimic_compat

SCOOP_KWARGS = dict(robots="XArm7", food="pasta", n_grains=12, pile_variants=1, control_freq=20)


def default_controller_config(env_name: str, robots) -> dict:
    """The composite controller config a recorder stores in env_kwargs (robosuite 1.5's BASIC form)."""
    robot = robots if isinstance(robots, str) else robots[0]
    if env_name == "ScoopGranular":
        from veragmil_suite.controllers.scoop_config import load_scoop_controller_config

        return load_scoop_controller_config("OSC_POSE", robot=robot)
    from robosuite.controllers import load_composite_controller_config

    return load_composite_controller_config(controller="BASIC", robot=robot)


def record_tiny_dataset(
    path: str,
    env_name: str = "ScoopGranular",
    env_kwargs: dict | None = None,
    episodes: int = 3,
    steps: int = 20,
    valid_episodes: int = 1,
    camera_names: tuple[str, ...] = (),
    camera_size: int = 84,
    camera_depths: bool = False,
    action_scale: float = 0.5,
    seed: int = 0,
) -> str:
    """
    Writes ``episodes`` episodes of ``steps`` transitions to ``path`` and returns the path.

    Layout: data/demo_N/{actions, states, rewards, dones, obs/*, next_obs/*} with attributes num_samples and
    model_file; data attributes env_args (JSON) and total; mask/train and mask/valid (the last
    ``valid_episodes`` episodes).
    """
    robomimic_compat.install()
    from robomimic.envs.env_robosuite import EnvRobosuite

    kwargs = dict(SCOOP_KWARGS if env_kwargs is None and env_name == "ScoopGranular" else (env_kwargs or {}))
    kwargs.setdefault("controller_configs", default_controller_config(env_name, kwargs.get("robots", "Panda")))
    if camera_names:
        kwargs.update(
            camera_names=list(camera_names),
            camera_heights=camera_size,
            camera_widths=camera_size,
            camera_depths=camera_depths,
        )
    env = EnvRobosuite(
        env_name,
        render=False,
        render_offscreen=bool(camera_names),
        use_image_obs=bool(camera_names),
        postprocess_visual_obs=False,
        **kwargs,
    )
    rng = np.random.default_rng(seed)
    low, high = env.env.action_spec
    demos = []
    total = 0
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        for ep in range(episodes):
            obs = env.reset()
            start = env.get_state()
            action = np.zeros_like(low)
            record = dict(actions=[], states=[], rewards=[], dones=[], obs=[], next_obs=[])
            for t in range(steps):
                action = np.clip(0.7 * action + 0.3 * rng.uniform(-1, 1, size=low.shape), -1, 1)
                record["states"].append(env.get_state()["states"])
                next_obs, reward, done, _ = env.step(np.clip(action_scale * action, low, high))
                record["actions"].append(action_scale * action)
                record["rewards"].append(reward)
                record["dones"].append(int(t == steps - 1))
                record["obs"].append(obs)
                record["next_obs"].append(next_obs)
                obs = next_obs
            name = f"demo_{ep}"
            grp = data.create_group(name)
            for key in ("actions", "states", "rewards", "dones"):
                grp.create_dataset(key, data=np.array(record[key]))
            for kind in ("obs", "next_obs"):
                for key in record[kind][0]:
                    grp.create_dataset(f"{kind}/{key}", data=np.stack([o[key] for o in record[kind]]))
            grp.attrs["num_samples"] = steps
            grp.attrs["model_file"] = start["model"]
            demos.append(name)
            total += steps
        data.attrs["total"] = total
        data.attrs["env_args"] = json.dumps(env.serialize(), indent=4)
        split = len(demos) - valid_episodes
        f.create_dataset("mask/train", data=np.array(demos[:split], dtype="S"))
        f.create_dataset("mask/valid", data=np.array(demos[split:], dtype="S"))
    env.env.close()
    return path
