"""The sample dataset shipped in demos/: what our configs train on out of the box (demos/README.md)."""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import robosuite

from veragmil_suite.data.schema import check_schema, demo_names, open_dataset
from veragmil_suite.learning import robomimic_compat, robomimic_obs
from veragmil_suite.models.foods import TRAINING_FOODS

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "demos" / "scoop.hdf5"
CONFIG_DIR = ROOT / "configs" / "json"
SIZE_LIMIT_MB = 30
IMAGE_SIZE = 84
# low-dim observations a playback from states must reproduce, and the round-off allowed between CPUs
PLAYBACK_KEYS = ("robot0_joint_pos", "robot0_eef_pos", "bowl_pos", "desired_pose", "object", "spoon_load")
ROUND_OFF = 1e-9


def _config_obs_keys(name: str) -> dict[str, list[str]]:
    with open(CONFIG_DIR / f"{name}.json") as f:
        return json.load(f)["observation"]["modalities"]["obs"]


CONFIGS = sorted(p.stem for p in CONFIG_DIR.glob("*.json"))
# configs that read depth need a dataset recorded (or re-rendered) with depth; the sample is low-dim + RGB
RGB_OR_LOW_DIM = [name for name in CONFIGS if not _config_obs_keys(name)["depth"]]


def test_sample_holds_successful_scripted_demos_of_every_training_food():
    assert SAMPLE.stat().st_size < SIZE_LIMIT_MB * 1e6
    with open_dataset(SAMPLE) as f:
        meta = check_schema(f)
        names = demo_names(f)
        data = f["data"]
        foods = [data[n].attrs["food"] for n in names]
        assert set(foods) == set(TRAINING_FOODS)
        for n in names:
            g = data[n]
            assert g.attrs["device"] == "scripted" and bool(g.attrs["success"]), n
            image = g["obs/overhead_image"]
            assert image.dtype == np.uint8 and image.shape == (g.attrs["num_samples"], IMAGE_SIZE, IMAGE_SIZE, 3)
            assert set(g["obs"]) == set(g["next_obs"])
        train = {m.decode() for m in f["mask/train"][()]}
        valid = {m.decode() for m in f["mask/valid"][()]}
        assert train and valid and not train & valid and train | valid == set(names)
    assert meta["env_name"] == "ScoopGranular" and "env_name" not in meta["env_kwargs"]
    assert meta["env_kwargs"]["camera_names"] == ["overhead"]


@pytest.mark.parametrize("name", RGB_OR_LOW_DIM)
def test_config_loads_the_sample_through_robomimic(name):
    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils
    import robomimic.utils.obs_utils as ObsUtils
    import robomimic.utils.train_utils as TrainUtils
    from robomimic.config import config_factory

    with open(CONFIG_DIR / f"{name}.json") as f:
        ours = json.load(f)
    config = config_factory(ours["algo_name"])
    with config.values_unlocked():
        config.update(ours)
        config.train.data = str(SAMPLE)  # the configs name it relative to the repository root
    ObsUtils.initialize_obs_utils_with_config(config)
    shape_meta = FileUtils.get_shape_metadata_from_dataset(
        dataset_path=config.train.data, all_obs_keys=config.all_obs_keys, verbose=False
    )
    assert shape_meta["ac_dim"] == 6
    trainset, _ = TrainUtils.load_data_for_training(config, obs_keys=shape_meta["all_obs_keys"])
    item = trainset[0]
    # robomimic 0.3.0 pads a frame-stacked sequence with frame_stack - 1 earlier steps, actions as observations
    length = config.train.seq_length + config.train.frame_stack - 1
    assert item["actions"].shape == (length, 6)
    for key in config.all_obs_keys:
        assert item["obs"][key].shape[0] == length, key
    for key in config.observation.modalities.obs.rgb:
        assert item["obs"][key].shape[1:] == (IMAGE_SIZE, IMAGE_SIZE, 3)  # raw; robomimic processes per batch


def test_only_depth_configs_need_more_than_the_sample():
    with open_dataset(SAMPLE) as f:
        keys = set(f["data/demo_0/obs"])
    for name in CONFIGS:
        used = {k for keys_ in _config_obs_keys(name).values() for k in keys_}
        missing = used - keys
        assert missing <= {"overhead_depth"}, f"{name}.json reads keys the sample lacks: {missing}"
        assert bool(missing) == (name not in RGB_OR_LOW_DIM)


def test_sample_plays_back_on_the_pinned_mujoco():
    """Playback from the recorded states reproduces the recorded observations; open-loop action replay agrees to
    round-off for a step. Bit-exact action replay holds only on the MuJoCo *and* the CPU that recorded a demo
    (test_recording checks it for a demo recorded here): on another CPU the first step differs by ~1e-15, and
    grains are chaotic, so that grows to centimetres within 40 steps.

    A failure here after a MuJoCo upgrade means: remake the sample (demos/README.md) with the new pin.
    """
    with open_dataset(SAMPLE) as f:
        # the lightest pile replays fastest; a merged file's demos each carry their own env_args (food, grains)
        name = min(demo_names(f), key=lambda n: f[f"data/{n}/states"].shape[1])
        g = f[f"data/{name}"]
        meta = json.loads(g.attrs["env_args"])
        assert g.attrs["mujoco_version"] == mujoco.__version__
        xml, states, actions = g.attrs["model_file"], g["states"][()], g["actions"][()]
        recorded = {key: g[f"obs/{key}"][()] for key in PLAYBACK_KEYS}
    kwargs = dict(meta["env_kwargs"], has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    env = robosuite.make(meta["env_name"], **kwargs)
    robomimic_obs.reset_to_demo(env, xml, states[0])
    env.step(actions[0])
    np.testing.assert_allclose(env.sim.get_state().flatten(), states[1], rtol=0, atol=ROUND_OFF)
    for t in range(0, len(states), 10):
        env.sim.set_state_from_flattened(states[t])
        obs = robomimic_obs.observation(env, robomimic_obs.observe(env))
        for key in PLAYBACK_KEYS:
            np.testing.assert_allclose(obs[key], recorded[key][t], rtol=0, atol=ROUND_OFF, err_msg=f"{key} at {t}")
    env.close()
