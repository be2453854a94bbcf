"""
The robomimic 0.3.0 / robosuite 1.5 compatibility layer, gap by gap, and how robomimic's scripts are reached through
our entry points (tests/test_dataset_tools.py runs those scripts on a recorded file).
"""

import builtins
import importlib.util
import subprocess
import sys
import time
import types
from pathlib import Path

import h5py
import mujoco
import numpy as np
import pytest
from helpers.programs import run_program
from helpers.tiny_dataset import SCOOP_KWARGS, default_controller_config

from veragmil_suite.learning import robomimic_compat, robomimic_scripts

robomimic_compat.install()

import robomimic.utils.obs_utils as ObsUtils  # noqa: E402
from robomimic.envs.env_robosuite import EnvRobosuite  # noqa: E402

TASK_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_joint_pos", "desired_pose", "object")


def _scoop_env(**kwargs):
    args = dict(SCOOP_KWARGS, controller_configs=default_controller_config("ScoopGranular", "XArm7"))
    args.update(kwargs)
    return EnvRobosuite("ScoopGranular", postprocess_visual_obs=False, **args)


def _low_dim_specs(rgb=(), depth=()):
    ObsUtils.initialize_obs_utils_with_obs_specs(
        {"obs": {"low_dim": list(TASK_KEYS), "rgb": list(rgb), "depth": list(depth)}}
    )


# ---------------------------------------------------------------------------------------------------------------- #
# Imports                                                                                                            #
# ---------------------------------------------------------------------------------------------------------------- #


def test_mujoco_py_stand_in_names_mujocos_error():
    import mujoco_py

    if "veragmil_suite" in (mujoco_py.__doc__ or ""):  # no real mujoco_py installed
        assert mujoco_py.builder.MujocoException is mujoco.FatalError
        assert importlib.util.find_spec("mujoco_py") is mujoco_py.__spec__
    env = _scoop_env()
    assert issubclass(mujoco.FatalError, env.rollout_exceptions)
    env.env.close()


def test_torchvision_ops_are_defined_only_when_its_import_failed():
    import torch
    import torchvision

    defined = robomimic_compat.DEFINED_TORCHVISION_OPS
    assert bool(defined) == (not torchvision.extension._has_ops())
    assert set(defined) <= {"nms", "qnms"}
    for name in defined:
        assert torch._C._dispatch_has_kernel_for_dispatch_key(f"torchvision::{name}", "Meta")
    net = torchvision.models.resnet18()  # what robomimic's visual encoder builds on
    assert net(torch.zeros(1, 3, 84, 84)).shape == (1, 1000)


def test_install_is_idempotent():
    robomimic_compat.install()
    robomimic_compat.install()
    from robomimic.envs.env_base import EnvType
    from robomimic.utils import env_utils

    from veragmil_suite.learning.env_robosuite import EnvRobosuite15

    assert EnvRobosuite is EnvRobosuite15  # bound where robomimic looks its robosuite env class up
    assert env_utils.get_env_class(env_type=EnvType.ROBOSUITE_TYPE) is EnvRobosuite15


# ---------------------------------------------------------------------------------------------------------------- #
# robosuite 1.5 environments                                                                                         #
# ---------------------------------------------------------------------------------------------------------------- #


def test_observations_keep_task_keys_and_drop_empty_and_concatenated_ones():
    _low_dim_specs()
    env = _scoop_env()
    obs = env.reset()
    assert set(TASK_KEYS) <= set(obs)
    assert obs["object"].shape == (15,)  # desired_pose, bowl_pos, spoon_to_desired_pos, spoon_load
    assert "robot0_gripper_qpos" not in obs  # the spoon has no gripper joints: robosuite gives shape (0,)
    assert not any(k.endswith("-state") for k in obs)
    assert all(v.size > 0 for v in obs.values())
    env.env.close()


def test_step_observes_the_state_reached_and_state_keeps_this_simulations_xml():
    _low_dim_specs()
    env = _scoop_env()
    env.reset()
    for _ in range(3):
        before = env.step(np.full(6, 0.3))[0]
    state = env.get_state()
    # compiling another model makes robosuite's sim.model.get_xml() return that model's XML
    other = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    assert env.get_state()["model"] == state["model"]
    model = mujoco.MjModel.from_xml_string(state["model"])
    assert (model.nq, model.nv) == (env.env.sim.model.nq, env.env.sim.model.nv) != (other.nq, other.nv)

    fresh = _scoop_env()
    fresh.reset()
    after = fresh.reset_to(state)
    for key in TASK_KEYS:
        np.testing.assert_allclose(after[key], before[key], atol=1e-9, err_msg=key)
    env.env.close()
    fresh.env.close()


def test_images_are_upright_under_either_image_convention(monkeypatch):
    import robosuite.macros

    _low_dim_specs(rgb=["overhead_image"], depth=["overhead_depth"])
    images = {}
    for convention in ("opengl", "opencv"):
        monkeypatch.setattr(robosuite.macros, "IMAGE_CONVENTION", convention)
        env = _scoop_env(seed=3, camera_names=["overhead"], camera_depths=True)
        env.postprocess_visual_obs = False
        images[convention] = env.reset()
        env.env.close()
    for key in ("overhead_image", "overhead_depth"):
        np.testing.assert_array_equal(images["opengl"][key], images["opencv"][key])
    # upright: the table (light, near) fills the bottom rows; under opengl robosuite alone gives it upside down
    depth = images["opengl"]["overhead_depth"][..., 0]
    assert depth[-5:].mean() < depth[:5].mean()


def test_depth_policy_renders_depth_without_rgb_keys():
    _low_dim_specs(depth=["overhead_depth"])
    env = EnvRobosuite(
        "ScoopGranular",
        use_image_obs=False,  # robomimic decides this from rgb keys only
        camera_names=["overhead"],
        controller_configs=default_controller_config("ScoopGranular", "XArm7"),
        **{k: v for k, v in SCOOP_KWARGS.items()},
    )
    obs = env.reset()
    assert obs["overhead_depth"].shape == (1, 84, 84) and obs["overhead_depth"].dtype == np.float32
    assert env.serialize()["env_kwargs"]["camera_depths"] is True
    env.env.close()


def test_env_kwargs_with_env_name_and_a_robosuite_14_controller_config():
    import robomimic.utils.env_utils as EnvUtils
    from robosuite.controllers import load_part_controller_config

    _low_dim_specs()
    legacy = load_part_controller_config(default_controller="OSC_POSE")  # robosuite <= 1.4 datasets store this
    env_meta = dict(
        env_name="Lift", type=1, env_kwargs=dict(env_name="Lift", robots=["Panda"], controller_configs=legacy)
    )
    env = EnvUtils.create_env_from_metadata(env_meta=env_meta)
    assert env.action_dimension == 7
    assert env.serialize()["env_kwargs"]["controller_configs"]["body_parts"]["right"]["type"] == "OSC_POSE"
    env.env.close()


def test_step_reports_the_environments_own_termination():
    _low_dim_specs()
    env = _scoop_env()
    env.reset()
    assert env.step(np.zeros(6))[2] is False  # robomimic's environments run to the caller's horizon
    env.env._physics_error = "simulated blow-up"  # how ScoopGranular ends an episode on a physics error
    obs, reward, done, info = env.step(np.zeros(6))
    assert done is True and info["physics_error"] == "simulated blow-up"
    env.env.close()


# ---------------------------------------------------------------------------------------------------------------- #
# robomimic's train.py                                                                                               #
# ---------------------------------------------------------------------------------------------------------------- #


def _config(output_dir, name="exp", save=True):
    from robomimic.config import config_factory

    config = config_factory("bc")
    with config.values_unlocked():
        config.train.output_dir = output_dir
        config.experiment.name = name
        config.experiment.save.enabled = save
    return config


def test_experiment_dirs_relative_to_cwd_never_prompt_nor_delete(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(builtins, "input", lambda *a: pytest.fail("prompted"))
    config = _config("runs")
    first = robomimic_scripts.experiment_dirs(config)
    marker = Path(first[0]) / "kept.txt"
    marker.write_text("earlier run")
    second = robomimic_scripts.experiment_dirs(config)  # same second, same experiment
    assert Path(first[0]).parent != Path(second[0]).parent
    assert marker.read_text() == "earlier run"
    for log_dir, model_dir, video_dir in (first, second):
        assert Path(log_dir).is_relative_to(tmp_path / "runs" / "exp")
        assert Path(log_dir).is_dir() and Path(model_dir).is_dir() and Path(video_dir).is_dir()
    assert robomimic_scripts.experiment_dirs(_config("runs", save=False))[1] is None


def test_train_script_records_errors_and_keeps_the_last_validation_batch():
    module = types.ModuleType("fake_train")

    def train(config, device):
        loader = module.DataLoader(valid, batch_size=4, drop_last=True)
        assert len(list(loader)) == 1  # 3 samples, batch 4: robomimic's loader would serve none
        raise RuntimeError("boom")

    class Split(list):
        def __init__(self, n, key):
            super().__init__(np.zeros((n, 2), dtype=np.float32))
            self.filter_by_attribute = key

    valid = Split(3, "valid")
    module.train = train
    outcome = robomimic_scripts.prepare_train_script(module)
    config = _config("runs")
    with config.values_unlocked():
        config.experiment.validate = True
        config.train.hdf5_filter_key = "train"
        config.train.hdf5_validation_filter_key = "valid"
    with pytest.raises(RuntimeError, match="boom"):
        module.train(config, device=None)
    assert outcome.failed and str(outcome.error) == "boom"
    with pytest.raises(ValueError, match="fewer than one batch"):
        module.DataLoader(Split(3, "train"), batch_size=4, drop_last=True)


def test_torch_threads_of_a_training_run_follow_the_environment(monkeypatch):
    import torch

    module = types.ModuleType("fake_train")
    seen = []

    def train(config, device):
        torch.set_num_threads(2)  # what robomimic's train() does
        seen.append(torch.get_num_threads())

    module.train = train
    before, set_num_threads = torch.get_num_threads(), torch.set_num_threads
    monkeypatch.setenv("VERAGMIL_TORCH_THREADS", "1")
    robomimic_scripts.prepare_train_script(module)
    module.train(_config("runs"), device=None)
    monkeypatch.delenv("VERAGMIL_TORCH_THREADS")
    robomimic_scripts.prepare_train_script(module)
    module.train(_config("runs"), device=None)
    assert seen == [1, 2] and torch.set_num_threads is set_num_threads
    torch.set_num_threads(before)


def test_no_prompts_turns_input_into_an_error():
    saved = builtins.input
    with robomimic_scripts.no_prompts():
        with pytest.raises(RuntimeError, match="never prompt"):
            input("overwrite? (y/n)")
    assert builtins.input is saved


# ---------------------------------------------------------------------------------------------------------------- #
# robomimic's scripts through our entry points                                                                       #
# ---------------------------------------------------------------------------------------------------------------- #


def test_a_failing_script_exits_nonzero(tmp_path):
    result = run_program(
        "veragmil-robomimic-dataset-info", "--dataset", tmp_path / "missing.hdf5", check=False, timeout=300
    )
    assert result.returncode != 0


def test_module_form_dispatches_to_the_same_commands():
    usage = subprocess.run(
        [sys.executable, "-m", "veragmil_suite.scripts.robomimic_entry", "nonsense"], capture_output=True, text=True
    )
    # one line on stderr naming the commands
    said = usage.stderr.strip().splitlines()
    assert usage.returncode == 2 and len(said) == 1 and "unknown command 'nonsense'; accepted: train, " in said[0]
    started = time.time()
    helped = subprocess.run(
        [sys.executable, "-m", "veragmil_suite.scripts.robomimic_entry", "train", "--help"],
        capture_output=True,
        text=True,
    )
    assert helped.returncode == 0 and "--dataset" in helped.stdout
    assert time.time() - started < 120


def test_recorded_observations_are_carried_only_where_their_shapes_match(tmp_path):
    """states-to-obs' carry of the torque-dependent observations: the recorded obs over robomimic's; next_obs from the
    recorded next_obs when it has the output's shape, else the recorded obs one step on; an obs of another shape left
    as robomimic read it."""
    from veragmil_suite.learning.robomimic_obs import TORQUE_DEPENDENT_OBSERVATIONS

    acc, force = TORQUE_DEPENDENT_OBSERVATIONS[:2]
    recorded = np.arange(15.0).reshape(5, 3)
    with h5py.File(tmp_path / "source.hdf5", "w") as f:
        f[f"data/demo_0/obs/{force}"] = recorded
        f[f"data/demo_0/next_obs/{force}"] = np.zeros((4, 3))  # another shape than the output's
        f[f"data/demo_0/obs/{acc}"] = np.ones((4, 3))  # another shape than the output's
    with h5py.File(tmp_path / "output.hdf5", "w") as f:
        for key in (acc, force):
            f[f"data/demo_0/obs/{key}"] = np.full((5, 3), -1.0)
            f[f"data/demo_0/next_obs/{key}"] = np.full((5, 3), -1.0)
    carried = robomimic_scripts._carry_recorded_observations(
        str(tmp_path / "source.hdf5"), str(tmp_path / "output.hdf5")
    )
    assert carried == [force]
    with h5py.File(tmp_path / "output.hdf5") as f:
        np.testing.assert_array_equal(f[f"data/demo_0/obs/{force}"][()], recorded)
        np.testing.assert_array_equal(f[f"data/demo_0/next_obs/{force}"][:-1], recorded[1:])
        np.testing.assert_array_equal(f[f"data/demo_0/next_obs/{force}"][-1], np.full(3, -1.0))
        np.testing.assert_array_equal(f[f"data/demo_0/obs/{acc}"][()], np.full((5, 3), -1.0))


def _writing_script(fail: bool) -> types.ModuleType:
    """A stand-in for robomimic's run_trained_agent: opens its video and dataset in place, as robomimic does."""

    def run_trained_agent(args):
        Path(args.video_path).write_bytes(b"half a video")
        with h5py.File(args.dataset_path, "w") as f:
            f.create_group("data")
            if fail:
                raise RuntimeError("killed part-way")

    return types.SimpleNamespace(run_trained_agent=run_trained_agent)


def test_run_agent_outputs_are_written_whole_or_left_as_they_were(tmp_path):
    """veragmil-run-agent's --video_path and --dataset_path (robomimic opens both in place; --force replaces them):
    a run that fails part-way leaves the earlier files and no temporary one; one that ends puts the new ones in
    place."""
    video, dataset = tmp_path / "rollouts.mp4", tmp_path / "rollouts.hdf5"
    video.write_bytes(b"the earlier video")
    with h5py.File(dataset, "w") as f:
        f.create_group("earlier")
    args = types.SimpleNamespace(video_path=str(video), dataset_path=str(dataset))
    failing = _writing_script(fail=True)
    robomimic_scripts.prepare_outputs_whole(failing, "run_trained_agent", ("dataset_path",))
    with pytest.raises(RuntimeError):
        failing.run_trained_agent(args)
    assert video.read_bytes() == b"the earlier video" and list(h5py.File(dataset, "r")) == ["earlier"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rollouts.hdf5", "rollouts.mp4"]
    assert (args.video_path, args.dataset_path) == (str(video), str(dataset))
    ending = _writing_script(fail=False)
    robomimic_scripts.prepare_outputs_whole(ending, "run_trained_agent", ("dataset_path",))
    ending.run_trained_agent(args)
    assert video.read_bytes() == b"half a video" and list(h5py.File(dataset, "r")) == ["data"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rollouts.hdf5", "rollouts.mp4"]
