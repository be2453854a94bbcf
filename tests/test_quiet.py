"""
Quiet by default: making an environment, recording (a tiny scripted collection), training (a few gradient steps)
and evaluating (one short episode) print no warning, no log record at WARNING or above and no line of their own
beyond what each program prints by design. Each stage runs in a fresh interpreter (tests/helpers/stage.py), so what
robosuite and robomimic say at import counts too; every warning of veragmil_suite's own modules is shown there.
"""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.output import warning_lines

from veragmil_suite.private_macros import (
    PRIVATE_MACROS_FILE,
    missing_private_macros,
    private_macros_text,
    write_private_macros,
)

ROOT = Path(__file__).resolve().parents[1]
LIGHT_SCENE = {"food": "pasta", "n_grains": 12, "pile_variants": 1}
# what veragmil-collect --quiet prints: a line per episode, what became of it, the summary
COLLECT_LINES = re.compile(r"episode \d+: .*|  (saved as|discarded).*|\d+ attempts, .*")
# what veragmil-evaluate --quiet prints: its tables and where they went
EVALUATE_LINES = re.compile(
    r"Table (II|III): .*|Physics \(grain models.*\): calibrated|Spill limit of success \(.*\): scooped|\|.*\|"
    r"|written to .*|"
)


def _stage(*args: str, timeout: int = 300) -> list[str]:
    """The lines a stage prints (stdout and stderr); fails on a non-zero exit."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    run = subprocess.run(
        [sys.executable, "-m", "helpers.stage", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        env=env,
        cwd=ROOT,
    )
    assert run.returncode == 0, f"{args[:2]} exited {run.returncode}:\n{run.stdout}\n{run.stderr}"
    return (run.stdout + run.stderr).splitlines()


def test_the_private_macros_files_are_there():
    missing = missing_private_macros()
    assert not missing, f"no private macros file of {missing}: python -m veragmil_suite.private_macros (make setup)"


def test_making_recording_training_and_evaluating_print_no_warning(tmp_path):
    assert not missing_private_macros(), "python -m veragmil_suite.private_macros first (make setup runs it)"
    scene = dict(LIGHT_SCENE, robots="XArm7", has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    made = _stage("env", json.dumps(scene))
    assert made == [], "making and stepping an environment printed:\n" + "\n".join(made)

    data = tmp_path / "demos.hdf5"
    recorded = _stage(
        *("veragmil_suite.scripts.collect_human_demonstrations", "main", "--device", "scripted", "--quiet"),
        *("--food", "pasta", "--n-grains", "12", "--episodes", "1", "--keep", "all", "--max-attempts", "1"),
        *("--horizon", "10", "--cameras", "--output", str(data)),
    )
    stray = [line for line in recorded if not COLLECT_LINES.fullmatch(line)]
    assert recorded and not stray and not warning_lines(recorded), "recording printed:\n" + "\n".join(recorded)

    with open(ROOT / "configs" / "json" / "bc.json") as f:
        config = json.load(f)
    config["experiment"].update(name="quiet", epoch_every_n_steps=3, validate=False, render_video=False)
    config["experiment"]["rollout"]["enabled"] = False
    config["experiment"]["save"].update(enabled=True, every_n_epochs=1)
    config["train"].update(data=str(data), output_dir=str(tmp_path / "runs"), num_epochs=1, batch_size=4)
    config["train"]["hdf5_filter_key"] = None
    (tmp_path / "bc.json").write_text(json.dumps(config))
    trained = _stage("veragmil_suite.scripts.robomimic_entry", "train_main", "--config", str(tmp_path / "bc.json"))
    # robomimic's own report (its config, model, epochs) is what veragmil-train prints by design: the pipeline keeps
    # it in a log file; here it must hold no warning
    assert "finished run successfully!" in trained and not warning_lines(trained), "\n".join(warning_lines(trained))

    checkpoint = next((tmp_path / "runs" / "quiet").glob("*/models/model_epoch_1.pth"))
    evaluated = _stage(
        *("veragmil_suite.scripts.evaluate", "main", "--agent", f"bc={checkpoint}", "--foods", "pasta", "--quiet"),
        *("--episodes", "1", "--horizon", "10", "--processes", "1", "--output-dir", str(tmp_path / "eval")),
        *("--env-kwargs", json.dumps({"n_grains": 12, "pile_variants": 1})),
    )
    stray = [line for line in evaluated if not EVALUATE_LINES.fullmatch(line)]
    assert not stray and not warning_lines(evaluated), "evaluating printed:\n" + "\n".join(evaluated)


def test_a_private_macros_file_is_written_once_and_an_existing_one_is_kept(tmp_path):
    written = write_private_macros(tmp_path, "robosuite", {"CONSOLE_LOGGING_LEVEL": "WARNING"})
    assert written == tmp_path / PRIVATE_MACROS_FILE
    namespace: dict = {}
    exec(written.read_text(), namespace)
    assert namespace["CONSOLE_LOGGING_LEVEL"] == "WARNING"
    written.write_text("CONSOLE_LOGGING_LEVEL = 'DEBUG'\n")
    assert write_private_macros(tmp_path, "robosuite", {"CONSOLE_LOGGING_LEVEL": "WARNING"}) is None
    assert "DEBUG" in written.read_text() and "WARNING" in private_macros_text("robosuite", {"X": "WARNING"})


COUNTED = ["[robosuite WARNING] No private macro", "ROBOMIMIC WARNING(", "a.py:3: UserWarning: b", "log record ERROR a"]


@pytest.mark.parametrize("line", COUNTED)
def test_the_warning_lines_counted_are_those_robosuite_robomimic_python_and_logging_print(line):
    assert warning_lines([line]) == [line]
    assert not warning_lines(["Warnings generated by robomimic have been duplicated here (from above)"])
