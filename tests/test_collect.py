"""veragmil-collect: the headless scripted form automation calls, Ctrl-C mid-episode, keep/discard from a device,
scripted 3D-mouse data labelled scripted, clear errors for missing hardware, --help of every console command."""

import argparse
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import robosuite

from veragmil_suite.data.schema import open_dataset
from veragmil_suite.devices import operators
from veragmil_suite.devices.session import SessionDevice
from veragmil_suite.scripts import collect_human_demonstrations as collect
from veragmil_suite.scripts import dataset_tools
from veragmil_suite.utils import cli

BIN = Path(sys.executable).parent
LIGHT = ["--food", "pasta", "--n-grains", "12", "--camera-size", "32"]


def _headless_env():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MUJOCO_GL"] = "osmesa"
    return env


def test_scripted_collection_runs_headless_in_its_automation_form(tmp_path):
    out = tmp_path / "out.hdf5"
    # pasta of 12 pieces: the cheapest scene the expert scoops (rice loads a spoon from about 80 grains: twice the time)
    args = ["--device", "scripted", "--food", "pasta", "--n-grains", "12", "--episodes", "1", "--output", str(out)]
    result = subprocess.run(
        [str(BIN / "veragmil-collect"), *args],
        cwd=tmp_path,
        env=_headless_env(),
        stdin=subprocess.DEVNULL,  # a prompt would fail on end of input
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.count("saved as demo_") == 1
    assert "spilled" in result.stdout and "time" in result.stdout
    with open_dataset(out) as f:
        data = f["data"]
        assert sorted(data.keys()) == ["demo_0"]
        for name in data:
            g = data[name]
            assert g.attrs["success"] and g.attrs["device"] == "scripted" and g.attrs["source"] == "scripted"
            assert g.attrs["food"] == "pasta" and g.attrs["operator"] == "scripted-expert"
            assert g["obs/overhead_image"].shape[1:] == (84, 84, 3)
            assert g.attrs["num_samples"] == g["actions"].shape[0] >= 100
        attempts = json.loads(data.attrs["attempts"])
        assert sum(a["kept"] for a in attempts) == 1
        assert all(a["device"] == "scripted" for a in attempts)


def _collect(out, *args):
    return subprocess.run(
        [str(BIN / "veragmil-collect"), "--device", "scripted", *LIGHT, "--output", str(out), "--quiet", *args],
        env=_headless_env(),
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_parallel_recording_writes_the_same_demos_as_serial_recording(tmp_path):
    # seed 3's first attempts; --cameras with no name: low-dim only
    serial, parallel = tmp_path / "serial.hdf5", tmp_path / "parallel.hdf5"
    for out, workers in ((serial, "1"), (parallel, "2")):
        result = _collect(out, "--episodes", "2", "--seed", "3", "--workers", workers, "--cameras")
        assert result.returncode == 0, result.stderr[-2000:]
    with open_dataset(serial) as a, open_dataset(parallel) as b:
        assert sorted(a["data"].keys()) == sorted(b["data"].keys()) == ["demo_0", "demo_1"]
        seeds = [int(a["data"][f"demo_{i}"].attrs["seed"]) for i in range(2)]
        assert seeds == sorted(seeds) and seeds[0] >= 3 and len(set(seeds)) == 2
        for name in a["data"]:
            x, y = a["data"][name], b["data"][name]
            assert x.attrs["seed"] == y.attrs["seed"] and x.attrs["stage"] == y.attrs["stage"] == "held"
            np.testing.assert_array_equal(x["actions"][:], y["actions"][:])
            np.testing.assert_array_equal(x["states"][:], y["states"][:])
            np.testing.assert_array_equal(x["obs/object"][:], y["obs/object"][:])
    # the second demo's attempt is the episode of its seed, whatever came before it
    alone = tmp_path / "alone.hdf5"
    assert _collect(alone, "--episodes", "1", "--seed", str(seeds[1]), "--cameras").returncode == 0
    with open_dataset(serial) as a, open_dataset(alone) as c:
        assert int(c["data/demo_0"].attrs["seed"]) == seeds[1]
        np.testing.assert_array_equal(a["data/demo_1/states"][:], c["data/demo_0/states"][:])


def test_noise_injection_records_the_operators_actions_and_replays_the_executed_ones(tmp_path):
    out = tmp_path / "dart.hdf5"
    result = _collect(out, "--episodes", "1", "--profile", "expert-dart", "--cameras")
    assert result.returncode == 0, result.stderr[-2000:]
    with open_dataset(out) as f:
        g = f["data/demo_0"]
        labels, executed = g["actions"][:], g["executed_actions"][:]
        assert g.attrs["profile"] == "expert-dart" and g.attrs["success"]
    assert labels.shape == executed.shape
    gap = np.abs(executed - labels)
    assert 0.01 < gap.mean() < 0.3  # noise of std 0.1 (clipped to the action range)
    # the executed actions replay the recorded states exactly (on this machine); the labels alone would not
    (replayed,) = dataset_tools.replay_demos(out, None, use_actions=True)
    assert replayed["max_state_error"] == 0.0 and replayed["success"]


def test_workers_need_the_scripted_device(tmp_path):
    result = subprocess.run(
        [str(BIN / "veragmil-collect"), "--device", "keyboard", "--workers", "2", "--output", str(tmp_path / "k.h5")],
        env=_headless_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode != 0 and "--processes 2 needs --device scripted" in result.stderr
    assert not (tmp_path / "k.h5").exists()


def test_ctrl_c_mid_episode_keeps_the_saved_episodes(tmp_path):
    out = tmp_path / "interrupted.hdf5"
    args = [
        "--device",
        "scripted",
        *LIGHT,
        "--episodes",
        "1000",  # never all recorded before the interrupt lands, however late the reader sees demo_0
        "--keep",
        "all",
        "--horizon",
        "60",
        "--output",
        str(out),
    ]
    child = subprocess.Popen(
        [str(BIN / "veragmil-collect"), *args],
        env=_headless_env(),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # Ctrl-C as in a terminal, even when the tests run in the background (which ignores SIGINT, and a child
        # started with it ignored keeps ignoring it)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        for line in child.stdout:
            if "saved as demo_0" in line:
                break
        os.kill(child.pid, signal.SIGINT)  # the second episode is under way
        stdout, stderr = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
    assert "interrupted" in stdout
    assert "Traceback" not in stderr
    assert child.returncode == 1  # fewer episodes than asked for
    with open_dataset(out) as f:
        names = sorted(f["data"].keys())
        assert "demo_0" in names
        for name in names:
            assert f["data"][name]["actions"].shape[0] == f["data"][name].attrs["num_samples"] > 0


def test_scripted_3d_mouse_data_is_labelled_scripted(tmp_path):
    out = tmp_path / "mouse.hdf5"
    args = ["--device", "scripted", "--profile", "spacemouse", *LIGHT, "--keep", "all", "--horizon", "20"]
    assert collect.main([*args, "--cameras", "--episodes", "1", "--output", str(out)]) == 0
    with open_dataset(out) as f:
        data = f["data"]
        g = data["demo_0"]
        for attrs in (data.attrs, g.attrs):
            assert attrs["device"] == "scripted" and attrs["source"] == "scripted"
            assert attrs["operator"] == "scripted-spacemouse" and attrs["profile"] == "spacemouse"
        assert "human" not in json.dumps({k: str(v) for k, v in g.attrs.items() if k != "model_file"})
        assert set(g["obs"].keys()).isdisjoint({"overhead_image", "overhead_depth"})  # --cameras with none: low-dim
        actions = g["actions"][()]
        assert ((actions != 0).sum(axis=1) <= 1).all()


class FakeHeadset(SessionDevice):
    """A clutched device whose operator takes a while to squeeze the grip (IDLE calls), pushes the spoon up for a few
    steps, then presses the scripted button ("keep"/"discard")."""

    IDLE = 7
    clutched = True

    def __init__(self, env, verdicts):
        self.env = env
        self.verdicts = list(verdicts)
        self.recording = False
        self.episode_command = None
        self.started = 0
        self.recording_seen = []
        self.progress = ""
        self.progress_seen = []
        self.farewell = None

    def start_control(self):
        self.started += 1
        self.episode_command = None
        self.steps = 0
        self.calls = 0

    @property
    def engaged(self):
        return self.calls > self.IDLE

    def input2action(self):
        self.calls += 1
        self.recording_seen.append(self.recording)
        self.progress_seen.append(self.progress)
        if not self.recording:  # waiting for the squeeze, or the call that saw it (the hand has not moved yet)
            return {"right_delta": np.zeros(6)}
        self.steps += 1
        if self.steps > 5:
            self.episode_command = self.verdicts.pop(0)
            return None
        return {"right_delta": np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0])}

    def set_recording(self, on):
        self.recording = on

    def show_progress(self, text):
        self.progress = text

    def close_session(self, farewell=None):
        self.farewell = farewell

    def connection_counters(self):
        # the page reconnected once after being dropped as silent
        return {"connections": 2, "malformed": 0, "heartbeat_timeouts": 1}


def test_keep_and_discard_from_the_device(tmp_path, monkeypatch, capsys):
    out = tmp_path / "vr.hdf5"
    headset = None

    def operator(args, env):
        nonlocal headset
        headset = FakeHeadset(env, ["discard", "keep"])
        return operators.TeleopOperator(env, headset, "")

    monkeypatch.setattr(collect, "make_operator", operator)
    argv = ["--device", "vr", *LIGHT, "--cameras", "--episodes", "1", "--operator", "tester", "--output", str(out)]
    assert collect.main(argv) == 0
    printed = capsys.readouterr().out
    assert "discarded" in printed and "saved as demo_0" in printed
    assert "vr server: connections 2, heartbeat_timeouts 1\n" in printed  # the non-zero counters, after the fact
    with open_dataset(out) as f:
        data = f["data"]
        assert list(data.keys()) == ["demo_0"]
        g = data["demo_0"]
        assert g.attrs["device"] == "vr" and g.attrs["source"] == "human" and g.attrs["operator"] == "tester"
        # the episode began at the squeeze: the idle time before it is neither recorded nor shown as recording
        assert g.attrs["num_samples"] == 5 and g.attrs["end_reason"] == "operator"
        assert headset.recording_seen[: FakeHeadset.IDLE] == [False] * FakeHeadset.IDLE
        # the operator sees where the collection stands, and its end
        assert headset.progress_seen[0] == "episode 1 | kept 0/1 | discarded 0 | vr.hdf5"
        assert headset.progress_seen[-1] == "episode 2 | kept 0/1 | discarded 1 | vr.hdf5"
        assert headset.farewell == f"1 demo saved to {out}"
        np.testing.assert_array_equal(g["actions"][:, 2], 0.3)
        attempts = json.loads(data.attrs["attempts"])
        assert [a["kept"] for a in attempts] == [False, True]
        assert attempts[0]["demo"] is None and attempts[1]["demo"] == "demo_0"
        assert all("success" in a and "grains_spilled" in a for a in attempts)


@pytest.mark.parametrize("flag,allowed", [([], False), (["--vr-allow-emulated"], True)])
def test_vr_allow_emulated_reaches_the_device(flag, allowed):
    """An emulator (iwer) marks every pose as emulated; only the flag lets such poses drive the arm."""
    args = collect.build_parser().parse_args(
        ["--device", "vr", *LIGHT, "--vr-port", "0", "--output", "unused.hdf5", *flag]
    )
    env = robosuite.make("ScoopGranular", **collect.env_kwargs_from_args(args), has_renderer=False)
    operator = operators.make_operator(args, env)
    try:
        assert operator.device.allow_emulated_position is allowed
    finally:
        operator.close()
        env.close()


def test_wrench_records_the_wrist_sensor():
    base = ["--device", "keyboard", *LIGHT, "--output", "unused.hdf5"]
    assert "use_wrench_obs" not in collect.env_kwargs_from_args(collect.build_parser().parse_args(base))
    with_sensor = collect.env_kwargs_from_args(collect.build_parser().parse_args([*base, "--wrench"]))
    assert with_sensor["use_wrench_obs"] is True


def test_missing_hardware_or_display_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    for device, message in (("keyboard", "needs a display"), ("spacemouse", "no SpaceMouse found")):
        out = tmp_path / f"{device}.hdf5"
        assert collect.main(["--device", device, *LIGHT, "--cameras", "--output", str(out)]) == 2
        assert message in capsys.readouterr().err
        assert not out.exists()


def test_controller_option_takes_an_osc_config_file(tmp_path):
    config = collect.controller_config("OSC_POSE", "XArm7")
    config["body_parts"]["right"]["kp"] = 250
    path = tmp_path / "stiff.json"
    path.write_text(json.dumps(config))
    assert cli.controller(str(path)) == str(path)
    assert collect.controller_config(str(path), "XArm7")["body_parts"]["right"]["kp"] == 250
    assert collect.controller_config("BASIC", "XArm7")["body_parts"]["right"]["type"] == "OSC_POSE"  # robosuite's
    config["body_parts"]["right"]["type"] = "JOINT_VELOCITY"
    path.write_text(json.dumps(config))
    with pytest.raises(argparse.ArgumentTypeError, match="'JOINT_VELOCITY'; collection needs OSC_POSE"):
        cli.controller(str(path))
    with pytest.raises(argparse.ArgumentTypeError, match="do not drive IK_POSE"):
        cli.controller("IK_POSE")
    with pytest.raises(argparse.ArgumentTypeError, match="missing.json: no such file"):
        cli.controller(str(tmp_path / "missing.json"))
    with pytest.raises(argparse.ArgumentTypeError, match="unknown controller 'BOGUS'; accepted: OSC_POSE, "):
        cli.controller("BOGUS")


@pytest.mark.parametrize(
    "main, expected",
    [
        (collect.main, "--device"),
        (dataset_tools.info_main, "--json"),
        (dataset_tools.merge_main, "--output"),
        (dataset_tools.split_main, "--valid-ratio"),
        (dataset_tools.replay_main, "--use-actions"),
        (dataset_tools.render_obs_main, "--camera-names"),
    ],
)
def test_every_console_command_has_help(main, expected, capsys):
    assert main(["--help"]) == 0
    assert expected in capsys.readouterr().out


def test_appending_continues_the_seeds_and_an_explicit_repeat_is_refused(tmp_path, capsys):
    out = tmp_path / "same.hdf5"
    args = ["--device", "scripted", *LIGHT, "--cameras", "--keep", "all", "--horizon", "10", "--output", str(out)]
    assert collect.main([*args, "--episodes", "2"]) == 0
    assert collect.main([*args, "--episodes", "1"]) == 0  # the same command again: no seed given
    with open_dataset(out) as f:
        assert [int(f["data"][n].attrs["seed"]) for n in ("demo_0", "demo_1", "demo_2")] == [0, 1, 2]
    assert dataset_tools.dataset_summary(out)["duplicates"] == []
    before = out.read_bytes()
    capsys.readouterr()
    assert collect.main([*args, "--episodes", "1", "--seed", "1"]) == 2
    err = capsys.readouterr().err
    assert "seeds up to 2" in err and "continue from 3" in err and "Traceback" not in err
    assert out.read_bytes() == before  # nothing recorded is touched


def test_a_dataset_tool_flags_a_demo_recorded_twice(tmp_path, capsys):
    out = tmp_path / "twice.hdf5"
    args = ["--device", "scripted", *LIGHT, "--cameras", "--keep", "all", "--horizon", "10", "--episodes", "1"]
    for path in (tmp_path / "a.hdf5", tmp_path / "b.hdf5"):  # two files made with the same seed...
        assert collect.main([*args, "--seed", "5", "--output", str(path)]) == 0
    assert dataset_tools.merge_main([str(tmp_path / "a.hdf5"), str(tmp_path / "b.hdf5"), "--output", str(out)]) == 0
    assert dataset_tools.dataset_summary(out)["duplicates"] == [["demo_0", "demo_1"]]  # ...merged: flagged
    capsys.readouterr()
    assert dataset_tools.info_main([str(out)]) == 0
    assert "DUPLICATES: demo_0, demo_1" in capsys.readouterr().out


@pytest.mark.parametrize(
    "bad,message",
    [
        (["--robot", "Nonexistent"], "Unknown robot 'Nonexistent'; robosuite's robots: "),
        (["--n-grains", "100000"], "n_grains 100000 is more than a bowl of pasta settles in reasonable time"),
    ],
)
def test_a_refused_start_creates_nothing(tmp_path, capsys, bad, message):
    out = tmp_path / "fresh.hdf5"
    args = ["--device", "scripted", *LIGHT, "--cameras", "--keep", "all", "--horizon", "10", "--episodes", "1"]
    assert collect.main([*args, *bad, "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()
    assert collect.main([*args, "--output", str(out)]) == 0  # the same path works with correct arguments
    with open_dataset(out) as f:
        assert list(f["data"].keys()) == ["demo_0"]


# ---------------------------------------------------------------------------------------------------------------- #
# A superset of robosuite's collect_human_demonstrations.py                                                         #
# ---------------------------------------------------------------------------------------------------------------- #


def test_every_option_of_robosuites_script_is_ours():
    import robosuite.scripts.collect_human_demonstrations as robosuites

    theirs = cli.script_parser(robosuites)
    ours = collect.build_parser()
    for action in theirs._actions:
        for name in action.option_strings:
            assert cli.respell(ours, [name])[0] in cli.option_strings(ours), f"robosuite's {name} is not ours"


def test_robosuites_flags_mean_what_they_mean_there():
    """robosuite's own command line (underscores and all), parsed by ours."""
    from robosuite.controllers import load_composite_controller_config

    args = collect.build_parser().parse_args(
        ["--environment", "ScoopGranular", "--robots", "Panda", "--config", "default", "--arm", "right",
         "--camera", "agentview", "--controller", "BASIC", "--device", "dualsense", "--pos-sensitivity", "0.5",
         "--rot-sensitivity", "2", "--renderer", "mujoco", "--max_fr", "30", "--reverse_xy", "True",
         "--goal_update_mode", "achieved", "--directory", "demos_here"]
    )  # fmt: skip
    assert (args.environment, args.robots, args.config, args.arm, args.camera) == (
        "ScoopGranular", "Panda", "default", "right", ["agentview"]
    )  # fmt: skip
    assert (args.device, args.pos_sensitivity, args.rot_sensitivity) == ("dualsense", 0.5, 2.0)
    assert (args.renderer, args.max_fr, args.reverse_xy, args.goal_update_mode) == ("mujoco", 30.0, True, "achieved")
    # robosuite's composite controller of that name, for that robot
    assert collect.env_kwargs_from_args(args)["controller_configs"] == load_composite_controller_config(
        controller="BASIC", robot="Panda"
    )
    # robosuite's layout: a new folder per run, named after the time, holding demo.hdf5
    assert re.fullmatch(r"demos_here/\d+_\d+/demo\.hdf5", collect.output_path(args))


class _Device:
    """Stands in for one of robosuite's device classes: records how it was built."""

    built: list = []

    def __init__(self, env, **kwargs):
        _Device.built.append((type(self).__name__, env, kwargs))


@pytest.mark.parametrize(
    "device, where, name, expected",
    [
        ("keyboard", "robosuite.devices", "Keyboard", dict(pos_sensitivity=0.5, rot_sensitivity=2.0)),
        ("spacemouse", "robosuite.devices", "SpaceMouse", dict(pos_sensitivity=0.5, rot_sensitivity=2.0)),
        (
            "dualsense",
            "robosuite.devices",
            "DualSense",
            dict(pos_sensitivity=0.5, rot_sensitivity=2.0, reverse_xy=True),
        ),
        ("mjgui", "robosuite.devices.mjgui", "MJGUI", dict(active_end_effector="right")),
    ],
)
def test_robosuites_devices_are_built_from_robosuites_own_classes(device, where, name, expected, monkeypatch):
    """The wiring, not the hardware: --device names robosuite's class, built as robosuite's script builds it."""
    import importlib

    monkeypatch.setattr(importlib.import_module(where), name, type(name, (_Device,), {}))
    _Device.built.clear()
    args = collect.build_parser().parse_args(
        ["--device", device, "--pos-sensitivity", "0.5", "--rot-sensitivity", "2", "--reverse-xy", "true",
         "--goal-update-mode", "achieved", "--output", "unused.hdf5"]
    )  # fmt: skip
    env = object()
    operator = operators.make_operator(args, env)
    assert isinstance(operator, operators.TeleopOperator) and operator.goal_update_mode == "achieved"
    assert _Device.built == [(name, env, expected)]


def test_a_dualsense_missing_is_one_line_from_robosuites_class(capsys):
    """robosuite's real DualSense class, with no controller plugged in: hidapi finds none, said in one line."""
    from types import SimpleNamespace

    args = collect.build_parser().parse_args(["--device", "dualsense", "--output", "unused.hdf5"])
    env = SimpleNamespace(robots=[SimpleNamespace(arms=["right"])])
    with pytest.raises(cli.UsageError, match="--device dualsense: no DualSense found through hidapi"):
        operators.make_device(args, env)


def test_mjgui_needs_robosuites_viewer(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("DISPLAY", ":0")
    argv = ["--device", "mjgui", "--renderer", "mujoco", *LIGHT, "--output", str(tmp_path / "m.hdf5")]
    assert collect.main(argv) == 2
    assert "--device mjgui drags the spoon's target in MuJoCo's viewer: it needs --renderer mjviewer" in (
        capsys.readouterr().err
    )


def test_the_script_runs_the_same_by_path_as_a_module_and_as_veragmil_collect(tmp_path):
    """robosuite's script is run by its path; ours runs the same program that way, with python -m and as
    veragmil-collect (this one with robosuite's --directory instead of --output)."""
    root = Path(__file__).resolve().parents[1]
    tiny = ["--device", "scripted", "--food", "pasta", "--n-grains", "8", "--horizon", "10", "--episodes", "1"]
    tiny += ["--keep", "all", "--camera-names", "--seed", "3"]
    ways = {
        "path": [sys.executable, str(root / "veragmil_suite" / "scripts" / "collect_human_demonstrations.py")],
        "module": [sys.executable, "-m", "veragmil_suite.scripts.collect_human_demonstrations"],
        "console": [str(BIN / "veragmil-collect")],
    }
    env = dict(_headless_env(), PYTHONPATH=str(root))
    running = {}
    for way, command in ways.items():
        where = (
            ["--directory", str(tmp_path / way)] if way == "console" else ["--output", str(tmp_path / f"{way}.hdf5")]
        )
        running[way] = subprocess.Popen(
            [*command, *tiny, *where], env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
    printed = {}
    for way, process in running.items():
        out, err = process.communicate(timeout=600)
        assert process.returncode == 0, (way, err[-3000:])
        printed[way] = [line for line in out.splitlines() if not line.startswith(("recording ", "1 attempts"))]
    (made,) = (tmp_path / "console").glob("*_*/demo.hdf5")
    files = {"path": tmp_path / "path.hdf5", "module": tmp_path / "module.hdf5", "console": made}
    assert printed["path"] == printed["module"] == printed["console"] and "  saved as demo_0 (1/1)" in printed["path"]
    with open_dataset(files["path"]) as a, open_dataset(files["module"]) as b, open_dataset(files["console"]) as c:
        for key in ("actions", "states"):
            np.testing.assert_array_equal(a["data/demo_0"][key][()], b["data/demo_0"][key][()])
            np.testing.assert_array_equal(a["data/demo_0"][key][()], c["data/demo_0"][key][()])


def test_the_physics_is_recorded_by_name_and_a_file_keeps_one_physics(tmp_path, capsys):
    """--physics picks the grain models; the dataset names them, and demos of another physics are not appended."""
    out = tmp_path / "calibrated.hdf5"
    args = ["--device", "scripted", *LIGHT, "--cameras", "--keep", "all", "--horizon", "10", "--output", str(out)]
    assert collect.main([*args, "--episodes", "1", "--physics", "calibrated"]) == 0
    with open_dataset(out) as f:
        kwargs = json.loads(f["data"].attrs["env_args"])["env_kwargs"]
        demo = (
            json.loads(f["data"]["demo_0"].attrs["env_args"])["env_kwargs"]
            if "env_args" in f["data"]["demo_0"].attrs
            else kwargs
        )
    assert kwargs["physics"] == demo["physics"] == "calibrated"
    before = out.read_bytes()
    capsys.readouterr()
    assert collect.main([*args, "--episodes", "1", "--physics", "table1"]) == 2
    assert "physics" in capsys.readouterr().err
    assert out.read_bytes() == before  # nothing recorded is lost or changed
    assert collect.main([*args, "--episodes", "1", "--physics", "sand"]) == 2
    err = capsys.readouterr().err
    assert "sand" in err and "calibrated" in err and "table1" in err
