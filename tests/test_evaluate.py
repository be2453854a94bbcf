"""
veragmil-evaluate: the tables' numbers against a hand-computed case, a recorded dataset scored by its own stored
metrics, the expert and a tiny trained checkpoint rolled out in parallel workers, every output file, the fixed
formats of episodes.csv and the journal, and clear errors (exit 2) for a bad food or agent.
"""

import csv
import inspect
import json
import math
import re
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import pytest
from helpers.programs import run_program
from helpers.recording import record_file, tiny_env_kwargs

from veragmil_suite.environments.scoop import ScoopGranular
from veragmil_suite.evaluation.agents import (
    AgentSpec,
    EpisodeRecord,
    EpisodeTask,
    EvaluationError,
    parse_agent_argument,
    parse_spec,
)
from veragmil_suite.evaluation.evaluate import JOURNAL_NAME, Journal, _recorded_settings, evaluate
from veragmil_suite.evaluation.reporting import EvaluationResult
from veragmil_suite.models.foods import DEFAULT_PHYSICS

# a cheap scene: a dozen pasta pieces, one settled pile
CHEAP = {"n_grains": 12, "pile_variants": 1}
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# episodes.csv as published results and scripts read it: EpisodeRecord's fields, in order
EPISODES_CSV_HEADER = (
    "agent,food,episode,seed,success,grains_spilled,spilled_volume_cm3,completion_time_s,steps,end_reason,"
    "physics_error,grains_in_spoon,spill_fraction,stage,peak_grains_in_spoon,wall_s,spilled_mass_g,spoon_mass_g,"
    "physics,spill_limit_of,pile"
)
EPISODES_CSV_ROW = "A,rice,0,0,True,2,0.2,10.0,200,success,,3,0.0,held,3,1.0,nan,nan,table1,scooped,"
# one line of episodes.jsonl, the journal a resumed run reads back
JOURNAL_LINE = (
    '{"key": "[\\"expert\\", \\"expert\\", \\"pasta\\", 0, 80, {\\"n_grains\\": 12, \\"pile_variants\\": 1}]", '
    '"record": {"agent": "expert", "food": "pasta", "episode": 0, "seed": 0, "success": false, "grains_spilled": 0, '
    '"spilled_volume_cm3": 0.0, "completion_time_s": 4.0, "steps": 80, "end_reason": "horizon", "physics_error": "", '
    '"grains_in_spoon": 12, "spill_fraction": 0.0, "stage": "loaded spoon", "peak_grains_in_spoon": 12, '
    '"wall_s": 1.3754890439995506}}'
)
# the same episode as written since grams, the physics, the spill limit and the pile are recorded (grams unknown in a
# journal of before: null; its physics the one every episode ran on before the choice, table1; its spill limit that
# of its env kwargs, there the default; its pile unknown: "")
JOURNAL_LINE_NOW = (
    JOURNAL_LINE[:-2]
    + ', "spilled_mass_g": null, "spoon_mass_g": null, "physics": "table1", "spill_limit_of": "scooped", "pile": ""}}'
)


def _episode(agent, food, success, spilled, time_s, episode=0):
    return EpisodeRecord(
        agent=agent,
        food=food,
        episode=episode,
        seed=episode,
        success=success,
        grains_spilled=spilled,
        spilled_volume_cm3=0.1 * spilled,
        completion_time_s=time_s,
        steps=int(time_s * 20),
        end_reason="success" if success else "horizon",
        physics_error="",
        grains_in_spoon=3,
        spill_fraction=0.0,
        stage="held" if success else "reached pile",
        peak_grains_in_spoon=3,
        wall_s=1.0,
    )


# A: rice 2 of 3 (spilled 2, 4, 6: mean 4, population std sqrt(8/3); time of the successes 10 and 14: 12; the
# failure's 30 s left out), pasta 0 of 1 (no time: "-"), peas 2 of 2 (spilled 0, 2; times 8, 12). B: rice only.
HAND_CASE = [
    _episode("A", "rice", True, 2, 10.0, 0),
    _episode("A", "rice", True, 4, 14.0, 1),
    _episode("A", "rice", False, 6, 30.0, 2),
    _episode("A", "pasta", False, 1, 20.0, 0),
    _episode("A", "peas", True, 0, 8.0, 0),
    _episode("A", "peas", True, 2, 12.0, 1),
    _episode("B", "rice", True, 3, 9.0, 0),
]


def test_a_chart_of_one_food_is_drawn_without_a_warning(tmp_path):
    """One food makes (2, 1) error bars, which matplotlib handled through a conversion NumPy deprecates."""
    result = EvaluationResult([r for r in HAND_CASE if r.food == "rice"], ["A", "B"], ["rice"], dict(seed=0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result.write(tmp_path)
    assert (tmp_path / "success.png").read_bytes()[:8] == PNG_MAGIC


def test_summary_and_tables_match_a_hand_computed_case(tmp_path):
    result = EvaluationResult(HAND_CASE, ["A", "B"], ["rice", "pasta", "peas"], dict(seed=0))
    rice = result.summary[("A", "rice")]
    assert rice["episodes"] == 3 and rice["successes"] == 2
    assert rice["success_rate"] == pytest.approx(2 / 3)
    assert rice["grains_spilled_mean"] == pytest.approx(4.0)
    assert rice["grains_spilled_std"] == pytest.approx(math.sqrt(8 / 3))
    assert rice["completion_time_s_mean"] == pytest.approx(12.0)
    assert math.isnan(result.summary[("A", "pasta")]["completion_time_s_mean"])
    assert ("B", "pasta") not in result.summary

    lines = result.markdown().splitlines()
    # Table II: success %, group averages weigh each food the same, a food without an entry is left out
    for line in (
        "| **seen (training)** | | |",
        "| rice | 67 (21-94) | 100 (21-100) |",
        "| pasta | 0 (0-79) | - |",
        "| *seen (training) average* | 33 (15-85) | 100 (21-100) |",  # interval of the group total, 2 in 4
        "| **unseen** | | |",
        "| peas | 100 (34-100) | - |",
        "| *unseen average* | 100 (34-100) | - |",
        "| *overall average* | 56 (30-90) | 100 (21-100) |",  # rates averaged per food; 4 successes in 6
    ):
        assert line in lines, line
    # Table III: spilled pieces mean +- std, grams spilled and carried ("-": not recorded), time over successes
    for line in (
        "| rice | 4.0 ± 1.6 | - | - | 12.0 | 3.0 ± 0.0 | - | - | 9.0 |",
        "| pasta | 1.0 ± 0.0 | - | - | - | - | - | - | - |",
        "| *seen (training) average* | 2.5 | - | - | 12.0 | 3.0 | - | - | 9.0 |",
        "| peas | 1.0 ± 1.0 | - | - | 10.0 | - | - | - | - |",
        "| *overall average* | 2.0 | - | - | 11.0 | 3.0 | - | - | 9.0 |",  # spilled (4 + 1 + 1) / 3; time (12 + 10) / 2
    ):
        assert line in lines, line
    rice_line, peas_line = "| rice | 67 (21-94) | 100 (21-100) |", "| peas | 100 (34-100) | - |"
    assert lines.index(rice_line) < lines.index("| **unseen** | | |") < lines.index(peas_line)
    # where the episodes stopped: furthest stage per agent and food
    stages = result.stages_markdown().splitlines()
    assert "| A | rice | 3 | 0 | 1 | 0 | 0 | 0 | 2 |" in stages
    assert "| A | peas (unseen) | 2 | 0 | 0 | 0 | 0 | 0 | 2 |" in stages

    paths = result.write(str(tmp_path))
    expected = {"episodes.csv", "results.json", "table.md", "table.csv", "stages.md", "stages.csv", "success.png"}
    assert set(paths) == expected
    with open(paths["table.csv"]) as f:
        rows = {r["food"]: r for r in csv.DictReader(f)}
    assert float(rows["rice"]["A success %"]) == pytest.approx(66.67, abs=0.01)
    low, high = float(rows["rice"]["A success % ci95 low"]), float(rows["rice"]["A success % ci95 high"])
    assert (low, high) == pytest.approx((20.77, 93.85), abs=0.01)
    assert float(rows["seen (training) average"]["A success %"]) == pytest.approx(33.33, abs=0.01)
    assert float(rows["overall average"]["A success %"]) == pytest.approx(55.56, abs=0.01)
    assert rows["pasta"]["A time s mean"] == "NaN" and rows["pasta"]["B success %"] == "NaN"
    assert float(rows["peas"]["A spilled pieces std"]) == pytest.approx(1.0)
    assert rows["rice"]["group"] == "seen (training)" and rows["peas"]["group"] == "unseen"
    with open(paths["episodes.csv"]) as f:
        episodes = list(csv.DictReader(f))
    assert len(episodes) == len(HAND_CASE) and episodes[2]["completion_time_s"] == "30.0"
    assert Path(paths["episodes.csv"]).read_text().splitlines()[:2] == [EPISODES_CSV_HEADER, EPISODES_CSV_ROW]
    saved = json.loads(Path(paths["results.json"]).read_text())
    assert list(saved["episodes"][0]) == EPISODES_CSV_HEADER.split(",")
    assert saved["config"]["physics"] == ["table1"]  # records that name none ran before the physics had a name
    assert lines[-2:] == [
        "Physics (grain models, veragmil_suite.models.foods): table1",
        "Spill limit of success (ScoopGranular's spill_limit_of): scooped",  # records that name none: the default
    ]
    config = {"seed": 0, "physics": ["table1"], "spill_limit_of": ["scooped"]}
    assert len(saved["episodes"]) == len(HAND_CASE) and saved["config"] == config
    assert episodes[2]["stage"] == "reached pile" and episodes[0]["stage"] == "held"
    with open(paths["stages.csv"]) as f:
        stage_rows = {(r["agent"], r["food"]): r for r in csv.DictReader(f)}
    assert stage_rows[("A", "rice")]["held"] == "2" and stage_rows[("A", "rice")]["reached pile"] == "1"
    pasta = next(s for s in saved["summary"] if (s["agent"], s["food"]) == ("A", "pasta"))
    assert pasta["completion_time_s_mean"] is None and pasta["success_rate"] == 0.0
    assert Path(paths["table.md"]).read_text() == result.markdown()
    assert Path(paths["success.png"]).read_bytes()[:8] == PNG_MAGIC


def test_a_journaled_episode_reads_back_and_is_journaled_the_same_way(tmp_path):
    """Resumed runs read the journals earlier runs wrote: the line format is fixed."""
    path = tmp_path / JOURNAL_NAME
    path.write_text(JOURNAL_LINE + "\n")
    task = EpisodeTask("renamed", parse_spec("expert"), "pasta", 3, 0, 80, {"n_grains": 12, "pile_variants": 1})
    record = Journal(path, resume=True).get(task)
    assert record == EpisodeRecord(**{**json.loads(JOURNAL_LINE)["record"], "episode": 3})
    assert (record.steps, record.end_reason, record.stage, record.peak_grains_in_spoon) == (
        80,
        "horizon",
        "loaded spoon",
        12,
    )
    again = tmp_path / "again.jsonl"
    Journal(again, resume=False).add(task, replace(record, episode=0))
    assert again.read_text() == JOURNAL_LINE_NOW + "\n"
    # a run that does not resume starts a new journal, and keeps the earlier one aside
    fresh = Journal(path, resume=False)
    assert fresh.records == {} and not path.exists()
    aside, _ = fresh.set_aside
    assert aside.name == "episodes.replaced.jsonl" and aside.read_text() == JOURNAL_LINE + "\n"
    assert fresh.describe_set_aside() == (
        f"{path} held 1 episodes of an earlier run: kept as {aside}, not used "
        "(--resume takes them instead of running them again)"
    )
    path.write_text(JOURNAL_LINE + "\n")
    assert Journal(path, resume=False).set_aside[0].name == "episodes.replaced.1.jsonl" and aside.is_file()


def test_a_journal_killed_mid_line_resumes_its_whole_episodes_and_journals_the_next_on_a_line_of_its_own(tmp_path):
    path = tmp_path / JOURNAL_NAME
    path.write_text(JOURNAL_LINE + "\n" + JOURNAL_LINE_NOW[: len(JOURNAL_LINE_NOW) // 2])  # killed mid-line
    task = EpisodeTask("renamed", parse_spec("expert"), "pasta", 3, 0, 80, {"n_grains": 12, "pile_variants": 1})
    journal = Journal(path, resume=True)
    record = journal.get(task)
    assert record is not None and len(journal.records) == 1
    later = replace(task, seed=1)
    journal.add(later, replace(record, seed=1))
    lines = path.read_text().splitlines()
    assert lines[0] == JOURNAL_LINE and len(lines) == 2 and json.loads(lines[1])["key"] == Journal.key(later)
    again = Journal(path, resume=True)
    assert again.get(task) is not None and again.get(later) is not None


def test_an_episode_journaled_before_spill_limits_were_recorded_takes_its_env_kwargs_limit(tmp_path):
    """A journal of a run scored under spill_limit_of="bowl", written before records named their spill limit, reads
    back as scored under "bowl" (its key holds the env kwargs), so its tables say which rule made them."""
    path = tmp_path / JOURNAL_NAME
    bowl_kwargs = {"n_grains": 12, "pile_variants": 1, "spill_limit_of": "bowl"}
    path.write_text(
        JOURNAL_LINE.replace('\\"pile_variants\\": 1}', '\\"pile_variants\\": 1, \\"spill_limit_of\\": \\"bowl\\"}')
        + "\n"
    )
    task = EpisodeTask("bowl", parse_spec("expert"), "pasta", 0, 0, 80, bowl_kwargs)
    record = Journal(path, resume=True).get(task)
    assert record is not None and record.spill_limit_of == "bowl"
    result = EvaluationResult([record], ["bowl"], ["pasta"], {})
    assert result.markdown().splitlines()[-1] == "Spill limit of success (ScoopGranular's spill_limit_of): bowl"


def test_a_journal_of_another_platform_is_set_aside_not_resumed(tmp_path):
    """The same episodes can end otherwise on another CPU or torch: resuming there keeps the journal, unused."""
    path = tmp_path / JOURNAL_NAME
    path.write_text(JOURNAL_LINE + "\n")
    task = EpisodeTask("renamed", parse_spec("expert"), "pasta", 3, 0, 80, {"n_grains": 12, "pile_variants": 1})
    assert Journal(path, resume=True).get(task) is not None  # no platform beside it: written here
    here = json.loads((tmp_path / f"{JOURNAL_NAME}.platform.json").read_text())
    assert {"cpu", "python", "mujoco", "torch", "numpy"} <= set(here)
    elsewhere = dict(here, torch="2.11.0+cu130")
    (tmp_path / f"{JOURNAL_NAME}.platform.json").write_text(json.dumps(elsewhere))
    journal = Journal(path, resume=True)
    assert journal.get(task) is None and not path.exists()
    aside, written_on = journal.set_aside
    assert written_on == elsewhere and aside.read_text() == JOURNAL_LINE + "\n"
    assert json.loads(Path(f"{aside}.platform.json").read_text()) == elsewhere
    assert "torch 2.11.0+cu130 (here " in journal.describe_set_aside()
    assert json.loads((tmp_path / f"{JOURNAL_NAME}.platform.json").read_text()) == here
    # a second journal of that platform set aside keeps the first
    path.write_text(JOURNAL_LINE + "\n")
    (tmp_path / f"{JOURNAL_NAME}.platform.json").write_text(json.dumps(elsewhere))
    assert Journal(path, resume=True).set_aside[0] != aside and aside.is_file()


def test_an_episode_on_the_gpu_is_journaled_apart_from_the_cpus():
    task = EpisodeTask("a", parse_spec("expert"), "pasta", 0, 0, 80, {})
    assert Journal.key(task) != Journal.key(replace(task, policy_device="cuda"))
    assert Journal.key(task) == Journal.key(replace(task, agent="b"))


def test_a_checkpoint_named_relative_or_absolute_resumes_the_same_episodes(tmp_path, monkeypatch):
    """A journal written with a checkpoint's (or a video's) relative path is read back by a run that names them
    absolutely, and the other way round; another file is another agent."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / JOURNAL_NAME
    record = EpisodeRecord(**{**json.loads(JOURNAL_LINE_NOW)["record"], "agent": "a"})
    relative = EpisodeTask("a", AgentSpec("checkpoint", "runs/model_epoch_5.pth"), "pasta", 0, 0, 80, CHEAP)
    absolute = replace(relative, spec=AgentSpec("checkpoint", str(tmp_path / "runs/model_epoch_5.pth")))
    # the key as runs before this spelling wrote it: the path as given
    old_key = json.dumps(["checkpoint", "runs/model_epoch_5.pth", "pasta", 0, 80, CHEAP], sort_keys=True)
    path.write_text(json.dumps({"key": old_key, "record": record.to_dict()}) + "\n")
    assert Journal(path, resume=True).get(absolute) is not None
    Journal(path, resume=False)  # sets that journal aside
    Journal(path, resume=True).add(absolute, record)
    assert Journal(path, resume=True).get(relative) is not None
    other = replace(relative, spec=AgentSpec("checkpoint", "runs/model_epoch_6.pth"))
    assert Journal(path, resume=True).get(other) is None
    video = tmp_path / "videos" / "a.mp4"
    video.parent.mkdir()
    video.write_bytes(b"")
    Journal(path, resume=True).add(replace(relative, video_path="videos/a.mp4"), record)
    assert Journal(path, resume=True).get(replace(absolute, video_path=str(video))) is not None


def test_agent_arguments_name_and_check_specs(tmp_path):
    checkpoint = tmp_path / "model_epoch_5.pth"
    checkpoint.write_bytes(b"")
    assert parse_agent_argument(str(checkpoint)) == ("model_epoch_5", str(checkpoint))
    assert parse_agent_argument(f"BC={checkpoint}") == ("BC", str(checkpoint))
    assert parse_agent_argument("expert") == ("expert", "expert")
    assert parse_agent_argument("3DM=expert:spacemouse") == ("3DM", "expert:spacemouse")
    with pytest.raises(ValueError, match="accepted profiles: expert, careful"):
        parse_agent_argument("expert:robot")
    with pytest.raises(ValueError, match=r"\*\.pth"):
        parse_agent_argument("policy.pkl")


def test_dataset_agent_reports_the_demos_stored_metrics(tmp_path):
    path = tmp_path / "human.hdf5"
    recorded = record_file(path, episodes=2, steps=12, env_kwargs=tiny_env_kwargs(cameras=()), operator="alice")
    result = evaluate({"human": f"dataset:{path}"}, foods=["pasta", "rice"], episodes=5, progress=False)
    assert [(e.agent, e.food, e.episode) for e in result.episodes] == [
        ("human", "pasta", 0),
        ("human", "pasta", 1),
    ]
    for episode, demo in zip(result.episodes, recorded):
        for key in ("success", "grains_spilled", "spilled_volume_cm3", "completion_time_s", "grains_in_spoon"):
            assert getattr(episode, key) == demo.metrics[key], key
        assert episode.steps == demo.num_samples == 12
    assert set(result.summary) == {("human", "pasta")}  # no rice in the file: no entry, "-" in the tables
    assert "| rice | - |" in result.markdown()


def test_cli_expert_and_dataset_in_two_processes_write_every_output(tmp_path):
    dataset = tmp_path / "demos.hdf5"
    record_file(dataset, episodes=1, steps=12, env_kwargs=tiny_env_kwargs(cameras=()))
    out = tmp_path / "eval"
    args = ["--agent", "expert", "--agent", f"human=dataset:{dataset}", "--foods", "pasta", "--episodes", 2]
    args += ["--processes", 2, "--output-dir", out, "--horizon", 300, "--env-kwargs", json.dumps(CHEAP)]
    result = run_program("veragmil-evaluate", *args, "--videos", 1, "--quiet", check=False, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    for name in ("episodes.csv", "results.json", "table.md", "table.csv", "success.png", "videos/expert_pasta_0.mp4"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "videos" / "expert_pasta_1.mp4").exists()
    assert (out / "success.png").read_bytes()[:8] == PNG_MAGIC
    saved = json.loads((out / "results.json").read_text())
    expert = [e for e in saved["episodes"] if e["agent"] == "expert"]
    assert [e["seed"] for e in expert] == [0, 1]  # episode i: seed + i
    for e in expert:
        assert e["end_reason"] in ("success", "horizon", "gave up") and 0 < e["steps"] <= 300
        assert e["success"] or e["end_reason"] != "success"  # success: the last step's, as demos store it
        assert re.fullmatch("[0-9a-f]{24}", e["pile"])  # the settled pile it ran on, which pooling compares
    assert {e["pile"] for e in saved["episodes"] if e["agent"] == "human"} == {""}  # a demo's pile is not known
    assert saved["config"]["foods"] == ["pasta"] and saved["config"]["env_kwargs"] == {
        **CHEAP,
        "physics": DEFAULT_PHYSICS,
    }
    assert saved["config"]["horizon"] == 300
    assert "robosuite" in saved["config"]["versions"]
    assert "Table II" in result.stdout and "| pasta |" in result.stdout and "human" in result.stdout
    assert "episodes:" not in result.stderr  # --quiet: no progress bar
    # --resume takes the journaled episodes (a video's episode too, its file being there) and writes the same tables
    again = run_program("veragmil-evaluate", *args, "--videos", 1, "--quiet", "--resume", check=False, timeout=300)
    assert again.returncode == 0, again.stdout[-3000:] + again.stderr[-3000:]
    assert "skipping 2 evaluation episodes journaled" in again.stdout and "; 0 to run" in again.stdout
    resumed = json.loads((out / "results.json").read_text())
    assert [e for e in resumed["episodes"] if e["agent"] == "expert"] == expert


def test_bad_food_or_agent_exits_2_naming_the_accepted_values_and_writes_nothing(tmp_path, capsys):
    from veragmil_suite.scripts.evaluate import main

    out = tmp_path / "eval"

    def refused(*args) -> str:
        assert main([*map(str, args), "--output-dir", str(out)]) == 2
        return capsys.readouterr().err

    assert "accepted: rice, buckwheat" in refused("--agent", "expert", "--foods", "rice", "lentils")
    said = refused("--agent", "robot.pkl", "--foods", "rice")
    assert "'expert:<profile>'" in said and "*.pth" in said
    assert "accepted profiles" in refused("--agent", "X=expert:sloppy")
    assert "not found" in refused("--agent", f"dataset:{tmp_path / 'none.hdf5'}")
    (tmp_path / "notes.hdf5").write_text("not HDF5")
    assert "notes.hdf5" in refused("--agent", f"dataset:{tmp_path / 'notes.hdf5'}")
    assert not out.exists()


def test_a_policy_device_the_machine_lacks_exits_2_naming_the_accepted_values(tmp_path, capsys):
    import torch

    from veragmil_suite.scripts.evaluate import main

    out = tmp_path / "eval"
    assert main(["--agent", "expert", "--policy-device", "tpu", "--output-dir", str(out)]) == 2
    assert "cpu" in capsys.readouterr().err
    if not torch.cuda.is_available():
        assert main(["--agent", "expert", "--policy-device", "cuda", "--output-dir", str(out)]) == 2
        assert "no CUDA device here (accepted: cpu, cuda)" in capsys.readouterr().err
    assert not out.exists()


def test_a_failing_episode_fails_the_run_with_the_workers_traceback():
    with pytest.raises(EvaluationError, match=r"(?s)expert on pasta, episode 0.*Traceback.*no_such_argument"):
        evaluate({"expert": "expert"}, ["pasta"], 1, processes=1, env_kwargs={"no_such_argument": 1}, progress=False)


def test_checkpoint_agent_rolls_out_on_the_evaluated_food(tmp_path):
    """A tiny BC checkpoint trained on pasta, evaluated on peas with the expert, the same seeds."""
    from helpers.tiny_dataset import record_tiny_dataset

    from veragmil_suite.study.training import train_checkpoint, training_config

    dataset = record_tiny_dataset(str(tmp_path / "tiny.hdf5"), episodes=2, steps=20, valid_episodes=1)
    config = training_config("bc", Path(dataset), tmp_path / "runs", "tiny_bc", epochs=1, steps_per_epoch=3)
    config["train"]["batch_size"] = 16
    checkpoints, _ = train_checkpoint(config, tmp_path)
    checkpoint = checkpoints[1]  # the last epoch's
    horizon = 15
    result = evaluate(
        {"BC": str(checkpoint), "expert": "expert"},
        foods=["peas"],
        episodes=1,
        processes=2,
        seed=7,
        horizon=horizon,
        env_kwargs=CHEAP,
        progress=False,
    )
    bc = next(e for e in result.episodes if e.agent == "BC")
    assert bc.food == "peas" and bc.seed == 7
    assert bc.steps == horizon and bc.end_reason == "horizon" and not bc.success
    assert {e.seed for e in result.episodes} == {7}
    assert "| peas | 0 (0-79) |" in result.markdown()  # one episode: a wide interval
    assert bc.stage == "start"  # 15 steps from the pre-scoop pose do not reach the pile
    # what the episodes ran with, though none was asked for: the tiny dataset names no physics, so its checkpoint
    # runs on Table I's (checkpoint_base_kwargs), the expert on the default
    assert result.config["horizon"] == horizon
    assert result.config["env_kwargs"] == {**CHEAP, "physics": {"BC": "table1", "expert": DEFAULT_PHYSICS}}


def test_an_evaluation_records_the_horizon_and_physics_its_episodes_ran_with():
    """Defaults resolved: an evaluation asked for nothing records what one that asked for the same values records
    (they did not, and pool_results refused to pool a study's episodes with veragmil-evaluate's alike ones)."""
    defaults = inspect.signature(ScoopGranular.__init__).parameters
    horizon, physics = defaults["horizon"].default, defaults["physics"].default
    expert = {"expert": parse_spec("expert")}
    assert _recorded_settings(expert, {}, None, {}) == (horizon, {"physics": physics})
    assert _recorded_settings(expert, {}, horizon, {"physics": physics}) == (horizon, {"physics": physics})
    # a checkpoint runs on its training env's horizon and physics (none named: Table I's); agents that differ are
    # recorded per agent
    specs = {**expert, "old": AgentSpec("checkpoint", "old.pth")}
    metas = {"old": {"env_kwargs": {"food": "rice", "horizon": 300, "n_grains": 50}}}
    assert _recorded_settings(specs, metas, None, {"n_grains": 12}) == (
        {"expert": horizon, "old": 300},
        {"n_grains": 12, "physics": {"expert": physics, "old": "table1"}},
    )
    assert _recorded_settings(specs, metas, 200, {"physics": "table1"}) == (200, {"physics": "table1"})
    # a dataset agent runs no episode
    assert _recorded_settings({"human": AgentSpec("dataset", "x.hdf5")}, {}, None, {}) == (None, {})


def test_a_checkpoint_of_several_foods_is_evaluated_on_each_food_asked(tmp_path):
    """A multi-food dataset's env_kwargs variants (robomimic's rollouts take its foods in turn) must not replace the
    evaluated food: they did, and every food of a study was scored on the dataset's first food."""
    from helpers.tiny_dataset import record_tiny_dataset

    from veragmil_suite.data.datasets import merge_datasets
    from veragmil_suite.study.training import train_checkpoint, training_config

    parts = [
        record_tiny_dataset(str(tmp_path / f"{food}.hdf5"), env_kwargs={**CHEAP, "food": food}, episodes=1, steps=8)
        for food in ("pasta", "peas")
    ]
    merge_datasets(parts, tmp_path / "two_foods.hdf5")
    config = training_config(
        "bc", tmp_path / "two_foods.hdf5", tmp_path / "runs", "tiny_bc", epochs=1, steps_per_epoch=2
    )
    config["train"]["batch_size"] = 4
    checkpoints, _ = train_checkpoint(config, tmp_path)
    result = evaluate(
        {"BC": str(checkpoints[1])}, foods=["beans", "peas"], episodes=1, processes=1, seed=3, horizon=2,
        env_kwargs=CHEAP, progress=False,
    )  # fmt: skip
    assert sorted(e.food for e in result.episodes) == ["beans", "peas"]  # run_episode refuses an env of another food


def test_a_checkpoint_that_names_no_physics_runs_on_the_physics_it_was_trained_on():
    """Checkpoints trained before the physics had a name ran on Table I's grains, whatever the default is now."""
    from veragmil_suite.evaluation.agents import checkpoint_base_kwargs

    old = {"env_kwargs": {"food": "rice", "n_grains": 12, "control_freq": 20}}
    assert checkpoint_base_kwargs(old) == {"control_freq": 20, "physics": "table1"}
    assert checkpoint_base_kwargs({"env_kwargs": {"food": "rice", "physics": "calibrated"}}) == {
        "physics": "calibrated"
    }


def test_reading_a_checkpoints_metadata_or_checking_a_checkpoint_argument_imports_no_robomimic():
    """A driver reads each checkpoint's env metadata, and every program checks its checkpoint arguments, before any
    policy runs: robomimic's import (torchvision's with it) cost seconds each time, for a dict torch.load returns."""
    code = (
        "import sys\n"
        "from veragmil_suite.evaluation.agents import env_metadata\n"
        "from veragmil_suite.scripts.quickstart import PRETRAINED, pretrained_checkpoint\n"
        "from veragmil_suite.utils.cli.files import checkpoint\n"
        "path = checkpoint(str(pretrained_checkpoint(PRETRAINED)))\n"
        "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'robomimic', 'torchvision'})\n"
        "print(env_metadata(path)['env_name'], heavy)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "ScoopGranular []", result.stdout + result.stderr[-2000:]


def test_an_rnn_horizon_sets_when_a_bc_rnn_checkpoint_resets_its_hidden_state(tmp_path):
    """--rnn-horizon N: a BC-RNN rolls out with its LSTM's state reset every N steps instead of its config's
    algo.rnn.horizon; the other agents run as they are, and the journal tells the two apart."""
    import numpy as np
    import torch
    from helpers.tiny_dataset import record_tiny_dataset

    from veragmil_suite.learning import robomimic_compat
    from veragmil_suite.learning.checkpoints import read_checkpoint, rnn_horizon_of, with_rnn_horizon
    from veragmil_suite.study.training import train_checkpoint, training_config

    dataset = record_tiny_dataset(str(tmp_path / "tiny.hdf5"), episodes=2, steps=12, valid_episodes=1)
    config = training_config("bc_rnn", Path(dataset), tmp_path / "runs", "tiny_rnn", epochs=1, steps_per_epoch=3)
    config["train"]["batch_size"] = 4
    checkpoint = str(train_checkpoint(config, tmp_path)[0][1])
    ckpt = read_checkpoint(checkpoint)
    assert rnn_horizon_of(ckpt) == config["algo"]["rnn"]["horizon"] == 10

    robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils

    def actions(ckpt_dict: dict, steps: int) -> list:
        """The policy's actions on one observation shown ``steps`` times."""
        policy, _ = FileUtils.policy_from_checkpoint(ckpt_dict=ckpt_dict, device=torch.device("cpu"))
        policy.start_episode()
        shapes = ckpt_dict["shape_metadata"]["all_shapes"]
        obs = {k: np.full(shape, 0.1, dtype=np.float32) for k, shape in shapes.items()}
        return [policy(ob=obs) for _ in range(steps)]

    every_3 = actions(with_rnn_horizon(ckpt, 3), 4)
    assert np.array_equal(every_3[3], every_3[0])  # a fresh hidden state on the same observation
    stock = actions(ckpt, 4)
    assert np.array_equal(stock[0], every_3[0]) and not np.array_equal(stock[3], stock[0])
    with pytest.raises(ValueError, match="without an RNN"):
        with_rnn_horizon({**ckpt, "config": json.dumps({"algo": {"rnn": {"enabled": False}}})}, 3)

    out = tmp_path / "eval"
    agents = {"RNN": checkpoint, "expert": "expert"}
    result = evaluate(
        agents, ["pasta"], 1, processes=1, horizon=4, env_kwargs=CHEAP, output_dir=str(out), progress=False,
        rnn_horizon=2,
    )  # fmt: skip
    assert result.config["rnn_horizon"] == {"RNN": 2}  # the expert has no RNN
    keys = [json.loads(json.loads(line)["key"]) for line in (out / JOURNAL_NAME).read_text().splitlines()]
    assert sorted(str(k[-1]) for k in keys) == sorted([str({"rnn_horizon": 2}), str(CHEAP)])
    # resumed with the checkpoint's own horizon, the RNN's episode runs again, the expert's is taken
    said = []
    again = evaluate(
        agents, ["pasta"], 1, processes=1, horizon=4, env_kwargs=CHEAP, output_dir=str(out), progress=False,
        resume=True, say=said.append,
    )  # fmt: skip
    assert "rnn_horizon" not in again.config and any("skipping 1 evaluation episodes" in s for s in said)
    with pytest.raises(ValueError, match="no agent is one"):
        evaluate({"expert": "expert"}, ["pasta"], 1, processes=1, horizon=4, env_kwargs=CHEAP, rnn_horizon=2)


def test_an_rnn_horizon_that_is_no_count_or_has_no_recurrent_agent_exits_2(tmp_path, capsys):
    from veragmil_suite.scripts.evaluate import main

    out = tmp_path / "eval"
    assert main(["--agent", "expert", "--rnn-horizon", "0", "--output-dir", str(out)]) == 2
    assert "--rnn-horizon" in capsys.readouterr().err
    assert main(["--agent", "expert", "--rnn-horizon", "20", "--output-dir", str(out), "--foods", "pasta"]) == 2
    assert "recurrent checkpoints (BC-RNN" in capsys.readouterr().err
    assert not out.exists()


def test_a_journaled_episode_on_a_pile_no_longer_drawn_runs_again(tmp_path):
    out = tmp_path / "eval"
    run = dict(foods=["pasta"], episodes=2, processes=1, horizon=4, env_kwargs=CHEAP, output_dir=str(out))
    timed = []  # on_episode: once per episode scored, with the episodes journaled before the run
    first = evaluate({"expert": "expert"}, **run, progress=False, on_episode=timed.append)
    assert timed == [0, 0]
    piles = [e.pile for e in first.episodes]
    assert all(re.fullmatch("[0-9a-f]{24}", p) for p in piles)
    # as if the lattice had changed since episode 0 ran: its record names a pile this code does not build
    journal = out / JOURNAL_NAME
    lines = journal.read_text().splitlines()
    entry = json.loads(lines[0])
    assert entry["record"]["seed"] == 0
    entry["record"]["pile"] = "0" * 24
    journal.write_text("\n".join([json.dumps(entry), *lines[1:]]) + "\n")
    said = []
    again = evaluate({"expert": "expert"}, **run, progress=False, resume=True, say=said.append, on_episode=timed.append)
    assert timed == [0, 0, 2]
    assert any("1 episodes journaled" in s and "no longer draws" in s for s in said)
    assert any("skipping 1 evaluation episodes" in s and "; 1 to run" in s for s in said)
    assert [e.pile for e in again.episodes] == piles
    # the episode run again is journaled after the stale one and is what a later resume takes
    said.clear()
    evaluate({"expert": "expert"}, **run, progress=False, resume=True, say=said.append)
    assert not any("no longer draws" in s for s in said) and any("; 0 to run" in s for s in said)
    # a record that names no pile (journaled before piles were named) is taken as it is
    entry["record"]["pile"] = ""
    journal.write_text(json.dumps(entry) + "\n")
    said.clear()
    evaluate({"expert": "expert"}, **run, progress=False, resume=True, say=said.append)
    assert not any("no longer draws" in s for s in said) and any("skipping 1 evaluation" in s for s in said)


def test_a_checkpoints_metadata_is_read_with_its_weights_mapped_not_read(tmp_path):
    """The readers of a checkpoint's metadata (the argument check, env_metadata, the rnn horizon) map its tensors
    from the file; a policy's reader reads them; a file of torch's legacy format is read whole by both."""
    import torch

    from veragmil_suite.learning.checkpoints import read_checkpoint

    ckpt = {"algo_name": "bc", "config": "{}", "env_metadata": {"env_name": "ScoopGranular"}, "shape_metadata": {}}
    ckpt["model"] = {"policy.weight": torch.arange(1000.0)}
    zipped, legacy = tmp_path / "zipped.pth", tmp_path / "legacy.pth"
    torch.save(ckpt, zipped)
    torch.save(ckpt, legacy, _use_new_zipfile_serialization=False)
    for path, weights, mapped in [
        (zipped, True, False),
        (legacy, True, False),
        (legacy, False, False),
        (zipped, False, True),
    ]:
        read = read_checkpoint(str(path), weights=weights)
        assert read["env_metadata"] == ckpt["env_metadata"]
        assert torch.equal(read["model"]["policy.weight"], ckpt["model"]["policy.weight"])
        assert (str(path) in Path("/proc/self/maps").read_text()) == mapped, (path.name, weights)
        del read
