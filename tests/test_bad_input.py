"""One clear line for every bad input, in every console program of setup.py: exit status 2, the problem and the
accepted values named, no traceback, nothing created. A program added to setup.py without cases here fails
test_every_console_program_has_cases."""

import importlib
import logging
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENTRY_POINTS = dict(re.findall(r'"(veragmil-[\w-]+)=([\w.]+:\w+)"', (ROOT / "setup.py").read_text()))
SAMPLE = str(ROOT / "demos" / "scoop.hdf5")
LIGHT = ["--food", "pasta", "--n-grains", "12"]

# (program, arguments, what the one line must say); {tmp} is a fresh directory, {missing} a file that is not there
CASES = [
    ("veragmil-collect", ["--device", "scripted", *LIGHT, "--robot", "Nonexistent", "--output", "{tmp}/a.hdf5"],
     "Unknown robot 'Nonexistent'; robosuite's robots: "),
    ("veragmil-collect", ["--device", "scripted", *LIGHT, "--control-freq", "7", "--output", "{tmp}/a.hdf5"],
     "accepted control frequencies"),
    ("veragmil-collect", ["--device", "vr", *LIGHT, "--vr-port", "99999", "--output", "{tmp}/a.hdf5"],
     "argument --vr-port: must be a TCP port in 0-65535, got 99999"),
    ("veragmil-collect", ["--device", "scripted", "--food", "pasta", "--n-grains", "100000", "--output",
     "{tmp}/a.hdf5"], "n_grains 100000 is more than a bowl of pasta settles in reasonable time: at most 160"),
    ("veragmil-collect", ["--device", "scripted", *LIGHT, "--camera-size", "0", "--output", "{tmp}/a.hdf5"],
     "argument --camera-size: must be a positive integer, got 0"),
    ("veragmil-collect", ["--device", "scripted", *LIGHT, "--output", "{tmp}"], "is a directory, not a dataset file"),
    ("veragmil-collect", ["--device", "scripted", "--food", "caviar", "--output", "{tmp}/a.hdf5"],
     "argument --food: unknown food 'caviar'; accepted: rice, "),
    ("veragmil-dataset-info", ["{missing}"], "no such file"),
    ("veragmil-dataset-info", ["{tmp}"], "is a directory"),
    ("veragmil-merge", ["{missing}", "--output", "{tmp}/m.hdf5"], "no such file"),
    ("veragmil-split", ["{missing}"], "no such file"),
    ("veragmil-split", [SAMPLE, "--ratio", "1.5"], "argument --valid-ratio/--ratio: must be a finite number in [0, 1)"),
    ("veragmil-replay", ["{missing}", "--use-actions"], "no such file"),
    ("veragmil-replay", [SAMPLE, "--size", "0", "--output", "{tmp}/v.mp4"], "argument --size: must be a positive"),
    ("veragmil-render-obs", ["{missing}", "--output", "{tmp}/r.hdf5"], "no such file"),
    ("veragmil-render-obs", [SAMPLE, "--size", "0", "--output", "{tmp}/r.hdf5"], "argument --size: must be a positive"),
    ("veragmil-train", ["--config", "{missing}"], "veragmil-train: error: argument --config: {missing}: no such file"),
    ("veragmil-train", ["--config", "{tmp}/bad.json"], "argument --config: {tmp}/bad.json: not a readable robomimic config (JSON) (not JSON"),
    ("veragmil-train", ["--config", "{tmp}"], "is a directory, not a robomimic config"),
    ("veragmil-run-agent", ["--agent", "{missing}", "--n_rollouts", "1"], "no such file"),
    ("veragmil-robomimic-dataset-info", ["--dataset", "{missing}"], "no such file"),
    ("veragmil-robomimic-playback", ["--dataset", "{missing}", "--n", "1"], "no such file"),
    ("veragmil-robomimic-states-to-obs", ["--dataset", "{missing}", "--output_name", "x.hdf5"], "no such file"),
    ("veragmil-evaluate", ["--agent", "expert", "--output-dir", "{tmp}/e", "--foods", "caviar"], "caviar"),
    ("veragmil-evaluate", ["--agent", "expert", "--output-dir", "{tmp}/e", "--env-kwargs", '{{"bogus": 1}}'],
     "unknown ScoopGranular argument(s) bogus; accepted: robots, "),
    ("veragmil-evaluate", ["--agent", "{missing}", "--output-dir", "{tmp}/e"], "unrecognized agent"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--episodes", "0"], "argument --episodes: must be a positive"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--demos-per-food", "0"], "argument --demos-per-food: must be"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algo-epochs", "rnn=4"], "argument --algo-epochs: 'rnn=4': unknown algorithm 'rnn'; accepted: bc, bc_rnn, bcq"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--algo-epochs", "bcq=0"], "argument --algo-epochs: 'bcq=0': must be a positive integer, got 0"),
    ("veragmil-quickstart", ["--episodes", "0"], "argument --episodes: must be a positive"),
    ("veragmil-study", ["--output-dir", "{tmp}/s", "--agent", "old=nowhere.pth"], "checkpoint 'nowhere.pth' not found"),
    ("veragmil-bench", ["--foods", "caviar"], "caviar"),
    ("veragmil-bench", ["--sleep-tolerance", "0"], "argument --sleep-tolerance: must be a finite number in (0, inf), got '0'"),
]  # fmt: skip


def test_every_console_program_has_cases():
    assert ENTRY_POINTS, "no console programs found in setup.py"
    assert set(ENTRY_POINTS) <= {program for program, _, _ in CASES}


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
    (tmp_path / "bad.json").write_text("{not json")
    before = set(tmp_path.rglob("*"))
    missing = tmp_path / "missing.hdf5"
    argv = [a.format(tmp=tmp_path, missing=missing) for a in args]
    message = message.format(tmp=tmp_path, missing=missing)
    module, function = ENTRY_POINTS[program].split(":")
    main = getattr(importlib.import_module(module), function)
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (2 if e.code else 0)
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
    out, err = capsys.readouterr()
    # what the program said: argparse's usage block (first line "usage:", the rest indented) and robosuite's import
    # warnings aside
    said = [line for line in err.splitlines() if line.strip() and not line.startswith(("usage:", " ", "[robosuite"))]
    assert code == 2, f"exit {code}; stderr: {err[-2000:]}"
    assert "Traceback" not in err and "Traceback" not in out
    assert message in err, err[-2000:]
    assert len(said) == 1, said
    assert set(tmp_path.rglob("*")) == before  # nothing created
