"""
Training through the console entry points: robomimic's stock BC, BC-RNN and BCQ train a few steps on a tiny
ScoopGranular dataset with validation and a rollout on, write a checkpoint and a video, and the checkpoint loads and
acts; failed runs exit non-zero.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import h5py
import mujoco
import numpy as np
import pytest
from helpers.tiny_dataset import record_tiny_dataset

from veragmil_suite.learning import robomimic_compat

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs" / "json"
BIN = Path(sys.executable).parent
ACTION_DIM = 6  # OSC_POSE delta; the spoon has no gripper DoF
EPISODE_STEPS = 20
ROLLOUT_HORIZON = 5


def _run(command, *args, timeout=300):
    return subprocess.run(
        [str(BIN / command), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,  # a prompt would fail instead of hanging
    )


def _tiny_config(name, dataset, out_dir, experiment, **train):
    """One of our configs shrunk to a few gradient steps and one short rollout (with video)."""
    with open(CONFIG_DIR / f"{name}.json") as f:
        config = json.load(f)
    config["experiment"].update(
        name=experiment,
        epoch_every_n_steps=3,
        validation_epoch_every_n_steps=1,
        validate=True,
        render_video=True,
    )
    config["experiment"]["rollout"].update(n=1, horizon=ROLLOUT_HORIZON, rate=1)
    config["experiment"]["save"]["every_n_epochs"] = 1
    config["train"].update(
        data=str(dataset),
        output_dir=str(out_dir),
        num_epochs=1,
        # the validation split (one 20-step episode) is smaller than a batch: robomimic's loader, which drops its
        # last batch, would serve no batch at all
        batch_size=32,
        hdf5_filter_key="train",
        hdf5_validation_filter_key="valid",
    )
    config["train"].update(train)
    path = Path(out_dir) / f"{experiment}.json"
    path.write_text(json.dumps(config, indent=2))
    return path


def _printed_json(text, heading):
    """The JSON block robomimic prints under a heading line."""
    match = re.search(re.escape(heading) + r"[^\n]*\n(?:Env: [^\n]*\n)?(\{.*?\n\})", text, re.S)
    assert match, f"robomimic printed no '{heading}' block"
    return json.loads(match.group(1))


@pytest.fixture(scope="module")
def low_dim_dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "tiny.hdf5"
    return record_tiny_dataset(str(path), episodes=4, steps=EPISODE_STEPS, valid_episodes=1)


@pytest.fixture(scope="module")
def trained(low_dim_dataset, tmp_path_factory):
    """Trains each algorithm once per module (lazily) and returns its process result and run folder."""
    runs = {}
    out = tmp_path_factory.mktemp("runs")

    def train(algo):
        if algo not in runs:
            config = _tiny_config(algo, low_dim_dataset, out, f"tiny_{algo}")
            result = _run("veragmil-train", "--config", config)
            run_dirs = sorted((out / f"tiny_{algo}").iterdir())
            runs[algo] = (result, run_dirs)
        return runs[algo]

    return train


@pytest.mark.parametrize("algo", ["bc", "bc_rnn", "bcq"])
def test_training_with_rollouts_writes_checkpoint_and_video(trained, algo):
    result, run_dirs = trained(algo)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "finished run successfully!" in result.stdout
    assert len(run_dirs) == 1
    run = run_dirs[0]
    train_log = _printed_json(result.stdout, "Train Epoch 1")
    assert np.isfinite(train_log["Loss"])
    valid_log = _printed_json(result.stdout, "Validation Epoch 1")
    assert np.isfinite(valid_log["Loss"])
    rollout = _printed_json(result.stdout, "Epoch 1 Rollouts took")
    assert rollout["Horizon"] == ROLLOUT_HORIZON
    checkpoints = list((run / "models").glob("*.pth"))
    assert len(checkpoints) == 1
    videos = list((run / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
    assert json.loads((run / "config.json").read_text())["algo_name"] == ("bcq" if algo == "bcq" else "bc")


@pytest.mark.parametrize("algo", ["bc", "bc_rnn", "bcq"])
def test_checkpoint_loads_and_acts(trained, algo):
    import torch

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils

    result, run_dirs = trained(algo)
    assert result.returncode == 0, result.stderr[-3000:]
    (checkpoint,) = (run_dirs[0] / "models").glob("*.pth")
    policy, ckpt = FileUtils.policy_from_checkpoint(ckpt_path=str(checkpoint), device=torch.device("cpu"))
    saved = ckpt["model"]
    loaded = policy.policy.nets.state_dict()
    assert saved.keys() == loaded.keys() and all(torch.equal(saved[k], loaded[k]) for k in saved)
    env, _ = FileUtils.env_from_checkpoint(ckpt_dict=ckpt)
    assert env.name == "ScoopGranular"
    policy.start_episode()
    obs = env.reset()
    start = obs["robot0_eef_pos"].copy()
    for _ in range(3):
        action = policy(ob=obs)
        assert action.shape == (ACTION_DIM,) and np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1)
        obs, reward, done, info = env.step(action)
        assert not info["physics_error"]
    assert np.linalg.norm(obs["robot0_eef_pos"] - start) > 0
    env.env.close()


def test_run_agent_entry_point_rolls_out_and_records(trained, tmp_path):
    result, run_dirs = trained("bc")
    assert result.returncode == 0, result.stderr[-3000:]
    (checkpoint,) = (run_dirs[0] / "models").glob("*.pth")
    out = tmp_path / "rollouts.hdf5"
    agent = _run("veragmil-run-agent", "--agent", checkpoint, "--n_rollouts", 1, "--horizon", 4, "--dataset_path", out)
    assert agent.returncode == 0, agent.stdout[-3000:] + agent.stderr[-3000:]
    with h5py.File(out, "r") as f:
        demo = f["data/demo_0"]
        assert demo["actions"].shape == (4, ACTION_DIM)
        # the recorded model is this simulation's (robosuite 1.5 alone returns the last compiled model's XML)
        model = mujoco.MjModel.from_xml_string(demo.attrs["model_file"])
        assert demo["states"].shape == (4, 1 + model.nq + model.nv)
        assert json.loads(f["data"].attrs["env_args"])["env_name"] == "ScoopGranular"


def test_image_training_renders_rgb_and_depth_in_rollouts(tmp_path):
    import torch

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils

    dataset = record_tiny_dataset(
        str(tmp_path / "rgbd.hdf5"), episodes=3, steps=8, camera_names=("overhead",), camera_depths=True
    )
    config = _tiny_config("bc_rnn_rgbd", dataset, tmp_path, "tiny_rgbd", batch_size=4, seq_length=3)
    data = json.loads(config.read_text())
    data["algo"]["rnn"]["horizon"] = 3
    data["experiment"]["epoch_every_n_steps"] = 1
    config.write_text(json.dumps(data))
    result = _run("veragmil-train", "--config", config)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert _printed_json(result.stdout, "Epoch 1 Rollouts took")["Horizon"] == ROLLOUT_HORIZON
    (checkpoint,) = (tmp_path / "tiny_rgbd").glob("*/models/*.pth")
    policy, ckpt = FileUtils.policy_from_checkpoint(ckpt_path=str(checkpoint), device=torch.device("cpu"))
    env, _ = FileUtils.env_from_checkpoint(ckpt_dict=ckpt)
    policy.start_episode()
    obs = env.reset()
    assert obs["overhead_image"].shape == (3, 84, 84) and obs["overhead_image"].dtype == np.float32
    assert obs["overhead_depth"].shape == (1, 84, 84)
    assert policy(ob=obs).shape == (ACTION_DIM,)
    env.env.close()


def test_a_config_whose_dataset_is_missing_is_refused_before_training(tmp_path):
    config = _tiny_config("bc", tmp_path / "missing.hdf5", tmp_path, "missing")
    result = _run("veragmil-train", "--config", config)
    assert result.returncode == 2
    assert f"veragmil-train: --config's train.data: {tmp_path / 'missing.hdf5'}: no such file" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "missing").exists()


def test_training_split_smaller_than_a_batch_fails_clearly(low_dim_dataset, tmp_path):
    """robomimic's train.py catches a failed run's error and would exit 0: ours exits non-zero, saying so."""
    config = _tiny_config("bc", low_dim_dataset, tmp_path, "big_batch", batch_size=1000)
    result = _run("veragmil-train", "--config", config)
    assert result.returncode != 0
    assert "fewer than one batch" in result.stdout and "training failed" in result.stderr
    assert "finished run successfully!" not in result.stdout


def test_normalize_obs_takes_any_leading_dimensions_and_leaves_extra_keys():
    robomimic_compat.install()
    import robomimic.utils.obs_utils as ObsUtils

    stats = {"a": {"mean": np.array([[1.0, 2.0]]), "std": np.array([[2.0, 4.0]])}}
    expected = np.array([0.5, 0.5])
    for shape in [(), (5,), (5, 10)]:  # a rollout step, a batch, a batch of sequences
        obs = {"a": np.broadcast_to([2.0, 4.0], (*shape, 2)), "extra": np.zeros(3)}
        out = ObsUtils.normalize_obs(obs, obs_normalization_stats=stats)
        np.testing.assert_allclose(out["a"], np.broadcast_to(expected, (*shape, 2)))
        assert out["extra"] is obs["extra"] and obs["a"][..., 0].max() == 2.0  # the caller's dict is unchanged
    with pytest.raises(ValueError, match=r"observation 'a' of shape \(5, 3\) does not end in .* \(2,\)"):
        ObsUtils.normalize_obs({"a": np.zeros((5, 3))}, obs_normalization_stats=stats)


def test_bc_rnn_trains_on_normalized_observations_once_and_its_policy_normalizes_in_rollouts(low_dim_dataset, tmp_path):
    """robomimic 0.3.0 failed on the first batch with train.hdf5_normalize_obs; the samples are normalized by the
    dataset alone, and the checkpoint carries the statistics its rollouts use."""
    import torch

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils
    from robomimic.algo.algo import Algo
    from robomimic.utils.dataset import SequenceDataset

    # robomimic 0.3.0 refuses validation with normalization
    config = _tiny_config(
        "bc_rnn", low_dim_dataset, tmp_path, "normalized", hdf5_normalize_obs=True, hdf5_validation_filter_key=None
    )
    spec = json.loads(config.read_text())
    spec["experiment"].update(validate=False, rollout=dict(spec["experiment"]["rollout"], enabled=False))
    config.write_text(json.dumps(spec))
    result = _run("veragmil-train", "--config", config)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    (checkpoint,) = (tmp_path / "normalized").glob("*/models/*.pth")
    policy, ckpt = FileUtils.policy_from_checkpoint(ckpt_path=str(checkpoint), device=torch.device("cpu"))
    stats = ckpt["obs_normalization_stats"]
    keys = spec["observation"]["modalities"]["obs"]["low_dim"]
    assert sorted(stats) == sorted(keys) and policy.obs_normalization_stats is not None

    # a sequence sample is normalized once, by the dataset: postprocessing the batch leaves it so
    seq = spec["train"]["seq_length"]
    dataset = SequenceDataset(
        hdf5_path=str(low_dim_dataset), obs_keys=keys, dataset_keys=("actions",), seq_length=seq,
        hdf5_normalize_obs=True, filter_by_attribute="train",
    )  # fmt: skip
    sample = dataset[0]
    with h5py.File(low_dim_dataset) as f:
        demo = sorted(n.decode() for n in f["mask/train"][:])[0]
        raw = f[f"data/{demo}/obs/{keys[0]}"][:seq]
    mean, std = dataset.obs_normalization_stats[keys[0]]["mean"], dataset.obs_normalization_stats[keys[0]]["std"]
    np.testing.assert_allclose(sample["obs"][keys[0]], (raw - mean) / std, rtol=1e-5, atol=1e-6)
    batch = {"obs": {k: torch.as_tensor(v)[None] for k, v in sample["obs"].items()}}
    kept = Algo.postprocess_batch_for_training(policy.policy, batch, obs_normalization_stats=stats)
    np.testing.assert_allclose(kept["obs"][keys[0]][0].numpy(), sample["obs"][keys[0]], rtol=1e-6)


def _resumable_config(dataset, out_dir, experiment, epochs, **algo):
    """BC on the tiny dataset for ``epochs`` epochs of 3 steps, no validation or rollouts, the last epoch saved."""
    Path(out_dir).mkdir(exist_ok=True)
    config = _tiny_config("bc", dataset, out_dir, experiment, num_epochs=epochs, hdf5_validation_filter_key=None)
    spec = json.loads(config.read_text())
    spec["experiment"].update(
        validate=False, render_video=False, rollout=dict(spec["experiment"]["rollout"], enabled=False)
    )
    spec["experiment"]["save"]["every_n_epochs"] = epochs
    spec["algo"]["optim_params"]["policy"]["learning_rate"].update(algo)
    config.write_text(json.dumps(spec))
    return config


def _final_weights(out_dir, experiment, epochs):
    import torch

    (checkpoint,) = (Path(out_dir) / experiment).glob(f"*/models/model_epoch_{epochs}.pth")
    return torch.load(checkpoint, map_location="cpu", weights_only=False)["model"]


def test_a_killed_training_resumes_to_the_weights_of_an_uninterrupted_one(
    low_dim_dataset, tmp_path, capsys, monkeypatch
):
    """The resume state (optimizers, schedules, random generators) is saved at an epoch's start; a run killed
    mid-way and started again with --resume skips the finished epochs and ends with the same weights, bit for bit,
    as one that ran through. A changed config is refused (exit 2) and the state kept."""
    import signal
    import time

    import torch

    from veragmil_suite.scripts.robomimic_entry import train_main

    epochs = 40
    monkeypatch.setenv("VERAGMIL_TORCH_THREADS", "1")  # for this process's runs and the processes it starts
    monkeypatch.setenv("VERAGMIL_RESUME_EVERY_S", "0")
    whole = _resumable_config(low_dim_dataset, tmp_path / "whole", "run", epochs)
    streams = sys.stdout, sys.stderr
    assert train_main(["--config", str(whole)]) == 0  # the uninterrupted run, in this process
    assert (sys.stdout, sys.stderr) == streams  # robomimic pointed them at its log; the entry point gives them back
    assert not list((tmp_path / "whole" / "run").glob("*/resume.pth"))  # a finished run keeps no resume state

    out = tmp_path / "killed"
    config = _resumable_config(low_dim_dataset, out, "run", epochs)
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    process = subprocess.Popen([str(BIN / "veragmil-train"), "--config", str(config)], **quiet)
    deadline = time.monotonic() + 240
    while not list(out.glob("run/*/resume.pth")) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    process.send_signal(signal.SIGKILL)
    process.wait()
    (state,) = out.glob("run/*/resume.pth")
    assert not list(out.glob(f"run/*/models/model_epoch_{epochs}.pth")), "the run ended before it was killed"
    killed_after = torch.load(state, weights_only=False)["epoch"]
    assert 1 <= killed_after < epochs

    other = _resumable_config(low_dim_dataset, out, "run", epochs, initial=0.5)
    capsys.readouterr()
    assert train_main(["--config", str(other), "--resume"]) == 2  # in this process: the refusal comes before training
    refused = capsys.readouterr()
    assert f"veragmil-train: {state.parent} was trained with another config" in refused.err and state.exists()
    assert "Traceback" not in refused.out + refused.err

    # robomimic rewrites its config.json in place at every start: one a kill cut short does not stop the resume
    robomimic_config = state.parent / "config.json"
    robomimic_config.write_text(robomimic_config.read_text()[:100])
    config = _resumable_config(low_dim_dataset, out, "run", epochs)
    resumed = _run("veragmil-train", "--config", config, "--resume")
    assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-3000:]
    assert len(list(out.glob("run/*"))) == 1 and not state.exists()  # the killed run's folder, finished
    log = next(out.glob("run/*/logs/log.txt")).read_text()
    assert f"after epoch {killed_after}" in log
    assert json.loads(next(out.glob("run/*/training_seconds.json")).read_text())["seconds"] > 0
    expected, got = _final_weights(tmp_path / "whole", "run", epochs), _final_weights(out, "run", epochs)
    assert expected.keys() == got.keys()
    for key in expected:
        assert torch.equal(expected[key], got[key]), key


def test_the_config_a_run_held_is_read_from_whichever_record_is_whole(tmp_path):
    from veragmil_suite.learning import training_resume

    assert training_resume.held_config(tmp_path) is None
    (tmp_path / "config.json").write_text('{"algo_name": "bc"}')
    assert training_resume.held_config(tmp_path) == {"algo_name": "bc"}  # a run started before our record
    (tmp_path / "config.json").write_text('{"algo_na')  # robomimic's, cut short
    assert training_resume.held_config(tmp_path) is None
    (tmp_path / training_resume.HELD_CONFIG_FILE).write_text('{"algo_name": "bc_rnn"}')
    assert training_resume.held_config(tmp_path) == {"algo_name": "bc_rnn"}


def test_rollout_videos_are_written_whole_and_a_torn_one_is_never_left_under_its_name(tmp_path):
    """robomimic writes a rollout's video under its final name while it records; the run's videos are recorded in a
    folder inside and moved into place when the rollouts end, so a kill mid-rollout leaves no torn epoch video."""
    from veragmil_suite.learning import training_resume

    videos = tmp_path / "videos"
    videos.mkdir()
    (videos / training_resume.PARTIAL_VIDEO_DIR).mkdir()
    (videos / training_resume.PARTIAL_VIDEO_DIR / "old_epoch_1.mp4").write_bytes(b"torn")  # what a kill left

    class Rollouts:
        killed = False

        def rollout_with_stats(self, video_dir=None, epoch=None, **kwargs):
            path = Path(video_dir) / f"ScoopGranular_epoch_{epoch}.mp4"
            path.write_bytes(b"half")
            assert not (videos / path.name).exists()  # nothing under the final name while it records
            if self.killed:
                raise KeyboardInterrupt
            path.write_bytes(b"whole video")
            return {"ScoopGranular": {"Success_Rate": 1.0}}, {"ScoopGranular": str(path)}

    rollouts = Rollouts()
    utils = training_resume.ResumingTrainUtils(rollouts)
    logs, paths = utils.rollout_with_stats(video_dir=str(videos), epoch=2)
    assert logs == {"ScoopGranular": {"Success_Rate": 1.0}}
    assert paths == {"ScoopGranular": str(videos / "ScoopGranular_epoch_2.mp4")}
    assert (videos / "ScoopGranular_epoch_2.mp4").read_bytes() == b"whole video"
    assert sorted(p.name for p in videos.iterdir()) == ["ScoopGranular_epoch_2.mp4"]  # the kill's leftover is gone
    rollouts.killed = True
    with pytest.raises(KeyboardInterrupt):
        utils.rollout_with_stats(video_dir=str(videos), epoch=3)
    assert not (videos / "ScoopGranular_epoch_3.mp4").exists()
    assert (videos / "ScoopGranular_epoch_2.mp4").read_bytes() == b"whole video"
