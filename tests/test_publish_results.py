"""veragmil-publish-results: what a results/ folder records of the study that made it."""

import json
from pathlib import Path

import pytest

from veragmil_suite.scripts.publish_results import main
from veragmil_suite.study.publish import publish


def _study(tmp_path: Path, agents: dict[str, str], timings: dict[str, float]) -> Path:
    study = tmp_path / "study"
    (study / "eval").mkdir(parents=True)
    config = {"agents": agents, "episodes": 20, "seed": 100000, "versions": {"mujoco": "3.8.1"}}
    (study / "eval" / "results.json").write_text(json.dumps({"config": config, "summary": [], "episodes": []}))
    (study / "eval" / "table.md").write_text("| food |\n")
    (study / "timings.json").write_text(json.dumps(timings))
    return study


def test_run_md_lists_only_the_pieces_behind_its_models(tmp_path):
    agents = {
        "expert operator": "expert:expert",
        "expert BC seed 4": "runs/grid/runs/expert_bc_30demos_50000steps_seed4/20261125/models/model_epoch_100.pth",
        "expert-dart BCQ": "runs/grid/runs/expert-dart_bcq_30demos_50000steps/20261124/models/model_epoch_100.pth",
    }
    timings = {
        "record expert": 300.0,
        "record expert-dart": 310.0,
        "record spacemouse": 320.0,
        "train expert_bc_30demos_50000steps_seed4": 600.0,
        "train expert_bc_30demos_50000steps": 601.0,  # another seed, another evaluation's
        "train expert-dart_bcq_30demos_50000steps": 700.0,
        "train spacemouse_bcq_30demos_50000steps": 701.0,
        "evaluate": 599.8,
        "evaluate (seeds 2-3)": 712.9,  # a pooled study's second evaluation
    }
    dest = tmp_path / "results" / "four_seeds"
    written = publish(_study(tmp_path, agents, timings), dest, "veragmil-study --output-dir x")
    assert written == ["table.md", "results.json", "timings.json", "RUN.md"]
    run_md = (dest / "RUN.md").read_text()
    table = run_md.split("|---|---:|\n")[1].split("\n\n")[0]
    assert [row.split(" | ")[0].removeprefix("| ") for row in table.splitlines()] == [
        "record expert",
        "record expert-dart",
        "train expert_bc_30demos_50000steps_seed4",
        "train expert-dart_bcq_30demos_50000steps",
        "evaluate",
        "evaluate (seeds 2-3)",
    ]
    assert "veragmil-study --output-dir x" in run_md and "mujoco 3.8.1" in run_md
    # the pieces' times stay beside results.json, where a pool of this folder finds them
    assert list(json.loads((dest / "timings.json").read_text())) == [
        row.split(" | ")[0].removeprefix("| ") for row in table.splitlines()
    ]
    # an evaluation that recorded no host: this machine's, said to be the publisher's
    assert "(this machine, which published the folder: its evaluation recorded none)" in run_md


def test_run_md_names_the_machine_that_scored_the_episodes_not_the_publisher(tmp_path):
    study = _study(tmp_path, {"expert operator": "expert:expert"}, {})
    results = json.loads((study / "eval" / "results.json").read_text())
    results["config"]["host"] = {"cpu": "Scoring CPU", "cores": 2}
    (study / "eval" / "results.json").write_text(json.dumps(results))
    publish(study, tmp_path / "dest", "cmd")
    run_md = (tmp_path / "dest" / "RUN.md").read_text()
    assert "Host: cpu Scoring CPU, cores 2\n" in run_md and "which published" not in run_md
    assert not (tmp_path / "dest" / "timings.json").exists()  # no piece timed: nothing to keep


def test_an_unfinished_study_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="results.json not found"):
        publish(tmp_path / "nothing", tmp_path / "dest", "cmd")
    assert main([str(tmp_path / "nothing"), "--output-dir", str(tmp_path / "dest"), "--command", "cmd"]) == 2
    assert not (tmp_path / "dest").exists()
