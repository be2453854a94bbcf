"""One clear line for the bad inputs issues found, in the console programs of setup.py and the benchmark scripts:
exit status 2, the problem and the accepted values named, no traceback, nothing created. tests/test_cli.py generates
the same check for every option of every program from the parsers themselves; the cases here are those found by hand
(issue 33 and before), many refused after parsing, where what is wrong is a combination or a file's content."""

import json
import logging
import socket
import sys
from pathlib import Path

import pytest
from helpers.programs import main_of

from veragmil_suite.learning.algorithms import ALGORITHMS

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = str(ROOT / "demos" / "scoop.hdf5")
CHECKPOINT = str(next((ROOT / "models" / "checkpoints").glob("*.pth")))
LIGHT = ["--food", "pasta", "--n-grains", "12"]
SCRIPTED = ["--device", "scripted", *LIGHT]
EVAL = ["--agent", "expert", "--output-dir", "{tmp}/e"]
LONG_NAME = "n" * 250 + ".hdf5"

# (program, arguments, what the one line must say); {tmp} is a fresh directory holding the files _bad_files writes,
# {missing} a file that is not there, {busy} a port another socket holds
CASES = [
    ("veragmil-collect", [*SCRIPTED, "--robot", "Nonexistent", "--output", "{tmp}/a.hdf5"],
     "Unknown robot 'Nonexistent'; robosuite's robots: "),
    ("veragmil-collect", [*SCRIPTED, "--control-freq", "7", "--output", "{tmp}/a.hdf5"],
     "accepted control frequencies"),
    ("veragmil-collect", ["--device", "vr", *LIGHT, "--vr-port", "99999", "--output", "{tmp}/a.hdf5"],
     "argument --vr-port: must be a TCP port in 0-65535, got 99999"),
    ("veragmil-collect", ["--device", "vr", *LIGHT, "--vr-port", "{busy}", "--output", "{tmp}/a.hdf5"],
     "another program holds it: give another port, or 0 for any free one"),
    ("veragmil-collect", ["--device", "vr", *LIGHT, "--vr-host", "999.1.1.1", "--output", "{tmp}/a.hdf5"],
     "argument --vr-host: '999.1.1.1' is not an address"),
    ("veragmil-collect", ["--device", "scripted", "--food", "pasta", "--n-grains", "100000", "--output",
     "{tmp}/a.hdf5"], "n_grains 100000 is more than a bowl of pasta settles in reasonable time: at most 160"),
    ("veragmil-collect", [*SCRIPTED, "--camera-size", "0", "--output", "{tmp}/a.hdf5"],
     "argument --camera-size: must be a size in pixels in [1, 4096], got 0"),
    ("veragmil-collect", [*SCRIPTED, "--output", "{tmp}"], "is a directory, not a dataset file"),
    ("veragmil-collect", [*SCRIPTED, "--output", "{tmp}/no/a.hdf5"], "the folder {tmp}/no does not exist"),
    ("veragmil-collect", ["--device", "scripted", "--food", "caviar", "--output", "{tmp}/a.hdf5"],
     "argument --food: unknown food 'caviar'; accepted: rice, "),
    ("veragmil-collect", [*SCRIPTED, "--episodes", "0", "--output", "{tmp}/a.hdf5"],
     "argument --episodes: must be a positive integer, got 0"),
    ("veragmil-collect", [*SCRIPTED, "--controller", "BOGUS", "--output", "{tmp}/a.hdf5"],
     "argument --controller: unknown controller 'BOGUS'; accepted: OSC_POSE, robosuite's composite controllers"),
    ("veragmil-collect", [*SCRIPTED, "--valid-ratio", "1.5", "--output", "{tmp}/a.hdf5"],
     "argument --valid-ratio: must be a finite number in [0, 1), got '1.5'"),
    ("veragmil-collect", [*SCRIPTED, "--max-attempts", "0", "--output", "{tmp}/a.hdf5"],
     "argument --max-attempts: must be a positive integer, got 0"),
    ("veragmil-collect", [*SCRIPTED, "--success-hold", "nan", "--output", "{tmp}/a.hdf5"],
     "argument --success-hold: must be a finite number in [0, inf), got 'nan'"),
    ("veragmil-collect", [*SCRIPTED, "--output", "{tmp}/a.hdf5", "--directory", "{tmp}/d"],
     "give --output FILE (appended to when it exists) or --directory DIR (robosuite's), one"),
    ("veragmil-collect", [*SCRIPTED, "--arm", "left", "--output", "{tmp}/a.hdf5"],
     "--arm left: the spoon is on the right arm"),
    ("veragmil-collect", [*SCRIPTED, "--max-fr", "1e-6", "--output", "{tmp}/a.hdf5"],
     "argument --max-fr: must be at least 1 control step per second, got '1e-6'"),
    ("veragmil-collect", [*SCRIPTED, "--keep", "ask", "--output", "{tmp}/a.hdf5"],
     "--keep ask asks the person at the device; --device scripted keeps all or success"),
    ("veragmil-collect", [*SCRIPTED, "--episodes", "5", "--max-attempts", "2", "--output", "{tmp}/a.hdf5"],
     "--max-attempts 2 is fewer than --episodes 5"),
    ("veragmil-collect", [*SCRIPTED, "--seed", "4294967295", "--output", "{tmp}/a.hdf5"],
     "seed 4294967295: its 5 attempt seeds run to 4294967299, past numpy's largest seed 4294967295; give a seed of "
     "at most 4294967291"),
    ("veragmil-collect", [*SCRIPTED, "--depth", "--camera-names", "--output", "{tmp}/a.hdf5"],
     "--depth records <camera>_depth beside each camera's image: give --camera-names"),
    ("veragmil-collect", [*SCRIPTED, "--camera-height", "100000", "--output", "{tmp}/a.hdf5"],
     "argument --camera-height: must be a size in pixels in [1, 4096], got 100000"),
    ("veragmil-merge", [SAMPLE, SAMPLE, "--output", "{tmp}/m.hdf5"], f"INPUTS {SAMPLE} is given twice"),
    ("veragmil-render-obs", [SAMPLE, "--demos", "demo_0", "demo_0", "--output", "{tmp}/r.hdf5"],
     "argument --demos: demo_0 given twice"),
    ("veragmil-robomimic-playback", ["--dataset", SAMPLE, "--use-obs", "--video_path", "{tmp}/v.mp4",
     "--render_image_names", "agentview_image"], "with --use-obs, an image observation the dataset stores; "
     "accepted: overhead_image"),
    ("veragmil-dataset-info", ["{missing}"], "no such file"),
    ("benchmarks/bench_against.py", ["--base", "{tmp}"], "holds no veragmil_suite/__init__.py"),
    ("benchmarks/bench_eval.py", ["--seed", "4294967295", "--episodes", "2"], "past numpy's largest seed"),
    ("benchmarks/bench_policy.py", ["--steps", "12"], "--steps 12: must be a multiple of every case's chunk ([1, 8])"),
    ("benchmarks/bench_policy.py", ["--steps", "200"], "--steps 200: the sample data's first demo has 193 steps"),
    ("benchmarks/bench_policy.py", ["--checkpoint", CHECKPOINT], "a bc checkpoint; give a diffusion_policy one"),
    ("veragmil-dataset-info", ["{tmp}"], "is a directory"),
    ("veragmil-merge", ["{missing}", "--output", "{tmp}/m.hdf5"], "no such file"),
    ("veragmil-merge", [SAMPLE, "--output", "{tmp}"], "is a directory, not a dataset file"),
    ("veragmil-merge", [SAMPLE, "--output", "{tmp}/no/m.hdf5"], "the folder {tmp}/no does not exist"),
    ("veragmil-merge", [SAMPLE, "--output", "{tmp}/" + LONG_NAME], "the file name is longer than 247 bytes"),
    ("veragmil-merge", [SAMPLE, "--output", "{tmp}/m.hdf5", "--valid-ratio", "5"],
     "argument --valid-ratio: must be a finite number in [0, 1), got '5'"),
    ("veragmil-split", ["{missing}"], "no such file"),
    ("veragmil-split", [SAMPLE, "--ratio", "1.5"], "argument --valid-ratio/--ratio: must be a finite number in [0, 1)"),
    ("veragmil-replay", ["{missing}", "--use-actions"], "no such file"),
    ("veragmil-replay", [SAMPLE, "--size", "0", "--output", "{tmp}/v.mp4"], "argument --size: must be a size in"),
    ("veragmil-replay", [SAMPLE, "--output", "{tmp}/no/v.mp4"], "the folder {tmp}/no does not exist"),
    ("veragmil-replay", [SAMPLE, "--use-actions", "--fps", "0"], "argument --fps: must be a finite number in (0, inf)"),
    ("veragmil-replay", [SAMPLE], "give --output (a video) and/or --use-actions (a replay check)"),
    ("veragmil-render-obs", ["{missing}", "--output", "{tmp}/r.hdf5"], "no such file"),
    ("veragmil-render-obs", [SAMPLE, "--size", "0", "--output", "{tmp}/r.hdf5"], "argument --size: must be a size"),
    ("veragmil-render-obs", [SAMPLE, "--output", "{tmp}/no/r.hdf5"], "the folder {tmp}/no does not exist"),
    ("veragmil-render-obs", [SAMPLE, "--output", "{tmp}/r.hdf5", "--cameras", "nocam"],
     "argument --camera-names/--cameras: unknown camera 'nocam'; accepted: "),
    ("veragmil-train", ["--config", "{missing}"], "veragmil-train: error: argument --config: {missing}: no such file"),
    ("veragmil-train", ["--config", "{tmp}/bad.json"],
     "argument --config: {tmp}/bad.json: not a readable robomimic config (JSON) (not JSON"),
    ("veragmil-train", ["--config", "{tmp}"], "is a directory, not a robomimic config"),
    ("veragmil-train", [], "give --config FILE (a robomimic config) or --algo NAME (its default config)"),
    ("veragmil-train", ["--algo", "nonexistent"], "unknown robomimic algorithm 'nonexistent'; accepted: bc, bcq, "),
    ("veragmil-train", ["--config", "{tmp}/bogus_key.json"], "key 'bogus_key' does not exist"),
    ("veragmil-train", ["--config", "{tmp}/bogus_algo.json"], "algo_name 'gail' is not one of robomimic's: bc, "),
    ("veragmil-train", ["--config", "{tmp}/no_data.json"],
     "give --dataset FILE (a robomimic dataset), or name it in the config's train.data"),
    ("veragmil-train", ["--algo", "bc"], "give --dataset FILE (a robomimic dataset), or name it in the config's"),
    ("veragmil-train", ["--algo", "bc", "--dataset", SAMPLE],
     "holds no robot0_gripper_qpos observations, which robomimic's default bc config trains on; the spoon has no"),
    ("veragmil-train", ["--config", "{tmp}/data_list.json"], "train.data is ['a.hdf5']: it must be a string or null"),
    ("veragmil-train", ["--config", "{tmp}/out_file.json", "--dataset", SAMPLE],
     "--config's train.output_dir: {tmp}/bad.json/runs: not a directory"),
    ("veragmil-train", ["--config", "{tmp}/no_data.json", "--dataset", SAMPLE, "--name", "../elsewhere"],
     "argument --name: must be an experiment name: one folder's name, no path, got '../elsewhere'"),
    ("veragmil-train", ["--config", "{tmp}/name_path.json", "--dataset", SAMPLE],
     "--config's experiment.name: must be an experiment name: one folder's name, no path, got 'a/b'"),
    ("veragmil-train", ["--config", "{tmp}/epochs.json"], "train.num_epochs is -3: it must be a whole number of at"),
    ("veragmil-train", ["--config", "{tmp}/batch.json"], "train.batch_size is 'abc': it must be a whole number of at"),
    ("veragmil-train", ["--config", "{tmp}/flag.json"], "train.hdf5_normalize_obs is 'yes': it must be true or false"),
    ("veragmil-train", ["--config", "{tmp}/wrench.json", "--dataset", SAMPLE],
     "scoop.hdf5 holds no robot0_eef_force, robot0_eef_torque observations, which {tmp}/wrench.json trains on; record"),
    ("veragmil-run-agent", ["--agent", "{missing}", "--n_rollouts", "1"], "no such file"),
    ("veragmil-run-agent", ["--agent", "{tmp}/fake.pth"], "not a readable robomimic checkpoint (.pth) (torch cannot"),
    ("veragmil-run-agent", ["--agent", "{tmp}/dict.pth"], "it lacks algo_name, config, env_metadata"),
    ("veragmil-run-agent", ["--agent", "{tmp}/list.pth"], "it holds a list, not a checkpoint dict"),
    ("veragmil-run-agent", ["--agent", "{tmp}/truncated.pth"], "torch cannot read it"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{missing}"], "no such file"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{tmp}/fake.pth"], "(no HDF5 signature)"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{tmp}/truncated.hdf5"], "not a readable robomimic dataset"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{tmp}/other.hdf5"], "robomimic's layout needs a 'data' group"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{tmp}/flat_obs.hdf5"], "data/demo_0/obs is not a group"),
    ("veragmil-robomimic-playback", ["--dataset", "{missing}", "--n", "1"], "no such file"),
    ("veragmil-robomimic-playback", ["--dataset", "{tmp}/other.hdf5"], "robomimic's layout needs a 'data' group"),
    ("veragmil-robomimic-playback", ["--dataset", SAMPLE, "--render"], "--render needs a display"),
    ("veragmil-robomimic-playback", ["--n", "1"], "give --dataset FILE (a robomimic dataset)"),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{missing}", "--output_name", "x.hdf5"], "no such file"),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{tmp}/fake.pth", "--output_name", "x.hdf5"],
     "(no HDF5 signature)"),
    ("veragmil-evaluate", [*EVAL, "--seed", "4294967295", "--episodes", "2"],
     "seed 4294967295: its 2 episode seeds run to 4294967296, past numpy's largest seed"),
    ("veragmil-evaluate", [*EVAL, "--videos", "5", "--episodes", "2"],
     "videos 5 is more than the 2 episodes per agent and food"),
    ("veragmil-evaluate", [*EVAL, "--foods", "caviar"], "caviar"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"bogus": 1}}'],
     "unknown ScoopGranular argument(s) bogus; accepted: robots, "),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"n_grains": -1}}'], "n_grains: must be a positive integer"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"horizon": -5}}'], "horizon is set by --horizon"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"robots": "Nonexistent"}}'], "robots is set by --robots"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"food": "sushi"}}'], "food is set by --foods"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"physics": "lunar"}}'], "unknown physics 'lunar'; accepted"),
    ("veragmil-evaluate", [*EVAL, "--env-kwargs", '{{"control_freq": 1e-9}}'],
     "control_freq: must be a control rate in Hz of at least 1"),
    ("veragmil-evaluate", [*EVAL, "--foods", "pasta", "--env-kwargs", '{{"n_grains": 500}}'],
     "--env-kwargs: n_grains: at most 160 grains of pasta"),
    ("veragmil-evaluate", ["--agent", "{missing}", "--output-dir", "{tmp}/e"], "unrecognized agent"),
    ("veragmil-evaluate", ["--agent", "{tmp}/fake.pth", "--output-dir", "{tmp}/e"], "not a readable robomimic check"),
    ("veragmil-evaluate", ["--agent", "{tmp}/dict.pth", "--output-dir", "{tmp}/e"], "it lacks algo_name"),
    ("veragmil-evaluate", ["--agent", "expert", "--output-dir", "{tmp}/bad.json"], "is a file, not a folder"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--seed", "4294900000"],
     "its 100003 recording and evaluation seeds run to 4295000002, past numpy's largest seed"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--episodes", "0"], "argument --episodes: must be a positive"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--demos-per-food", "0"], "argument --demos-per-food: must be"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algo-epochs", "rnn=4"],
     f"argument --algo-epochs: 'rnn=4': unknown algorithm 'rnn'; accepted: {', '.join(sorted(ALGORITHMS))}"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algos", "bc", "--algo-epochs", "bc_rnn=40"],
     "algo_epochs names bc_rnn, which algos ['bc'] does not train"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algo-epochs", "bc=3", "--algo-epochs", "bc=4"],
     "algo_epochs gives bc two budgets: give one"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--train-foods", "rice", "rice"],
     "argument --train-foods: rice given twice"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algo-epochs", "bcq=0"],
     "argument --algo-epochs: 'bcq=0': must be a positive integer, got 0"),
    ("veragmil-quickstart", ["--episodes", "0"], "argument --episodes: must be a positive"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--agent", "old=nowhere.pth"], "checkpoint 'nowhere.pth' not found"),
    ("veragmil-export-lerobot", ["{missing}", "--output-dir", "{tmp}/l"], "no such file"),
    ("veragmil-export-lerobot", [SAMPLE, "--output-dir", "{tmp}/l", "--filter-key", "caviar"],
     "has no filter key 'caviar'; its filter keys: "),
    ("veragmil-export-lerobot", [SAMPLE, "--output-dir", "{tmp}/l", "--vcodec", "mpeg2"], "mpeg2"),
    ("veragmil-bench", ["--foods", "caviar"], "caviar"),
    ("veragmil-bench", ["--steps", "0"], "argument --steps: must be a positive integer, got 0"),
    ("veragmil-bench", ["--steps", "-5"], "argument --steps: must be a positive integer, got -5"),
    ("veragmil-bench", ["--scales", "0"], "argument --scales: must be a finite number in (0, 4]"),
    ("veragmil-bench", ["--sleep-tolerance", "0"],
     "argument --sleep-tolerance: must be a finite number in (0, inf), got '0'"),
]  # fmt: skip


def _bad_files(folder: Path) -> None:
    """Files that are not what a program expects: bad JSON, configs robomimic refuses, checkpoints and HDF5 files
    that are not robomimic's."""
    import h5py
    import torch

    (folder / "bad.json").write_text("{not json")
    (folder / "bogus_key.json").write_text('{"algo_name": "bc", "bogus_key": 1}')
    (folder / "bogus_algo.json").write_text('{"algo_name": "gail"}')
    (folder / "epochs.json").write_text('{"algo_name": "bc", "train": {"num_epochs": -3}}')
    (folder / "batch.json").write_text('{"algo_name": "bc", "train": {"batch_size": "abc"}}')
    (folder / "flag.json").write_text('{"algo_name": "bc", "train": {"hdf5_normalize_obs": "yes"}}')
    (folder / "no_data.json").write_text('{"algo_name": "bc"}')
    (folder / "name_path.json").write_text('{"algo_name": "bc", "experiment": {"name": "a/b"}}')
    (folder / "data_list.json").write_text('{"algo_name": "bc", "train": {"data": ["a.hdf5"]}}')
    (folder / "out_file.json").write_text(
        json.dumps({"algo_name": "bc", "train": {"output_dir": f"{folder}/bad.json/runs"}})
    )
    low_dim = ["robot0_eef_pos", "robot0_eef_force", "robot0_eef_torque"]  # the wrist sensor: scoop.hdf5 lacks it
    wrench = {"algo_name": "bc", "observation": {"modalities": {"obs": {"low_dim": low_dim}}}}
    (folder / "wrench.json").write_text(json.dumps(wrench))
    (folder / "fake.pth").write_text("hello")
    torch.save({"a": 1}, folder / "dict.pth")
    torch.save([1, 2], folder / "list.pth")
    (folder / "truncated.pth").write_bytes((folder / "dict.pth").read_bytes()[:100])
    (folder / "truncated.hdf5").write_bytes(Path(SAMPLE).read_bytes()[:5000])
    with h5py.File(folder / "other.hdf5", "w") as f:
        f["x"] = [1, 2]
    with h5py.File(folder / "flat_obs.hdf5", "w") as f:
        f.create_group("data").attrs["env_args"] = "{}"
        f["data/demo_0/actions"] = [[0.0]]
        f["data/demo_0/obs"] = [1.0]


@pytest.mark.parametrize("program,args,message", CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_bad_input_gets_one_clear_line(program, args, message, tmp_path, capsys):
    # robosuite's log into this test's captured stderr, and back afterwards (a handler left on a closed capture
    # stream would print "--- Logging error ---" tracebacks into later tests)
    handlers = [h for h in logging.getLogger("robosuite_logs").handlers if isinstance(h, logging.StreamHandler)]
    streams = [h.stream for h in handlers]
    for handler in handlers:
        handler.stream = sys.stderr
    try:
        _check_one_clear_line(program, args, message, tmp_path, capsys)
    finally:
        for handler, stream in zip(handlers, streams):
            handler.stream = stream


def _check_one_clear_line(program, args, message, tmp_path, capsys):
    _bad_files(tmp_path)
    before = set(tmp_path.rglob("*"))
    missing = tmp_path / "missing.hdf5"
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        argv = [a.format(tmp=tmp_path, missing=missing, busy=port) for a in args]
        message = message.format(tmp=tmp_path, missing=missing)
        _run_and_check(program, argv, message, tmp_path, before, capsys)


def _run_and_check(program, argv, message, tmp_path, before, capsys):
    code = main_of(program)(argv)
    out, err = capsys.readouterr()
    # what the program said: robosuite's and robomimic's import warnings aside (argparse's usage block is not
    # printed: one line)
    warnings = (" ", "[robosuite", "ROBOMIMIC WARNING(", ")")
    said = [line for line in err.splitlines() if line.strip() and not line.startswith(warnings)]
    assert code == 2, f"exit {code}; stderr: {err[-2000:]}"
    assert "Traceback" not in err and "Traceback" not in out
    assert message in err, err[-2000:]
    assert len(said) == 1, said
    assert set(tmp_path.rglob("*")) == before  # nothing created


@pytest.mark.parametrize("control_freq", [1e-9, 0.5, float("nan"), float("inf"), -20, True])
def test_robosuite_make_refuses_a_control_rate_it_would_hang_on(control_freq):
    """robosuite runs period / physics step substeps per control step: 1e-9 Hz never returned."""
    import robosuite

    import veragmil_suite  # noqa: F401

    with pytest.raises(ValueError, match="control_freq must be a number of Hz of at least 1"):
        robosuite.make("ScoopGranular", robots="XArm7", control_freq=control_freq, has_offscreen_renderer=False)


@pytest.mark.parametrize(
    "name,value,message",
    [
        ("VERAGMIL_TORCH_THREADS", "two", "$VERAGMIL_TORCH_THREADS: must be a positive integer, got 'two'"),
        ("VERAGMIL_TORCH_THREADS", "0", "$VERAGMIL_TORCH_THREADS: must be a positive integer, got 0"),
        ("VERAGMIL_RESUME_EVERY_S", "-5", "$VERAGMIL_RESUME_EVERY_S: must be a finite number in [0, inf), got '-5'"),
        (
            "VERAGMIL_RESUME_EVERY_S",
            "soon",
            "$VERAGMIL_RESUME_EVERY_S: must be a finite number in [0, inf), got 'soon'",
        ),
    ],
)
def test_a_malformed_number_in_the_environment_gets_one_clear_line(name, value, message, tmp_path, capsys, monkeypatch):
    """A training would read it only after loading its data (a traceback, exit 1); every program checks it first."""
    monkeypatch.setenv(name, value)
    before = set(tmp_path.rglob("*"))
    config = ROOT / "configs" / "json" / "bc.json"
    _run_and_check("veragmil-train", ["--config", str(config), "--dataset", SAMPLE], message, tmp_path, before, capsys)


EVALUATION = str(ROOT / "results" / "grid_size_expert_bc" / "results.json")
# (program, arguments, what the one line must say) with an output that is there already, or is an input: {d} is a
# folder holding data.hdf5 (the sample), link.hdf5 (a hard link to it), old.mp4, old.hdf5, a finished evaluation
# (pool/results.json), a study (study/eval/results.json) and a published folder (published/RUN.md)
POOLED = "a={d}/pool/results.json:expert BC no-load-size obs seed 1"
OUTPUT_CASES = [
    ("veragmil-replay", ["{d}/data.hdf5", "-o", "{d}/data.hdf5"], "not a video file name; accepted: .mp4"),
    ("veragmil-replay", ["{d}/data.hdf5", "-o", "{d}/old.mp4"], "{d}/old.mp4 exists (use --force to overwrite it)"),
    ("veragmil-robomimic-playback", ["--dataset", "{d}/data.hdf5", "--video_path", "{d}/data.hdf5"],
     "not a video file name"),
    ("veragmil-robomimic-playback", ["--dataset", "{d}/data.hdf5", "--video_path", "{d}/old.mp4", "--n", "1"],
     "{d}/old.mp4 exists (use --force to overwrite it)"),
    ("veragmil-robomimic-playback", ["--dataset", "{d}/data.hdf5", "--filter_key", "nosuch", "--video_path",
     "{d}/new.mp4"], "has no filter key 'nosuch'; its filter keys: "),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{d}/data.hdf5", "--filter_key", "nosuch"],
     "has no filter key 'nosuch'; its filter keys: "),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{d}/data.hdf5", "--output_name", "data.hdf5", "--force"],
     "--output-name {d}/data.hdf5 is also an input: write it to a new file"),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{d}/data.hdf5", "--output_name", "link.hdf5", "--force"],
     "is also an input"),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{d}/data.hdf5", "--output_name", "old.hdf5"],
     "{d}/old.hdf5 exists (use --force to overwrite it)"),
    ("veragmil-run-agent", ["--agent", CHECKPOINT, "--n_rollouts", "1", "--dataset_path", "{d}/old.hdf5"],
     "{d}/old.hdf5 exists (use --force to overwrite it)"),
    ("veragmil-run-agent", ["--agent", CHECKPOINT, "--n_rollouts", "1", "--video_path", "{d}/old.mp4"],
     "{d}/old.mp4 exists (use --force to overwrite it)"),
    ("veragmil-drop-noops", ["{d}/data.hdf5", "-o", "{d}/link.hdf5", "--force"], "is also the input"),
    ("veragmil-render-obs", ["{d}/data.hdf5", "-o", "{d}/link.hdf5", "--force"], "is also the input"),
    ("veragmil-merge", ["{d}/data.hdf5", "{d}/old.hdf5", "-o", "{d}/link.hdf5", "--force"], "is also an input"),
    ("veragmil-pool-results", ["{d}/pool", "--agent", POOLED],
     "{d}/pool holds {d}/pool/results.json, which is pooled: write the pool to another folder"),
    ("veragmil-pool-results", ["{d}/study/eval", "--agent", POOLED],
     "{d}/study/eval/results.json exists (use --force to overwrite it)"),
    ("veragmil-publish-results", ["{d}/study", "--output-dir", "{d}/study/eval", "--command", "c", "--force"],
     "is the study's own evaluation folder"),
    ("veragmil-publish-results", ["{d}/study", "--output-dir", "{d}/published", "--command", "c"],
     "{d}/published/RUN.md exists (use --force to overwrite it)"),
    ("python -m veragmil_suite.calibration", ["--quick", "--foods", "peas", "--json", "{d}/old.json"],
     "{d}/old.json exists (use --force to overwrite it)"),
    ("python -m veragmil_suite.scripts.measure_expert", ["--episodes", "1", "--json", "{d}/old.json"],
     "{d}/old.json exists (use --force to overwrite it)"),
]  # fmt: skip


@pytest.fixture(scope="module")
def outputs_folder(tmp_path_factory) -> Path:
    import shutil

    folder = tmp_path_factory.mktemp("outputs")
    shutil.copy(SAMPLE, folder / "data.hdf5")
    (folder / "link.hdf5").hardlink_to(folder / "data.hdf5")
    shutil.copy(SAMPLE, folder / "old.hdf5")
    (folder / "old.mp4").write_bytes(b"an earlier video")
    (folder / "old.json").write_text('{"what": "an earlier measurement"}')
    for where in ("pool", "study/eval"):
        (folder / where).mkdir(parents=True)
        shutil.copy(EVALUATION, folder / where / "results.json")
    (folder / "published").mkdir()
    (folder / "published" / "RUN.md").write_text("what an earlier publication wrote\n")
    return folder


def _contents(folder: Path) -> dict[str, str]:
    import hashlib

    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("program,args,message", OUTPUT_CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(OUTPUT_CASES)])
def test_an_output_that_exists_or_is_an_input_is_refused_and_left_as_it_was(
    program, args, message, outputs_folder, capsys
):
    """A program never writes over a file that is there without --force (a recording, a video, an evaluation, a
    publication), nor over one of its own inputs even with it (a hard link is the same file): one line, exit 2."""
    before = _contents(outputs_folder)
    argv = [a.format(d=outputs_folder) for a in args]
    _run_and_check(
        program, argv, message.format(d=outputs_folder), outputs_folder, set(outputs_folder.rglob("*")), capsys
    )
    assert _contents(outputs_folder) == before


def test_a_live_window_without_a_display_is_refused_before_anything_is_recorded(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    argv = [*SCRIPTED, "--render", "on", "--output", "{tmp}/a.hdf5"]
    _run_and_check("veragmil-collect", [a.format(tmp=tmp_path) for a in argv], "--render on needs a display",
                   tmp_path, set(tmp_path.rglob("*")), capsys)  # fmt: skip
