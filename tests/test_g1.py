"""The Unitree G1 (robosuite-models, the "humanoid" extra): ScoopGranular places it at the table with the spoon in
its right hand and its left arm and torso held still, its action is the spoon arm's 6-D delta, the scripted expert
scoops with it, and recording, training and evaluation run on its data through the same commands; without
robosuite-models its names get one clear error."""

import json

import numpy as np
import pytest
import robosuite

from veragmil_suite.controllers.scoop_config import load_scoop_controller_config
from veragmil_suite.models import humanoid
from veragmil_suite.scripts.measure_expert import run_expert_episode
from veragmil_suite.study.settings import PipelineSettings

LIGHT = dict(food="pasta", n_grains=12, pile_variants=1)


def _make(robot, **kwargs):
    return robosuite.make(
        "ScoopGranular",
        robots=robot,
        **{**LIGHT, **kwargs},
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        seed=0,
    )


def _robot_contacts(env):
    """Contacts of the robot's own links (the spoon is the gripper's): with the table, or with itself."""
    model, data = env.sim.model, env.sim.data
    names = [
        (model.body_id2name(model.geom_bodyid[c.geom1]), model.body_id2name(model.geom_bodyid[c.geom2]))
        for c in data.contact[: data.ncon]
    ]
    return [pair for pair in names if any(name.startswith("robot0_") for name in pair)]


@pytest.mark.parametrize("robot", humanoid.G1_ROBOTS)
def test_g1_stands_at_the_table_spoon_in_hand_other_parts_held(robot):
    env = _make(robot, initialization_noise=None)
    obs = env.reset()
    g1 = env.robots[0]
    assert env.action_dim == 6  # the spoon arm's OSC_POSE delta, nothing for the left arm or the torso
    assert type(g1.gripper["right"]).__name__ == "SpoonGripper" and g1.gripper["left"].dof == 0
    # the spoon arm's pose under the single-arm keys the expert and the robomimic configs read
    np.testing.assert_array_equal(obs["robot0_eef_pos"], obs["robot0_right_eef_pos"])
    np.testing.assert_array_equal(obs["robot0_eef_quat_site"], obs["robot0_right_eef_quat_site"])
    # at the pre-scoop place above the (nominal) bowl, the spoon dipped 45 degrees, its heading free
    rim = env._nominal_rim_center()
    np.testing.assert_allclose(obs["robot0_eef_pos"], rim + env.pre_scoop_offset, atol=1e-3)
    spoon_z = env.sim.data.site_xmat[env.eef_site_id].reshape(3, 3)[:, 2]
    assert spoon_z[2] < -0.999  # the handle points straight down, as robots' pre-scoop attitude
    # close to the table, not in it, and no part touching another
    assert _robot_contacts(env) == []
    base = env.sim.data.get_body_xpos(g1.robot_model.root_body)
    assert base[0] < -env.table_full_size[0] / 2 < obs["robot0_eef_pos"][0]

    held = env._held_joint_qpos()
    joint_pos = {name: env.sim.data.qpos[env.sim.model.get_joint_qpos_addr(name)] for name in held}
    rng = np.random.default_rng(0)
    for _ in range(20):
        env.step(rng.uniform(-0.5, 0.5, 6))
    for name, value in held.items():
        assert env.sim.data.qpos[env.sim.model.get_joint_qpos_addr(name)] == pytest.approx(value, abs=2e-3), name
        assert joint_pos[name] == pytest.approx(value, abs=1e-9), name
    assert _robot_contacts(env) == []
    env.close()


def test_expert_scoops_pasta_with_the_g1():
    # 20 pieces: a lighter scene than pasta's 40, and still a portion (5% of the bowl) to carry
    result = run_expert_episode("pasta", 0, robot="G1FixedLowerBody", env_kwargs={"n_grains": 20})
    assert result["success"], result
    assert result["robot"] == "G1FixedLowerBody"
    assert result["end_reason"] == "success" and result["physics_error"] == ""
    assert result["grains_spilled"] == 0 and result["grains_in_spoon"] >= 2


def test_recording_training_and_evaluation_run_on_g1_data(tmp_path):
    from veragmil_suite.data.schema import open_dataset
    from veragmil_suite.evaluation.evaluate import evaluate
    from veragmil_suite.scripts import collect_human_demonstrations as collect
    from veragmil_suite.study.record import record_food
    from veragmil_suite.study.settings import StageError
    from veragmil_suite.study.training import train_checkpoint, training_config

    data = tmp_path / "g1.hdf5"
    argv = ["--device", "scripted", "--robot", "G1FixedLowerBody", "--food", "pasta", "--n-grains", "20"]
    assert collect.main([*argv, "--cameras", "--episodes", "1", "--output", str(data), "--quiet"]) in (0, None)
    with open_dataset(data) as f:
        demo = f["data/demo_0"]
        assert demo.attrs["robot"] == "G1FixedLowerBody" and demo.attrs["success"]
        assert demo["actions"].shape[1] == 6
        assert demo["obs/robot0_eef_pos"].shape[1] == 3

    # a study's recording of another robot does not append to it
    with pytest.raises(StageError, match=r"robot 'G1FixedLowerBody' \(asked: 'XArm7'\)"):
        record_food(data, "pasta", 2, n_grains=20, robot="XArm7")

    config = training_config("bc", data, tmp_path / "runs", "g1_bc", epochs=1, steps_per_epoch=3)
    config["train"]["batch_size"] = 16
    checkpoints, _ = train_checkpoint(config, tmp_path)
    horizon = 8
    # the operator scoops with the checkpoint's robot, unasked
    agents = {"BC": str(checkpoints[1]), "operator": "expert:expert"}
    out = tmp_path / "eval"
    result = evaluate(
        agents, foods=["pasta"], episodes=1, processes=1, horizon=horizon, progress=False, output_dir=str(out)
    )
    assert result.config["robot"] == "G1FixedLowerBody"
    assert [e.steps for e in result.episodes] == [horizon, horizon]
    assert all(e.physics_error == "" for e in result.episodes)
    journaled = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert all("G1FixedLowerBody" in json.dumps(entry) for entry in journaled)
    with pytest.raises(ValueError, match=r"one robot, XArm7, but .* BC \(G1FixedLowerBody\)"):
        evaluate(agents, foods=["pasta"], episodes=1, horizon=horizon, progress=False, robot="XArm7")


def test_g1_names_need_robosuite_models_and_a_fixed_base(monkeypatch):
    from robosuite.robots import ROBOT_CLASS_MAPPING

    with pytest.raises(ValueError, match="stands on its own legs .* G1FixedLowerBody or G1ArmsOnly"):
        humanoid.check_robot("G1")
    with pytest.raises(ValueError, match="has 2 arms"):
        humanoid.check_robot("Baxter")
    with pytest.raises(ValueError, match="stands on its own legs"):
        PipelineSettings("unused", robot="G1FloatingBody")
    with pytest.raises(ValueError, match="robosuite's IK_POSE controller needs a 7-DoF arm"):
        load_scoop_controller_config("IK_POSE", robot="G1FixedLowerBody")

    # as without robosuite-models: robosuite registers no G1
    for name in humanoid.G1_ROBOTS + humanoid.UNSUPPORTED_G1_ROBOTS:
        monkeypatch.delitem(ROBOT_CLASS_MAPPING, name)
    monkeypatch.setattr(humanoid, "robosuite_models_installed", lambda: False)
    with pytest.raises(ValueError, match=r"comes with robosuite-models, .*pip install 'veragmil_suite\[humanoid\]'"):
        _make("G1FixedLowerBody")
    with pytest.raises(ValueError, match=r"Unknown robot 'Nonexistent'; robosuite's robots: .*the G1 .* needs pip"):
        humanoid.check_robot("Nonexistent")
