"""veragmil-quickstart and veragmil-study: settings, the shortened configs, and the main job end to end (tiny)."""

import json
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from veragmil_suite.asset_paths import config_path
from veragmil_suite.pipeline import PipelineSettings, training_config

BIN = Path(sys.executable).parent


def _run(command, *args, timeout=600, cwd=None):
    return subprocess.run(
        [str(BIN / command), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        cwd=cwd,
    )


@pytest.mark.parametrize("algo", ["bc", "bc_rnn", "bcq"])
def test_training_config_shortens_our_config_and_changes_nothing_else(algo, tmp_path):
    with open(config_path(algo)) as f:
        stock = json.load(f)
    config = training_config(algo, tmp_path / "d.hdf5", tmp_path / "runs", "x", epochs=7, steps_per_epoch=11)
    assert config["train"]["num_epochs"] == 7 and config["experiment"]["epoch_every_n_steps"] == 11
    assert config["train"]["data"] == str(tmp_path / "d.hdf5")
    assert config["experiment"]["rollout"]["enabled"] is False
    assert config["experiment"]["save"]["every_n_epochs"] == 7  # the last epoch is the checkpoint evaluated
    assert config["algo"] == stock["algo"] and config["observation"] == stock["observation"]
    assert config["train"]["seq_length"] == stock["train"]["seq_length"]


def test_bad_settings_name_the_accepted_values(tmp_path):
    with pytest.raises(ValueError, match="accepted foods"):
        PipelineSettings(output_dir=str(tmp_path), eval_foods=["rice", "lentils"])
    with pytest.raises(ValueError, match=r"accepted: \['bc', 'bc_rnn', 'bcq'\]"):
        PipelineSettings(output_dir=str(tmp_path), algos=["diffusion"])
    with pytest.raises(ValueError, match="episodes must be a positive integer"):
        PipelineSettings(output_dir=str(tmp_path), episodes=0)
    result = _run("veragmil-study", "--output-dir", tmp_path / "s", "--algos", "gail", timeout=60)
    assert result.returncode == 2 and "invalid choice: 'gail'" in result.stderr
    result = _run("veragmil-quickstart", "--output-dir", tmp_path / "q", "--episodes", "0", timeout=60)
    assert result.returncode == 2 and "episodes must be a positive integer" in result.stderr
    assert not (tmp_path / "q").exists() and not (tmp_path / "s").exists()


def test_quickstart_end_to_end_records_trains_evaluates_and_prints_the_tables(tmp_path):
    """The README's main job, shrunk: one cheap food, one demo, a few gradient steps, one episode per agent."""
    out = tmp_path / "qs"
    args = ["--output-dir", out, "--train-foods", "pasta", "--eval-foods", "pasta", "peas", "--n-grains", "12"]
    args += ["--demos-per-food", "1", "--epochs", "2", "--steps-per-epoch", "5", "--episodes", "1", "--horizon", "300"]
    result = _run("veragmil-quickstart", *args)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    with h5py.File(out / "data" / "expert.hdf5") as f:
        assert len(f["data"]) == 1
        assert json.loads(f["data"].attrs["env_args"])["env_kwargs"]["food"] == "pasta"
    (checkpoint,) = (out / "runs").glob("expert_bc/*/models/model_epoch_2.pth")
    summary = json.loads((out / "eval" / "results.json").read_text())
    agents = {e["agent"] for e in summary["episodes"]}
    assert agents == {"expert BC", "expert operator"}
    assert {(e["agent"], e["food"]) for e in summary["episodes"]} == {(a, f) for a in agents for f in ("pasta", "peas")}
    for name in ("table.md", "table.csv", "episodes.csv", "success.png"):
        assert (out / "eval" / name).stat().st_size > 0
    assert "expert BC" in result.stdout and "peas" in result.stdout and "pasta" in result.stdout
    # nothing recorded is overwritten by a second run into the same folder
    again = _run("veragmil-quickstart", *args)
    assert again.returncode == 1 and "exists" in again.stderr
    assert checkpoint.exists()
