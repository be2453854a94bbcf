"""robomimic's own scripts (get_dataset_info, playback_dataset, dataset_states_to_obs, train, run_trained_agent,
through our entry points, which only bridge) on a file of several foods and grain counts: every demo runs in its
own food's scene, rollouts go through the file's foods, and appending another food or grain count is recorded per
demo and reported."""

import json
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import robosuite
from helpers.programs import run_program
from helpers.recording import CAMERA_SIZE, record_file, tiny_env_kwargs

from veragmil_suite.data.schema import VARIANTS_KEY, demo_names
from veragmil_suite.learning import robomimic_compat, robomimic_obs
from veragmil_suite.scripts.dataset_tools import info_main

# one worker runs this file's tests: its module fixtures are built once (make test: --dist loadgroup)
pytestmark = pytest.mark.xdist_group("robomimic_multi_food")

ROOT = Path(__file__).resolve().parents[1]
STEPS = 8
# what each demo of the mixed file was recorded with, in order: a food, another food, another grain count
RECORDED = [("pasta", 12), ("buckwheat", 12), ("pasta", 10)]
CONFIG = ROOT / "configs" / "json" / "bc.json"


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """One file: a pasta demo, then a buckwheat demo and a demo with fewer pasta pieces appended to it, recorded
    with the wrist sensor (observations robomimic cannot extract from states)."""
    path = tmp_path_factory.mktemp("mixed") / "mixed.hdf5"
    for seed, (food, n_grains) in enumerate(RECORDED):
        kwargs = tiny_env_kwargs(food, n_grains=n_grains, use_wrench_obs=True)
        record_file(path, episodes=1, steps=STEPS, seed=seed, env_kwargs=kwargs)
    return path


def _scene(env, xml: str) -> tuple[str, int]:
    """The food and grain count of a saved model, as a ScoopGranular env adopts them."""
    env.reset_from_xml_string(xml)
    return env.food.name, env.n_grains


def test_appending_another_food_or_grain_count_is_recorded_per_demo_and_reported(mixed, tmp_path, capsys):
    with h5py.File(mixed) as f:
        per_demo = [json.loads(f["data"][n].attrs["env_args"])["env_kwargs"] for n in demo_names(f)]
        assert [(kw["food"], kw["n_grains"]) for kw in per_demo] == RECORDED
        variants = json.loads(f["data"].attrs["env_args"])[VARIANTS_KEY]
    assert variants == [dict(env_kwargs=dict(food=food, n_grains=n), demos=1) for food, n in RECORDED]
    # robomimic's get_dataset_info prints the file's env meta, variants included
    out = run_program("veragmil-robomimic-dataset-info", "--dataset", mixed, cwd=tmp_path).stdout
    meta = json.loads(re.search(r"==== Env Meta ====\n(\{.*?\n\})", out, re.S).group(1))
    assert meta[VARIANTS_KEY] == variants
    assert info_main([str(mixed)]) == 0
    assert (
        "env kwargs per demo: food='pasta' n_grains=12 (1 demos); food='buckwheat' n_grains=12 (1 demos); "
        "food='pasta' n_grains=10 (1 demos)" in capsys.readouterr().out
    )


def test_robomimics_playback_replays_every_demo_in_its_own_scene(mixed, tmp_path):
    """playback_dataset --use-actions warns at every state the actions do not reproduce exactly."""
    dataset = tmp_path / "mixed.hdf5"
    shutil.copy(mixed, dataset)
    video = tmp_path / "playback.mp4"
    out = run_program(
        "veragmil-robomimic-playback", "--dataset", dataset, "--use-actions", "--video_path", video, cwd=tmp_path
    ).stdout
    assert out.count("Playing back episode") == len(RECORDED)
    assert "diverged" not in out and video.stat().st_size > 1000


def test_robomimics_states_to_obs_extracts_every_demo_and_keeps_its_attributes(mixed, tmp_path):
    dataset = tmp_path / "mixed.hdf5"
    shutil.copy(mixed, dataset)
    size = CAMERA_SIZE // 2  # camera settings of robomimic's processing, which each demo's env_args take
    cameras = ["--camera_names", "overhead", "--camera_height", size, "--camera_width", size]
    args = ["--dataset", dataset, "--output_name", "extracted.hdf5", "--done_mode", "2", *cameras]
    killed = tmp_path / ".extracted.hdf5.deadbeef.writing"  # a killed run's working copy: this run removes it
    killed.write_bytes(b"half an extraction")
    out = run_program("veragmil-robomimic-states-to-obs", *args, cwd=tmp_path).stdout
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".extracted")) == []
    assert f"kept the recorded {', '.join(robomimic_obs.TORQUE_DEPENDENT_OBSERVATIONS)}" in out
    with h5py.File(dataset) as ours, h5py.File(tmp_path / "extracted.hdf5") as theirs:
        assert (
            json.loads(theirs["data"].attrs["env_args"])[VARIANTS_KEY]
            == json.loads(ours["data"].attrs["env_args"])[VARIANTS_KEY]
        )
        assert json.loads(theirs["data"].attrs["env_args"])["env_name"] == "ScoopGranular"
        assert {k: list(theirs["mask"][k]) for k in ours["mask"]} == {k: list(ours["mask"][k]) for k in ours["mask"]}
        for name, (food, n_grains) in zip(demo_names(ours), RECORDED):
            mine, extracted = ours[f"data/{name}"], theirs[f"data/{name}"]
            assert extracted.attrs["food"] == food
            assert {"robot0_eef_pos", "robot0_joint_pos", "object", "desired_pose", "overhead_image"} <= set(
                extracted["obs"]
            )
            kwargs = json.loads(extracted.attrs["env_args"])["env_kwargs"]
            assert (kwargs["food"], kwargs["n_grains"], kwargs["camera_heights"]) == (food, n_grains, size)
            assert extracted["obs/overhead_image"].shape == (STEPS, size, size, 3)
            np.testing.assert_array_equal(extracted["dones"][()], mine["dones"][()])
            # every observation comes back as recorded, the sensor's and the accelerations (carried over: they
            # read a step's torques) as well as the state's; images at another size
            assert set(robomimic_obs.TORQUE_DEPENDENT_OBSERVATIONS) <= set(extracted["obs"])
            for key in extracted["obs"]:
                if "overhead" not in key:
                    np.testing.assert_array_equal(extracted["obs"][key][()], mine["obs"][key][()], err_msg=key)
                    np.testing.assert_array_equal(
                        extracted["next_obs"][key][:-1], mine["next_obs"][key][:-1], err_msg=f"next_obs {key}"
                    )
    # a failed run leaves the earlier output as it was, and no partial file
    before = (tmp_path / "extracted.hdf5").read_bytes()
    bad = ["--dataset", dataset, "--output_name", "extracted.hdf5", "--camera_names", "nowhere"]
    assert run_program("veragmil-robomimic-states-to-obs", *bad, cwd=tmp_path, check=False).returncode != 0
    assert (tmp_path / "extracted.hdf5").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["extracted.hdf5", "mixed.hdf5"]


def test_robomimics_states_to_obs_on_the_shipped_sample(tmp_path):
    """The sample's buckwheat and pasta demos (robomimic's environment is made for its first food, rice)."""
    dataset = tmp_path / "sample.hdf5"
    keys = ("robot0_joint_pos", "robot0_eef_pos", "bowl_pos", "desired_pose", "object", "spoon_load")
    with h5py.File(ROOT / "demos" / "scoop.hdf5") as f, h5py.File(dataset, "w") as out:
        data = out.create_group("data")
        for key, value in f["data"].attrs.items():
            data.attrs[key] = value
        picked = [n for n in demo_names(f) if f["data"][n].attrs["food"] in ("buckwheat", "pasta")][::2]
        for name in picked:
            f.copy(f["data"][name], data, name=name)
    run_program("veragmil-robomimic-states-to-obs", "--dataset", dataset, "--output_name", "x.hdf5", cwd=tmp_path)
    with h5py.File(dataset) as ours, h5py.File(tmp_path / "x.hdf5") as theirs:
        assert sorted(theirs["data"]) == sorted(picked)
        for name in picked:
            # the demo's own env_args, less the cameras robomimic rendered none of
            kwargs = json.loads(theirs[f"data/{name}"].attrs["env_args"])["env_kwargs"]
            assert kwargs["food"] == ours[f"data/{name}"].attrs["food"] and "camera_names" not in kwargs
            for key in keys:  # round-off between CPUs (the sample was recorded elsewhere)
                np.testing.assert_allclose(
                    theirs[f"data/{name}/obs/{key}"][()], ours[f"data/{name}/obs/{key}"][()], rtol=0, atol=1e-9
                )


def test_an_environment_made_from_the_file_goes_through_its_foods_at_each_reset(mixed):
    robomimic_compat.install()
    import robomimic.utils.env_utils as EnvUtils
    import robomimic.utils.file_utils as FileUtils

    env_meta = FileUtils.get_env_metadata_from_dataset(dataset_path=str(mixed))
    env = EnvUtils.create_env_from_metadata(env_meta=env_meta, render=False, render_offscreen=False)
    seen = []
    for _ in range(len(RECORDED) + 1):
        env.reset()
        env.reset_to(env.get_state())  # run_trained_agent's restart: the same episode, the same food
        seen.append((env.env.food.name, env.env.n_grains))
    assert seen == RECORDED + RECORDED[:1]
    assert env.serialize()[VARIANTS_KEY] == env_meta[VARIANTS_KEY]


def test_training_rollouts_and_run_agent_cover_the_files_foods(mixed, tmp_path):
    config = json.loads(CONFIG.read_text())
    config["experiment"].update(name="mixed", epoch_every_n_steps=2, validate=False, render_video=False)
    config["experiment"]["rollout"].update(n=len(RECORDED), horizon=2, rate=1)
    config["experiment"]["save"]["every_n_epochs"] = 1
    config["train"].update(data=str(mixed), output_dir=str(tmp_path), num_epochs=1, batch_size=8)
    config["train"].update(hdf5_filter_key=None, hdf5_validation_filter_key=None)
    path = tmp_path / "mixed.json"
    path.write_text(json.dumps(config))
    run_program("veragmil-train", "--config", path, cwd=tmp_path)
    (checkpoint,) = tmp_path.glob("mixed/*/models/*.pth")
    out = tmp_path / "rollouts.hdf5"
    args = ["--agent", checkpoint, "--n_rollouts", len(RECORDED), "--horizon", 2, "--dataset_path", out, "--seed", 0]
    run_program("veragmil-run-agent", *args, cwd=tmp_path)
    env = robosuite.make("ScoopGranular", food="pasta", n_grains=12, pile_variants=1, has_offscreen_renderer=False,
                         use_camera_obs=False)  # fmt: skip
    with h5py.File(out) as f:
        assert [_scene(env, f["data"][n].attrs["model_file"]) for n in demo_names(f)] == RECORDED
    env.close()
