"""
Diffusion Policy as a robomimic algorithm: importing veragmil_suite registers it, its U-Net, a tiny training run on
the sample data through veragmil-train whose loss falls, a checkpoint that robomimic's policy_from_checkpoint loads
to the same actions, and rollouts through robomimic's run_trained_agent and our evaluation.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers.output import warning_lines
from helpers.programs import run_program

from veragmil_suite.learning import robomimic_compat

# one worker runs this file's tests: its module fixtures are built once (make test: --dist loadgroup)
pytestmark = pytest.mark.xdist_group("diffusion_policy")

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_DATA = ROOT / "demos" / "scoop.hdf5"
ACTION_DIM = 6
EPOCHS = 3
STEPS_PER_EPOCH = 40


def _tiny_config(out_dir: Path, name: str) -> dict:
    """configs/json/diffusion_policy.json with a small U-Net, a few gradient steps and one short rollout."""
    config = json.loads((ROOT / "configs" / "json" / "diffusion_policy.json").read_text())
    config["experiment"].update(name=name, epoch_every_n_steps=STEPS_PER_EPOCH, validate=False, render_video=False)
    config["experiment"]["rollout"].update(n=1, horizon=10, rate=EPOCHS)
    config["experiment"]["save"]["every_n_epochs"] = EPOCHS
    config["train"].update(data=str(SAMPLE_DATA), output_dir=str(out_dir), num_epochs=EPOCHS, batch_size=32)
    config["algo"]["unet"].update(diffusion_step_embed_dim=32, down_dims=[32, 64])
    config["algo"]["optim_params"]["policy"]["learning_rate"].update(initial=1e-3, warmup_steps=10)
    return config


def _tiny_model(out_dir: Path, name: str):
    """The tiny config's model built in this process (seed 0), its config, shape metadata and a loader of the sample
    data."""
    import torch

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils
    import robomimic.utils.obs_utils as ObsUtils
    import robomimic.utils.train_utils as TrainUtils
    from robomimic.algo import algo_factory
    from robomimic.config import config_factory
    from torch.utils.data import DataLoader

    config = config_factory("diffusion_policy")
    with config.values_unlocked():
        config.update(_tiny_config(out_dir, name))
    ObsUtils.initialize_obs_utils_with_config(config)
    shape_meta = FileUtils.get_shape_metadata_from_dataset(str(SAMPLE_DATA), all_obs_keys=config.all_obs_keys)
    torch.manual_seed(0)
    model = algo_factory("diffusion_policy", config, shape_meta["all_shapes"], shape_meta["ac_dim"], device="cpu")
    trainset, _ = TrainUtils.load_data_for_training(config, obs_keys=shape_meta["all_obs_keys"])
    loader = DataLoader(trainset, batch_size=config.train.batch_size, shuffle=True, drop_last=True)
    return model, config, shape_meta, loader


def _epoch_losses(stdout: str) -> list[float]:
    return [float(v) for v in re.findall(r"Train Epoch \d+\n\{\n\s+\"Loss\": ([0-9.e+-]+)", stdout)]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """One tiny veragmil-train run of diffusion_policy on the sample data: its process result and checkpoint."""
    out = tmp_path_factory.mktemp("dp")
    config = out / "dp.json"
    config.write_text(json.dumps(_tiny_config(out / "runs", "tiny_dp")))
    result = run_program("veragmil-train", "--config", config, check=False)
    checkpoints = sorted((out / "runs" / "tiny_dp").glob("*/models/*.pth"))
    return result, checkpoints


def test_importing_veragmil_suite_registers_diffusion_policy_without_importing_torch():
    code = """
import sys
import veragmil_suite
assert "torch" not in sys.modules and "robomimic" not in sys.modules
from veragmil_suite.learning import robomimic_compat
robomimic_compat.install()
from robomimic.algo import algo_name_to_factory_func
from robomimic.config import config_factory
config = config_factory("diffusion_policy")
print(algo_name_to_factory_func("diffusion_policy")(config.algo)[0].__name__, config.algo.horizon.prediction_horizon)
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.split()[-2:] == ["DiffusionPolicyUNet", "16"]
    # robomimic imported first: registered when veragmil_suite is imported
    code = (
        "import robomimic.config, veragmil_suite; print(robomimic.config.config_factory('diffusion_policy').algo_name)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0 and result.stdout.split()[-1] == "diffusion_policy", result.stderr[-3000:]


def test_unet_predicts_a_sequence_of_the_samples_shape_from_its_conditioning():
    import torch

    from veragmil_suite.learning.algos.conditional_unet1d import ConditionalUnet1D

    torch.manual_seed(0)
    net = ConditionalUnet1D(input_dim=ACTION_DIM, global_cond_dim=10, diffusion_step_embed_dim=16, down_dims=(16, 32))
    sample, cond = torch.randn(3, 16, ACTION_DIM), torch.randn(3, 10)
    out = net(sample, torch.tensor([0, 5, 99]), cond)
    assert out.shape == sample.shape
    assert not torch.allclose(out, net(sample, torch.tensor([0, 5, 99]), cond + 1))  # FiLM conditions it
    assert torch.allclose(net(sample, 7, cond), net(sample, torch.tensor([7, 7, 7]), cond))
    with pytest.raises(ValueError, match="sequence length 15 is not a multiple of the U-Net's 2"):
        net(torch.randn(3, 15, ACTION_DIM), 0, cond)


def test_windows_that_do_not_match_the_horizons_are_refused_naming_the_settings(tmp_path):
    robomimic_compat.install()
    from robomimic.algo import algo_factory
    from robomimic.config import config_factory

    config = config_factory("diffusion_policy")
    with config.values_unlocked():
        config.update(_tiny_config(tmp_path, "x"))
        config.train.frame_stack = 1
    with pytest.raises(ValueError, match=r"set train.frame_stack = 2 and train.seq_length = 15 \(got 1 and 15\)"):
        algo_factory("diffusion_policy", config, {"robot0_eef_pos": [3]}, ACTION_DIM, device="cpu")


def test_tiny_training_on_the_sample_data_lowers_the_loss(trained):
    result, checkpoints = trained
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "finished run successfully!" in result.stdout
    losses = _epoch_losses(result.stdout)
    assert len(losses) == EPOCHS and all(np.isfinite(losses))
    assert losses[-1] < 0.6 * losses[0], losses  # noise prediction starts near 1 (unit-variance noise)
    assert re.search(r"Epoch 3 Rollouts took .*\n.*\n\{\n\s+\"Horizon\": 10", result.stdout)  # framestacked env
    assert len(checkpoints) == 1


def test_a_checkpoint_round_trip_through_policy_from_checkpoint_gives_the_same_actions(tmp_path):
    """A model trained in this process, saved by robomimic and loaded by policy_from_checkpoint, acts the same over
    two action chunks, from the EMA weights it was saved with."""
    import torch

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils
    import robomimic.utils.train_utils as TrainUtils
    from robomimic.algo import RolloutPolicy

    model, config, shape_meta, loader = _tiny_model(tmp_path, "round_trip")
    TrainUtils.run_epoch(model=model, data_loader=loader, epoch=1, num_steps=5)
    trained = dict(model.nets.named_parameters())
    ema = dict(model._acting_nets().named_parameters())
    assert any(not torch.equal(trained[k], ema[k]) for k in trained)  # the EMA lags the trained weights
    path = tmp_path / "model.pth"
    env_meta = FileUtils.get_env_metadata_from_dataset(str(SAMPLE_DATA))
    TrainUtils.save_model(model, config, env_meta, shape_meta, str(path))
    loaded, _ = FileUtils.policy_from_checkpoint(ckpt_path=str(path), device=torch.device("cpu"))

    with h5py.File(SAMPLE_DATA, "r") as f:
        demo = f["data/demo_0/obs"]
        observations = [{k: demo[k][t] for k in shape_meta["all_obs_keys"]} for t in range(12)]

    def actions(policy):
        torch.manual_seed(3)
        policy.start_episode()
        return np.array([policy(ob=ob) for ob in observations])

    original = actions(RolloutPolicy(model))
    assert original.shape == (12, ACTION_DIM) and np.all(np.isfinite(original))
    np.testing.assert_array_equal(actions(loaded), original)
    assert not np.allclose(original[0], original[8])  # the second chunk is a new prediction


def test_a_gradient_step_reports_robomimics_gradient_norm_and_moves_the_ema_by_its_decay(tmp_path):
    """The squared gradient norm summed on the device is robomimic's (the sum over weights of their squared norms),
    and the EMA's fused update is the decay's: shadow - (1 - decay) x (shadow - weight)."""
    import torch

    model, _, _, loader = _tiny_model(tmp_path, "one_step")
    batch = next(iter(loader))
    batch = model.postprocess_batch_for_training(model.process_batch_for_training(batch), obs_normalization_stats=None)
    model.set_train()
    model.train_on_batch(batch, epoch=1)  # the warm-up's first decay is 0: the EMA starts at the weights
    shadow_before = [s.clone() for s in model.ema.shadow_params]
    info = model.train_on_batch(batch, epoch=1)
    params = list(model.nets.parameters())
    expected = sum(p.grad.norm(2).pow(2).item() for p in params if p.grad is not None)
    assert model.log_info(info)["Policy_Grad_Norms"] == pytest.approx(expected, rel=1e-5)
    decay = model.ema.cur_decay_value
    assert 0 < decay < 1
    for before, after, weight in zip(shadow_before, model.ema.shadow_params, params):
        torch.testing.assert_close(after, before - (1 - decay) * (before - weight.detach()))


def test_run_agent_rolls_the_checkpoint_out_in_a_framestacked_env(trained, tmp_path):
    result, checkpoints = trained
    assert result.returncode == 0, result.stderr[-3000:]
    out = tmp_path / "rollouts.hdf5"
    agent = run_program("veragmil-run-agent", "--agent", checkpoints[0], "--n_rollouts", 1, "--horizon", 10,
                 "--dataset_path", out, check=False)  # fmt: skip
    assert agent.returncode == 0, agent.stdout[-3000:] + agent.stderr[-3000:]
    # quiet, like the other algorithms (test_quiet.py): no warning in training or in the rollout
    for run in (result, agent):
        warned = warning_lines((run.stdout + run.stderr).splitlines())
        assert not warned, warned
    with h5py.File(out, "r") as f:
        actions = f["data/demo_0/actions"][:]
    assert actions.shape == (10, ACTION_DIM) and np.all(np.isfinite(actions)) and np.all(np.abs(actions) <= 1)


def test_evaluation_rolls_the_checkpoint_out_one_observation_at_a_time(trained):
    from veragmil_suite.evaluation.evaluate import evaluate

    result, checkpoints = trained
    assert result.returncode == 0, result.stderr[-3000:]
    scored = evaluate(
        {"DP": str(checkpoints[0])},
        foods=["pasta"],
        episodes=1,
        processes=1,
        seed=5,
        horizon=12,
        env_kwargs={"n_grains": 12, "pile_variants": 1},
        progress=False,
    )
    (episode,) = scored.episodes
    assert episode.steps == 12 and episode.end_reason == "horizon" and not episode.physics_error
