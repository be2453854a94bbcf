"""The demonstration file: robomimic's schema key by key, exact replay, append, crash safety, clear errors."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers.env import pinned_mujoco_version
from helpers.recording import CAMERA_SIZE, make_env, record_file, synthetic_episode, synthetic_writer, tiny_env_kwargs

from veragmil_suite.data.recording import EpisodeRecorder
from veragmil_suite.data.schema import DatasetError, env_meta, open_dataset, provenance
from veragmil_suite.data.writer import DemoWriter
from veragmil_suite.evaluation.agents import parse_spec
from veragmil_suite.learning import robomimic_obs
from veragmil_suite.scripts.dataset_tools import info_main, split_main

ROBOT_KEYS = {
    "robot0_joint_pos": (7,),
    "robot0_joint_pos_cos": (7,),
    "robot0_joint_pos_sin": (7,),
    "robot0_joint_vel": (7,),
    "robot0_joint_acc": (7,),
    "robot0_eef_pos": (3,),
    "robot0_eef_quat": (4,),
    "robot0_eef_quat_site": (4,),
}
OBJECT_KEYS = {"desired_pose": (7,), "bowl_pos": (3,), "spoon_to_desired_pos": (3,), "spoon_load": (2,)}
# the task's observables outside ``object`` (a modality of their own)
GOAL_KEYS = {"spoon_to_desired_rot": (3,), "piece_size": (2,)}
CAMERA_KEYS = {
    "overhead_image": ((CAMERA_SIZE, CAMERA_SIZE, 3), np.uint8),
    "overhead_depth": ((CAMERA_SIZE, CAMERA_SIZE, 1), np.float32),
}
STEPS = 12


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "demos.hdf5"
    episodes = record_file(path, episodes=2, steps=STEPS)
    return path, episodes


def test_fresh_file_has_robomimics_schema_key_by_key(recorded):
    path, episodes = recorded
    with h5py.File(path, "r") as f:
        assert set(f.keys()) == {"data", "mask"}
        data = f["data"]
        meta = json.loads(data.attrs["env_args"])
        assert meta["env_name"] == "ScoopGranular" and meta["type"] == 1
        assert "env_name" not in meta["env_kwargs"]
        assert meta["env_kwargs"]["control_freq"] == 20
        assert meta["env_kwargs"]["controller_configs"]["body_parts"]["right"]["type"] == "OSC_POSE"
        assert meta["env_kwargs"]["food"] == "pasta"
        for key, value in dict(device="scripted", operator="scripted-expert", food="pasta", robot="XArm7").items():
            assert data.attrs[key] == value
        assert data.attrs["mujoco_version"] == pinned_mujoco_version()
        assert data.attrs["robosuite_version"] == "1.5.2"
        for key in ("veragmil_suite_version", "robomimic_version", "date"):
            assert data.attrs[key]
        assert set(data.keys()) == {"demo_0", "demo_1"}
        assert data.attrs["total"] == 2 * STEPS

        for name, episode in zip(("demo_0", "demo_1"), episodes):
            g = data[name]
            assert set(g.keys()) == {"actions", "states", "rewards", "dones", "obs", "next_obs"}
            assert g.attrs["num_samples"] == STEPS
            model = ET.fromstring(g.attrs["model_file"])
            assert model.tag == "mujoco" and model.find(".//body[@name='grain11']") is not None
            assert g.attrs["food"] == "pasta" and g.attrs["device"] == "scripted"
            for metric in ("success", "grains_spilled", "spilled_volume_cm3", "completion_time_s"):
                assert metric in g.attrs
            assert g["actions"].shape == (STEPS, 6) and g["actions"].dtype == np.float64
            assert np.abs(g["actions"][()]).max() <= 1.0
            assert g["states"].shape == (STEPS, episode.states.shape[1]) and g["states"].dtype == np.float64
            assert g["rewards"].shape == (STEPS,)
            dones = g["dones"][()]
            assert dones.shape == (STEPS,) and dones[-1] == 1 and set(np.unique(dones)) <= {0, 1}
            np.testing.assert_array_equal(g["actions"][()], episode.actions)
            np.testing.assert_array_equal(g["states"][()], episode.states)
            for group in ("obs", "next_obs"):
                keys = set(g[group].keys())
                assert keys == set(ROBOT_KEYS) | set(OBJECT_KEYS) | set(GOAL_KEYS) | set(CAMERA_KEYS) | {"object"}
                for key, shape in {**ROBOT_KEYS, **OBJECT_KEYS, **GOAL_KEYS}.items():
                    assert g[group][key].shape == (STEPS, *shape), key
                for key, (shape, dtype) in CAMERA_KEYS.items():
                    assert g[group][key].shape == (STEPS, *shape) and g[group][key].dtype == dtype, key
                # robomimic's "object" is robosuite's object-state: the object observables concatenated
                parts = np.concatenate([g[group][k][()] for k in OBJECT_KEYS], axis=1)
                np.testing.assert_array_equal(g[group]["object"][()], parts)
            for key in g["obs"]:
                np.testing.assert_array_equal(g["next_obs"][key][:-1], g["obs"][key][1:])

        masks = {k: sorted(x.decode() for x in f["mask"][k][()]) for k in f["mask"]}
        assert set(masks) == {"train", "valid", "pasta", "success"}
        assert sorted(masks["train"] + masks["valid"]) == ["demo_0", "demo_1"] and masks["valid"]
        assert masks["pasta"] == ["demo_0", "demo_1"]


def test_each_observation_is_that_of_its_recorded_state(recorded):
    """What robomimic's dataset_states_to_obs extracts: reset_to(state) gives back the recorded observation."""
    path, _ = recorded
    env = make_env(tiny_env_kwargs())
    env.reset()
    with open_dataset(path) as f:
        g = f["data/demo_1"]
        robomimic_obs.reset_to_demo(env, g.attrs["model_file"], g["states"][0])
        for t in (0, 5, STEPS - 1):
            env.sim.set_state_from_flattened(g["states"][t])
            obs = robomimic_obs.observation(env, robomimic_obs.observe(env))
            for key in obs:
                if key in robomimic_obs.TORQUE_DEPENDENT_OBSERVATIONS:
                    continue
                np.testing.assert_array_equal(obs[key], g["obs"][key][t], err_msg=f"{key} at step {t}")
    env.close()


def test_recorded_demo_replays_exactly_from_its_actions(recorded):
    path, _ = recorded
    env = make_env(tiny_env_kwargs(cameras=()))
    env.reset()
    for _ in range(2):  # an env that has lived through other episodes replays just the same
        env.step(np.full(6, 0.3))
    with open_dataset(path) as f:
        g = f["data/demo_0"]
        states, actions = g["states"][()], g["actions"][()]
        robomimic_obs.reset_to_demo(env, g.attrs["model_file"], states[0])
        np.testing.assert_array_equal(env.sim.get_state().flatten(), states[0])
        for t in range(1, len(actions)):
            env.step(actions[t - 1])
            np.testing.assert_array_equal(env.sim.get_state().flatten(), states[t], err_msg=f"state {t}")
    env.close()


def test_a_recording_starts_where_the_reset_put_the_arm(tmp_path):
    """A recording restarts the env from its own state (so that playback reproduces it); the restarted arm holds
    the pose the reset's joint noise drew, as a plain reset's does, instead of being pulled toward the noise-free
    start pose in its first step (results/start_mismatch/: 3 cm and 4 degrees on the farthest grid start)."""
    held = {}
    for restart in ("none", "recording", "robosuite's playback"):
        env = make_env(tiny_env_kwargs(cameras=()), seed=4)
        obs = env.reset()
        start = obs["robot0_eef_pos"].copy()
        if restart == "recording":
            obs, _ = robomimic_obs.restart_from_current_state(env)
        elif restart == "robosuite's playback":  # playback_demonstrations_from_hdf5.py's steps, none of ours
            state, xml = env.sim.get_state().flatten(), env.sim.model.get_xml()
            env.reset_from_xml_string(xml)
            env.sim.reset()
            env.sim.set_state_from_flattened(state)
            env.sim.forward()
        for _ in range(3):
            obs, _, _, _ = env.step(np.zeros(6))
        held[restart] = obs["robot0_eef_pos"]
        assert np.linalg.norm(held[restart] - start) < 5e-4, (restart, held[restart] - start)
        env.close()
    np.testing.assert_allclose(held["recording"], held["none"], atol=5e-4)


def test_append_continues_numbering_and_drops_an_interrupted_write(tmp_path):
    path = tmp_path / "append.hdf5"
    record_file(path, episodes=1, steps=4)
    with h5py.File(path, "a") as f:  # what a kill during a write leaves: an episode under its temporary name
        f["data"].create_group("incomplete_demo_1").create_dataset("actions", data=np.zeros((2, 6)))
    with open_dataset(path) as f:
        assert list(f["data/demo_0/actions"].shape) == [4, 6]
    record_file(path, episodes=2, steps=4, seed=1, operator="second-session")
    with open_dataset(path) as f:
        data = f["data"]
        assert sorted(data.keys()) == ["demo_0", "demo_1", "demo_2"]
        assert data.attrs["total"] == 12
        assert [data[n].attrs["operator"] for n in ("demo_0", "demo_1", "demo_2")] == [
            "scripted-expert",
            "second-session",
            "second-session",
        ]
        assert json.loads(data.attrs["operators"]) == ["scripted-expert", "second-session"]
        assert len(json.loads(data.attrs["attempts"])) == 3
        members = sorted(x.decode() for k in ("train", "valid") for x in f["mask"][k][()])
        assert members == ["demo_0", "demo_1", "demo_2"]


def test_a_file_an_earlier_version_wrote_takes_more_demos(tmp_path):
    """The shipped sample was written before the package moved into role folders: its writer is still ours."""
    path = tmp_path / "sample.hdf5"
    path.write_bytes((Path(__file__).resolve().parents[1] / "demos" / "scoop.hdf5").read_bytes())
    with h5py.File(path, "r") as f:
        env_args = json.loads(f["data"].attrs["env_args"])
    with DemoWriter(path, env_args, {"device": "scripted"}) as writer:
        assert writer.next_index > 0


def test_demos_of_the_earlier_start_never_mix_with_new_ones(tmp_path):
    """A file recorded before demos started where the reset put the arm (no "start" attribute) takes no new demo,
    joins no merge with new ones, and a study does not resume it; every refusal names the start and the file
    stays as it was."""
    from veragmil_suite.data.datasets import merge_datasets
    from veragmil_suite.data.schema import DEMO_START, EARLIER_START, demo_names, demo_start
    from veragmil_suite.study.record import StageError, check_recording

    new, old = tmp_path / "new.hdf5", tmp_path / "old.hdf5"
    for path in (new, old):
        with synthetic_writer(path) as writer:
            writer.write(synthetic_episode(steps=5))
    with h5py.File(new, "r") as f:
        assert demo_start(f["data"].attrs) == demo_start(f["data/demo_0"].attrs) == DEMO_START
    with h5py.File(old, "a") as f:  # as a file of before the attribute reads
        for group in (f["data"], f["data/demo_0"]):
            del group.attrs["start"]
    before = old.read_bytes()
    with pytest.raises(DatasetError, match=f"first step {EARLIER_START} .*write to a new file"):
        synthetic_writer(old)
    with pytest.raises(DatasetError, match=f"start otherwise .*first step {EARLIER_START}, not {DEMO_START}"):
        merge_datasets([new, old], tmp_path / "mixed.hdf5")
    assert not (tmp_path / "mixed.hdf5").exists() and old.read_bytes() == before
    with pytest.raises(StageError, match=f"start {EARLIER_START!r} \\(asked: {DEMO_START!r}\\)"):
        check_recording(old, "pasta", profile="", seed=None, n_grains=12, cameras=("overhead",))
    merged, again = tmp_path / "two_new.hdf5", tmp_path / "new_again.hdf5"
    again.write_bytes(new.read_bytes())
    merge_datasets([new, again], merged)
    with h5py.File(merged, "r") as f:
        assert len(demo_names(f)) == 2 and demo_start(f["data"].attrs) == DEMO_START


def test_append_refuses_another_setup(tmp_path):
    path = tmp_path / "a.hdf5"
    record_file(path, episodes=1, steps=3)
    other = tiny_env_kwargs(control_freq=60)
    with pytest.raises(DatasetError, match="control_freq"):
        DemoWriter(path, env_meta(other), provenance("scripted", "x", "pasta", "XArm7"))


def _robomimic_file(path, env_name):
    with h5py.File(path, "w") as f:
        f.create_group("data").attrs["env_args"] = json.dumps(dict(env_name=env_name, type=1, env_kwargs={}))


def test_foreign_and_corrupt_files_give_clear_errors(tmp_path, recorded, capsys):
    meta = env_meta(tiny_env_kwargs())
    prov = provenance("scripted", "x", "pasta", "XArm7")
    garbage = tmp_path / "garbage.hdf5"
    garbage.write_bytes(b"this is not HDF5\n" * 100)
    truncated = tmp_path / "truncated.hdf5"
    truncated.write_bytes(recorded[0].read_bytes()[:5000])
    bare = tmp_path / "bare.hdf5"
    with h5py.File(bare, "w") as f:
        f.create_dataset("x", data=[1, 2, 3])
    lift = tmp_path / "lift.hdf5"
    _robomimic_file(lift, "Lift")
    foreign = tmp_path / "foreign.hdf5"
    _robomimic_file(foreign, "ScoopGranular")  # robomimic layout, but not written by us
    cases = [
        (garbage, "cannot be read as HDF5"),
        (truncated, "cannot be read as HDF5"),
        (bare, "not a robomimic dataset"),
        (lift, "holds demonstrations of 'Lift'"),
    ]
    for path, message in cases:
        with pytest.raises(DatasetError, match=message):
            open_dataset(path)
        with pytest.raises(DatasetError, match=message):
            DemoWriter(path, meta, prov)
    with pytest.raises(DatasetError, match="not written by veragmil_suite"):
        DemoWriter(foreign, meta, prov)
    with pytest.raises(DatasetError, match="no such file"):
        open_dataset(tmp_path / "missing.hdf5")
    # a damaged demo is named
    damaged = tmp_path / "damaged.hdf5"
    damaged.write_bytes(recorded[0].read_bytes())
    with h5py.File(damaged, "a") as f:
        del f["data/demo_1/states"]
    with pytest.raises(DatasetError, match="demo_1 is incomplete: no 'states'"):
        open_dataset(damaged)
    # the command-line tools say it in one line and exit 2
    for tool in (info_main, lambda argv: split_main([*argv, "--ratio", "0.5"])):
        assert tool([str(garbage)]) == 2
        err = capsys.readouterr().err
        assert "cannot be read as HDF5" in err and len(err.strip().splitlines()) == 1


CHILD = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    import numpy as np
    from helpers.recording import make_env, record_file, tiny_env_kwargs
    from veragmil_suite.data.recording import EpisodeRecorder

    record_file({path!r}, episodes=2, steps=5)
    env = make_env(tiny_env_kwargs())
    recorder = EpisodeRecorder(env)
    recorder.reset()
    print("MID-EPISODE", flush=True)
    while True:
        recorder.step(np.zeros(6))
    """
)


def test_killed_mid_episode_the_file_keeps_every_finished_episode(tmp_path):
    path = tmp_path / "crash.hdf5"
    code = CHILD.format(tests=os.path.dirname(__file__), path=str(path))
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        for line in child.stdout:
            if "MID-EPISODE" in line:
                break
        else:
            pytest.fail("the child process died before its third episode")
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == -signal.SIGKILL
    with open_dataset(path) as f:
        data = f["data"]
        assert sorted(data.keys()) == ["demo_0", "demo_1"]
        assert data.attrs["total"] == 10
        for name in data:
            assert data[name]["states"][()].shape[0] == 5
            assert data[name]["obs/overhead_image"][()].shape == (5, CAMERA_SIZE, CAMERA_SIZE, 3)


def test_a_non_finite_action_is_never_stored(tmp_path):
    env = make_env(tiny_env_kwargs(cameras=()))
    recorder = EpisodeRecorder(env)
    recorder.reset(seed=0)
    recorder.step(np.full(6, 0.1))
    _, _, done, info = recorder.step(np.array([0.1, np.nan, 0, 0, 0, 0]))
    assert done and "non-finite action" in info["physics_error"]
    assert recorder.num_steps == 1  # the NaN step is not in the episode
    episode = recorder.episode(attrs=dict(end_reason="physics"))
    assert np.isfinite(episode.actions).all() and episode.actions.shape == (1, 6)
    assert "non-finite action" in episode.metrics["physics_error"]  # the episode says why it ended
    path = tmp_path / "nan.hdf5"
    with DemoWriter(path, env_meta(tiny_env_kwargs(cameras=())), provenance("scripted", "x", "pasta", "XArm7")) as w:
        w.write(episode)
    with open_dataset(path) as f:
        assert "non-finite action" in f["data/demo_0"].attrs["physics_error"]
    with pytest.raises(ValueError, match="non-finite action label"):  # a label is checked before anything runs
        recorder.reset(seed=0)
        recorder.step(np.zeros(6), label=np.array([np.inf, 0, 0, 0, 0, 0]))
    assert recorder.num_steps == 0
    env.close()


def _invalid_episodes():
    """Every way an episode can fail to be a demo, generated from a valid one: no steps, each array non-finite or
    of another length, actions (executed or stored) outside the action space, a physics end without its error."""
    good = synthetic_episode(steps=6)
    yield "no steps", synthetic_episode(steps=0)
    for key in ("actions", "states", "rewards"):
        for bad in (np.nan, np.inf):
            value = getattr(good, key).copy()
            value[2] = bad
            yield f"{key} {bad}", dataclasses.replace(good, **{key: value})
    for key in ("states", "rewards", "dones"):
        yield f"{key} short", dataclasses.replace(good, **{key: getattr(good, key)[:-1]})
    yield "obs short", dataclasses.replace(good, obs={k: v[:-1] for k, v in good.obs.items()})
    for outside in (5.0, -1.5):
        yield f"action {outside}", dataclasses.replace(good, actions=np.full((6, 6), outside))
        yield f"executed {outside}", dataclasses.replace(good, executed_actions=np.full((6, 6), outside))
    bounds = (np.full(6, -0.5), np.full(6, 0.5))  # the env's own action space, when the recorder gives it
    yield "outside its env's bounds", dataclasses.replace(good, actions=np.full((6, 6), 0.8), action_bounds=bounds)
    yield "physics without error", dataclasses.replace(good, attrs=dict(end_reason="physics"))


@pytest.mark.parametrize("what, episode", list(_invalid_episodes()), ids=lambda x: x if isinstance(x, str) else "")
def test_the_writer_refuses_an_episode_that_is_not_a_valid_demo(tmp_path, what, episode):
    path = tmp_path / "demos.hdf5"
    with synthetic_writer(path) as writer:
        writer.write(synthetic_episode(steps=6))
        before = path.read_bytes()
        with pytest.raises(DatasetError):
            writer.write(episode)
    assert path.read_bytes() == before


def _edited(path, tmp_path, name, edit):
    out = tmp_path / name
    out.write_bytes(path.read_bytes())
    with h5py.File(out, "a") as f:
        edit(f["data/demo_1"])
    return out


def _emptied(g):
    for key in ("actions", "states", "rewards", "dones"):
        data = g[key][()]
        del g[key]
        g.create_dataset(key, data=data[:0])
    for group in ("obs", "next_obs"):
        for key in list(g[group]):
            data = g[group][key][()]
            del g[group][key]
            g[group].create_dataset(key, data=data[:0])
    g.attrs["num_samples"] = 0
    g.attrs["success"] = True


def _set_actions(value):
    def edit(g):
        g["actions"][2] = value

    return edit


def test_the_schema_check_refuses_an_empty_or_non_finite_demo_and_the_info_flags_the_rest(tmp_path, capsys):
    path = tmp_path / "demos.hdf5"
    with synthetic_writer(path) as writer:
        for seed in range(3):
            writer.write(synthetic_episode(steps=6, seed=seed))
    refused = {
        "no steps": _edited(path, tmp_path, "empty.hdf5", _emptied),
        "non-finite actions": _edited(path, tmp_path, "nan.hdf5", _set_actions(np.nan)),
    }
    for message, bad in refused.items():
        with pytest.raises(DatasetError, match=f"demo_1 has {message}"):
            open_dataset(bad)
        with pytest.raises(ValueError, match=f"demo_1 has {message}"):  # nor scored as an agent's episodes
            parse_spec(f"dataset:{bad}")
        capsys.readouterr()
        assert info_main([str(bad)]) == 2
        err = capsys.readouterr().err
        assert f"demo_1 has {message}" in err and len(err.strip().splitlines()) == 1
    flagged = {
        "actions outside the action space": _edited(path, tmp_path, "big.hdf5", _set_actions(5.0)),
        "physics_error is empty": _edited(
            path, tmp_path, "physics.hdf5", lambda g: g.attrs.update(end_reason="physics", physics_error="")
        ),
    }
    for message, bad in flagged.items():
        capsys.readouterr()
        assert info_main([str(bad)]) == 0
        out = capsys.readouterr().out
        assert "FLAGGED demo_1:" in out and message in out, message
