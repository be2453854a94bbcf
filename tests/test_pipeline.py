"""veragmil-quickstart and veragmil-study: settings, the shortened configs, and the main job end to end (tiny)."""

import contextlib
import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import psutil
import pytest
from helpers.output import warning_lines
from helpers.programs import BIN, run_program

from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.study.record import record_food
from veragmil_suite.study.settings import PipelineSettings, StageError
from veragmil_suite.study.training import training_config
from veragmil_suite.utils.asset_paths import config_path


@pytest.mark.parametrize("algo", ["bc", "bc_rnn", "bcq", "diffusion_policy"])
def test_training_config_shortens_our_config_and_changes_nothing_else(algo, tmp_path):
    with open(config_path(algo)) as f:
        stock = json.load(f)
    config = training_config(
        algo, tmp_path / "d.hdf5", tmp_path / "runs", "x", epochs=7, steps_per_epoch=11, filter_key="first3",
        save_epochs=[2, 7],
    )  # fmt: skip
    assert config["train"]["num_epochs"] == 7 and config["experiment"]["epoch_every_n_steps"] == 11
    assert config["train"]["data"] == str(tmp_path / "d.hdf5") and config["train"]["hdf5_filter_key"] == "first3"
    assert config["experiment"]["save"]["epochs"] == [2]
    assert config["experiment"]["rollout"]["enabled"] is False
    assert config["experiment"]["save"]["every_n_epochs"] == 7  # the last epoch is the checkpoint evaluated
    assert config["algo"] == stock["algo"] and config["observation"] == stock["observation"]
    assert config["train"]["seq_length"] == stock["train"]["seq_length"]


def test_bad_settings_name_the_accepted_values(tmp_path):
    with pytest.raises(ValueError, match="accepted foods"):
        PipelineSettings(output_dir=str(tmp_path), eval_foods=["rice", "lentils"])
    with pytest.raises(ValueError, match=re.escape(f"accepted: {sorted(ALGORITHMS)}")):
        PipelineSettings(output_dir=str(tmp_path), algos=["diffusion"])
    with pytest.raises(ValueError, match="episodes must be a positive integer"):
        PipelineSettings(output_dir=str(tmp_path), episodes=0)
    with pytest.raises(
        ValueError, match=r"eval_steps \[150\] .* multiples of steps_per_epoch \(100\) up to .* \(2000\)"
    ):
        PipelineSettings(output_dir=str(tmp_path), eval_steps=[150, 200])
    with pytest.raises(ValueError, match="demos_per_food must be positive"):
        PipelineSettings(output_dir=str(tmp_path), demos_per_food=[0, 3])
    with pytest.raises(ValueError, match="checkpoint 'nowhere.pth' not found"):
        PipelineSettings(output_dir=str(tmp_path), agents={"old": "nowhere.pth"})
    with pytest.raises(ValueError, match="agent name 'expert BC no-load-size obs' is taken by one of this run's own"):
        PipelineSettings(output_dir=str(tmp_path), agents={"expert BC no-load-size obs": "expert:careful"})
    assert PipelineSettings(output_dir=str(tmp_path), agents={"careful": "expert:careful"}).agents
    result = run_program("veragmil-study", "--output-dir", tmp_path / "s", "--algos", "gail", timeout=60, check=False)
    assert result.returncode == 2 and "argument --algos: unknown algorithm 'gail'; accepted: bc, " in result.stderr
    result = run_program(
        "veragmil-quickstart", "--output-dir", tmp_path / "q", "--episodes", "0", timeout=60, check=False
    )
    assert result.returncode == 2 and "argument --episodes: must be a positive integer, got 0" in result.stderr
    assert not (tmp_path / "q").exists() and not (tmp_path / "s").exists()


def test_no_operators_leaves_the_scripted_operators_out_of_the_study():
    from veragmil_suite.scripts.study import add_pipeline_arguments, settings_from_args
    from veragmil_suite.utils.cli.parser import Parser

    parser = Parser("veragmil-study")
    add_pipeline_arguments(parser, PipelineSettings(output_dir="runs/study"))
    argv = ["--output-dir", "runs/x", "--profiles", "expert", "expert-dart", "--algos", "bc"]
    assert settings_from_args(parser.parse_args(argv)).own_agents() == [
        "expert operator", "expert-dart operator", "expert BC no-load-size obs", "expert-dart BC no-load-size obs"
    ]  # fmt: skip
    without = settings_from_args(parser.parse_args([*argv, "--no-operators"]))
    assert without.own_agents() == ["expert BC no-load-size obs", "expert-dart BC no-load-size obs"]


def test_every_setting_is_an_option_of_the_study_built_from_the_settings_alone():
    """A new PipelineSettings field with its Option is a study option with no other file touched; what the
    options do not give is the parser's defaults object."""
    from dataclasses import fields

    from veragmil_suite.scripts.study import build_parser, settings_from_args

    parser = build_parser()
    dests = {action.dest for action in parser._actions}
    assert {f.name for f in fields(PipelineSettings)} <= dests
    settings = settings_from_args(parser.parse_args(["--output-dir", "runs/x"]))
    defaults = parser.get_default("pipeline_defaults")
    for f in fields(PipelineSettings):
        if f.name != "output_dir":
            assert getattr(settings, f.name) == getattr(defaults, f.name), f.name
    given = settings_from_args(parser.parse_args([
        "--output-dir", "runs/x", "--robot", "XArm7", "--algos", "bc", "bc_rnn", "--algo-epochs", "bc_rnn=40",
        "--algo-epochs", "bc=3",
        "--agent", "careful=expert:careful", "--n-grains", "50", "--train-seeds", "1", "3", "--ray",
    ]))  # fmt: skip
    assert given.algo_epochs == {"bc_rnn": 40, "bc": 3} and given.agents == {"careful": "expert:careful"}
    assert (given.n_grains, given.train_seeds, given.output_dir) == (50, [1, 3], "runs/x")
    assert given.ray is not None
    dated = settings_from_args(parser.parse_args([])).output_dir
    assert dated.startswith(os.path.join("runs", "study", "")) and dated[-15:-7].isdigit()


def test_training_seeds_name_their_runs_and_columns_and_the_default_seed_keeps_its_old_name(tmp_path):
    grid = dict(output_dir=str(tmp_path), algos=["bc", "bcq"], seed=0)
    one = PipelineSettings(**grid)
    assert (
        one.train_seeds == [1] and one.run_name("expert", "bc", 30, 1) == "expert_bc_30demos_2000steps_obs-no-load-size"
    )
    assert one.own_agents() == ["expert operator", "expert BC no-load-size obs", "expert BCQ no-load-size obs"]
    three = PipelineSettings(**grid, train_seeds=[1, 2, 3, 2], score_demonstrators=False)
    assert three.train_seeds == [1, 2, 3]
    assert three.run_name("expert", "bcq", 30, 3) == "expert_bcq_30demos_2000steps_obs-no-load-size_seed3"
    assert three.own_agents() == [f"expert {a} no-load-size obs seed {s}" for a in ("BC", "BCQ") for s in (1, 2, 3)]
    assert three.model_label("expert", "bc", 30, 2000) == "expert BC no-load-size obs"  # the recipe, all its seeds
    with pytest.raises(ValueError, match=r"train_seeds must be integers >= 0 .* got \[-1\]"):
        PipelineSettings(**grid, train_seeds=[-1])


def test_observation_sets_name_their_runs_and_columns_and_the_object_set_keeps_its_old_run_name(tmp_path):
    from veragmil_suite.learning.observation_sets import OBSERVATION_SETS

    grid = dict(output_dir=str(tmp_path), algos=["bc", "diffusion_policy"], seed=0, score_demonstrators=False)
    both = PipelineSettings(**grid, obs_sets=["object", "no-load", "object"])
    assert both.obs_sets == ["object", "no-load"]
    assert both.own_agents() == [
        "expert BC object obs", "expert BC no-load obs",
        "expert Diffusion Policy object obs", "expert Diffusion Policy no-load obs",
    ]  # fmt: skip
    assert both.run_name("expert", "bc", 30, 1, "object") == "expert_bc_30demos_2000steps"
    assert both.run_name("expert", "bc", 30, 2, "no-load") == "expert_bc_30demos_2000steps_obs-no-load_seed2"
    default = PipelineSettings(**grid)  # the configs' own set: no grain counts
    assert default.obs_sets == ["no-load-size"] and default.own_agents()[0] == "expert BC no-load-size obs"
    assert default.run_name("expert", "bc", 30, 1) == "expert_bc_30demos_2000steps_obs-no-load-size"
    config = training_config("bc", tmp_path / "d.hdf5", tmp_path / "runs", "x", 1, 1, obs_set="no-load")
    assert config["observation"]["modalities"]["obs"]["low_dim"] == list(OBSERVATION_SETS["no-load"])
    with pytest.raises(
        ValueError,
        match=r"unknown observation set 'counts'; accepted: "
        r"\['no-load', 'no-load-rot', 'no-load-size', 'object', 'wrench'\]",
    ):
        PipelineSettings(**grid, obs_sets=["counts"])


def test_an_rnn_horizon_names_the_recurrent_models_columns_trains_the_same_runs_and_needs_one(tmp_path):
    """--rnn-horizon N changes how the recurrent models roll out, not what is trained: the same runs, columns that
    say it; a study without a recurrent algorithm refuses it (exit 2) before it writes anything."""
    grid = dict(output_dir=str(tmp_path), algos=["bc", "bc_rnn"], seed=0, score_demonstrators=False)
    every_20 = PipelineSettings(**grid, rnn_horizon=20)
    assert every_20.own_agents() == ["expert BC no-load-size obs", "expert BC-RNN no-load-size obs rnn.horizon 20"]
    assert every_20.run_name("expert", "bc_rnn", 30, 1) == PipelineSettings(**grid).run_name("expert", "bc_rnn", 30, 1)
    assert ALGORITHMS["bc_rnn"].recurrent and not ALGORITHMS["bc"].recurrent
    with pytest.raises(ValueError, match=r"rnn_horizon applies to recurrent algorithms \(bc_rnn, bc_rnn_gmm\)"):
        PipelineSettings(output_dir=str(tmp_path), algos=["bc", "bcq"], rnn_horizon=20)
    out = tmp_path / "s"
    args = ["--output-dir", out, "--algos", "bc", "bcq", "--rnn-horizon", "20"]
    result = run_program("veragmil-study", *args, timeout=60, check=False)
    assert result.returncode == 2 and "algos ['bc', 'bcq'] has none" in result.stderr and not out.exists()


def test_the_seed_table_gives_each_seeds_rate_and_their_mean_and_range():
    from veragmil_suite.evaluation.agents import EpisodeRecord
    from veragmil_suite.evaluation.reporting import EvaluationResult, seed_markdown, seed_spread

    def episodes(agent, food, successes, n=4):
        common = dict(grains_spilled=0, spilled_volume_cm3=0.0, completion_time_s=9.0, steps=200, end_reason="",
                      physics_error="", grains_in_spoon=5, spill_fraction=0.0, peak_grains_in_spoon=5,
                      wall_s=1.0)  # fmt: skip
        return [
            EpisodeRecord(
                agent=agent,
                food=food,
                episode=i,
                seed=i,
                success=i < successes,
                stage="held" if i < successes else "start",
                **common,
            )
            for i in range(n)
        ]

    records = (
        episodes("a1", "rice", 4) + episodes("a1", "peas", 1) + episodes("a2", "rice", 2) + episodes("a2", "peas", 3)
    )
    result = EvaluationResult(records, agents=["a1", "a2"], foods=["rice", "peas"])
    points = [dict(agent="a1", recipe="BC", train_seed=1), dict(agent="a2", recipe="BC", train_seed=2)]
    rows = {r["train_seed"]: r for r in seed_spread(result, points)}
    assert [rows[k]["seen success %"] for k in (1, 2, "mean", "lowest", "highest")] == [100, 50, 75, 50, 100]
    assert [rows[k]["unseen success %"] for k in (1, 2, "mean")] == [25, 75, 50]
    assert rows["mean"]["overall success %"] == 62.5
    assert "| BC | 1, 2 | 75 (50-100) | 50 (25-75) | 62 (62-62) | 100, 50 | 25, 75 | 62, 62 |" in seed_markdown(
        list(rows.values())
    )


def test_an_algorithm_with_its_own_budget_is_evaluated_at_its_end_and_at_the_sweeps_steps_it_reaches(tmp_path):
    grid = dict(output_dir=str(tmp_path), algos=["bc", "bc_rnn", "bcq"], epochs=100, steps_per_epoch=500)
    settings = PipelineSettings(**grid, algo_epochs={"bc_rnn": 40})
    assert [settings.total_steps_of(a) for a in ("bc", "bc_rnn", "bcq")] == [50000, 20000, 50000]
    assert settings.steps_of("bc") == [50000] and settings.steps_of("bc_rnn") == [20000]
    assert settings.own_agents() == [
        "expert operator", "expert BC no-load-size obs 50k steps", "expert BC-RNN no-load-size obs 20k steps",
        "expert BCQ no-load-size obs 50k steps",
    ]  # fmt: skip
    curve = PipelineSettings(**grid, algo_epochs={"bc_rnn": 40}, eval_steps=[10000, 50000])
    assert curve.steps_of("bc") == [10000, 50000] and curve.steps_of("bc_rnn") == [10000, 20000]
    assert PipelineSettings(**grid).own_agents() == [
        "expert operator",
        "expert BC no-load-size obs",
        "expert BC-RNN no-load-size obs",
        "expert BCQ no-load-size obs",
    ]
    longer = PipelineSettings(**grid, algo_epochs={"bcq": 200})  # more than epochs: its own end only
    assert longer.steps_of("bcq") == [100000] and longer.steps_of("bc") == [50000]
    assert longer.own_agents() == [
        "expert operator", "expert BC no-load-size obs 50k steps", "expert BC-RNN no-load-size obs 50k steps",
        "expert BCQ no-load-size obs 100k steps",
    ]  # fmt: skip
    with pytest.raises(ValueError, match=r"algo_epochs names unknown algorithm\(s\) \['gail'\]; accepted"):
        PipelineSettings(**grid, algo_epochs={"gail": 3})
    with pytest.raises(ValueError, match=r"eval_steps \[60000\] .* up to .* \(50000\)"):
        PipelineSettings(**grid, algo_epochs={"bc_rnn": 40}, eval_steps=[60000])


# what veragmil-quickstart prints on stdout: a line per stage, the tables, where they went
QUICKSTART_LINES = re.compile(
    r"\[veragmil\] .*|Table (II|III): .*|Physics \(grain models.*\): calibrated|Spill limit of success \(.*\): scooped"
    r"|Furthest stage .*|\|.*\|"
    r"|Tables, chart and .*|"
)


def test_quickstart_end_to_end_records_trains_evaluates_and_prints_the_tables(tmp_path):
    """The README's main job, shrunk: one cheap food, one demo, a few gradient steps, one episode per agent."""
    out = tmp_path / "qs"
    args = ["--output-dir", out, "--train-foods", "pasta", "--eval-foods", "pasta", "peas", "--n-grains", "12"]
    args += ["--demos-per-food", "1", "--epochs", "2", "--steps-per-epoch", "5", "--episodes", "1", "--horizon", "250"]
    result = run_program("veragmil-quickstart", *args, check=False)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    with h5py.File(out / "data" / "expert.hdf5") as f:
        assert len(f["data"]) == 1
        assert json.loads(f["data"].attrs["env_args"])["env_kwargs"]["food"] == "pasta"
    (checkpoint,) = (out / "runs").glob("expert_bc_1demos_10steps_obs-no-load-size/*/models/model_epoch_2.pth")
    summary = json.loads((out / "eval" / "results.json").read_text())
    agents = {e["agent"] for e in summary["episodes"]}
    assert agents == {
        "expert BC no-load-size obs",
        "expert operator",
        "pretrained BC-RNN no-load-size obs 50k",
    }  # the shipped checkpoint beside
    assert {(e["agent"], e["food"]) for e in summary["episodes"]} == {(a, f) for a in agents for f in ("pasta", "peas")}
    for name in ("table.md", "table.csv", "episodes.csv", "success.png"):
        assert (out / "eval" / name).stat().st_size > 0
    assert "expert BC no-load-size obs" in result.stdout and "peas" in result.stdout and "pasta" in result.stdout
    stages = (out / "eval" / "stages.md").read_text()
    # the expert's one episode has its row (whether a 12-grain pasta scoop succeeds on one seed is a property of
    # the CPU: the same seed held on one host and scooped nothing on another; measure_expert measures the expert)
    assert re.search(r"\| expert operator \| pasta \| 1 \|( \d+ \|){6}", stages), stages
    # its stages, a progress bar for each, the tables, and nothing else
    assert not warning_lines((result.stdout + result.stderr).splitlines())
    bars = result.stderr.replace("\r", "\n")
    for bar in ("expert pasta: 100%", "expert_bc_1demos_10steps_obs-no-load-size: 100%", "episodes: 100%"):
        assert bar in bars, bars[-2000:]
    assert not [line for line in result.stdout.splitlines() if not QUICKSTART_LINES.fullmatch(line)], result.stdout


CHEAP_STUDY = ["--profiles", "expert", "--algos", "bc", "--train-foods", "pasta", "--eval-foods", "pasta", "peas"]
CHEAP_STUDY += ["--n-grains", "12", "--epochs", "2", "--steps-per-epoch", "5", "--horizon", "250"]
# one evaluation worker and no recording pool: the tests run two at a time on two cores, and a second worker's start
# would cost more than its episodes (the tests of parallel pieces ask for more)
CHEAP_STUDY += ["--processes", "1"]


def _start_study(args: list, output: int) -> subprocess.Popen:
    """veragmil-study with ``args`` in a session of its own (to be killed with everything it started), its output
    sent to ``output`` (subprocess.PIPE: read as text)."""
    return subprocess.Popen(
        [str(BIN / "veragmil-study"), *map(str, args)],
        stdout=output,
        stderr=output,
        stdin=subprocess.DEVNULL,
        text=True,
        env=dict(os.environ, MUJOCO_GL="osmesa"),
        start_new_session=True,
    )


@pytest.mark.xdist_group("studies")  # not beside test_ray.py's studies: each starts many processes
def test_a_killed_study_resumes_and_skips_every_finished_piece(tmp_path):
    out = tmp_path / "study"
    args = [*CHEAP_STUDY, "--output-dir", out, "--demos-per-food", "1", "2", "--eval-steps", "5", "10"]
    args += ["--eval-foods", "pasta", "--episodes", "1"]
    first = _start_study(args, subprocess.DEVNULL)
    journal = out / "eval" / "episodes.jsonl"
    deadline = time.monotonic() + 500
    while time.monotonic() < deadline and first.poll() is None:
        if journal.exists() and len(journal.read_text().splitlines()) >= 2:
            break
        time.sleep(0.2)
    assert first.poll() is None, "the study ended before it could be killed mid-evaluation"
    os.killpg(first.pid, signal.SIGKILL)  # the study and its evaluation workers, mid-evaluation
    first.wait()
    journaled = len([line for line in journal.read_text().splitlines() if line.endswith("}")])
    assert journaled >= 2
    # the killed run noted its evaluation's time episode by episode: the resumed run adds its own to it
    killed = json.loads((out / "timings.json").read_text())["evaluate"]
    assert killed > 0
    checkpoints = sorted((out / "runs").glob("expert_bc_*/*/models/*.pth"))
    assert len(checkpoints) == 4  # 2 demo counts x checkpoints at 5 and 10 steps

    again = run_program("veragmil-study", *args, check=False)
    assert again.returncode == 0, again.stdout[-3000:] + again.stderr[-3000:]
    config = json.loads((out / "eval" / "results.json").read_text())["config"]
    assert config["env_kwargs"]["physics"] == "calibrated" and config["physics"] == ["calibrated"]  # every agent on it
    said = again.stdout
    assert "skipping recording expert pasta" in said
    for demos in (1, 2):
        assert f"skipping training expert_bc_{demos}demos_10steps_obs-no-load-size" in said
    assert f"skipping {journaled} evaluation episodes" in said
    assert json.loads((out / "timings.json").read_text())["evaluate"] > killed
    assert sorted((out / "runs").glob("expert_bc_*/*/models/*.pth")) == checkpoints  # not trained again
    results = json.loads((out / "eval" / "results.json").read_text())
    agents = {e["agent"] for e in results["episodes"]}
    assert agents == {
        "expert operator",
        "expert BC no-load-size obs 1 demos 5 steps",
        "expert BC no-load-size obs 1 demos 10 steps",
        "expert BC no-load-size obs 2 demos 5 steps",
        "expert BC no-load-size obs 2 demos 10 steps",
    }
    # every (agent, food, episode) exactly once: 5 agents x 1 food x 1 episode
    keys = [(e["agent"], e["food"], e["episode"]) for e in results["episodes"]]
    assert len(keys) == len(set(keys)) == 5
    with open(out / "eval" / "curves.csv") as f:
        curves = list(csv.DictReader(f))
    assert [(int(r["demos_per_food"]), int(r["steps"])) for r in curves] == [(1, 5), (1, 10), (2, 5), (2, 10)]
    assert all(
        0 <= float(r["seen ci95 low"]) <= float(r["seen success %"]) <= float(r["seen ci95 high"]) for r in curves
    )
    assert (out / "eval" / "curves.png").read_bytes()[:4] == b"\x89PNG"
    # the smaller dataset is the first demo of each food of the larger one
    with h5py.File(out / "data" / "expert.hdf5") as f:
        assert [n.decode() for n in f["mask/first1"][:]] == ["demo_0"]
        assert sorted(n.decode() for n in f["mask/first2"][:]) == ["demo_0", "demo_1"]

    # asking for the last checkpoints only finds everything done: the same runs, the episodes journaled, and the wall
    # times kept of the runs that did the work
    timings = json.loads((out / "timings.json").read_text())
    last_only = run_program(
        "veragmil-study", *args[: args.index("--eval-steps")], "--eval-foods", "pasta", "--episodes", "1", check=False
    )
    assert (
        last_only.returncode == 0 and "skipping training expert_bc_2demos_10steps_obs-no-load-size" in last_only.stdout
    )
    assert "skipping recording expert pasta" in last_only.stdout
    assert "skipping 3 evaluation episodes" in last_only.stdout  # operator and the two last checkpoints
    assert "; 0 to run" in last_only.stdout
    assert json.loads((out / "timings.json").read_text()) == timings
    # a second training seed trains one more run beside the first (kept: it is seed 1's) and reports the spread
    seeds = [*CHEAP_STUDY, "--output-dir", out, "--demos-per-food", "1", "--eval-foods", "pasta", "--episodes", "1"]
    two = run_program("veragmil-study", *seeds, "--train-seeds", "1", "2", "--no-operators", check=False)
    assert two.returncode == 0, two.stdout[-3000:] + two.stderr[-3000:]
    assert "skipping training expert_bc_1demos_10steps_obs-no-load-size:" in two.stdout
    assert (
        len(list((out / "runs").glob("expert_bc_1demos_10steps_obs-no-load-size_seed2/*/models/model_epoch_2.pth")))
        == 1
    )
    config = json.loads((out / "runs" / "expert_bc_1demos_10steps_obs-no-load-size_seed2.json").read_text())
    assert config["train"]["seed"] == 2
    assert "skipping 1 evaluation episodes" in two.stdout and "; 1 to run" in two.stdout
    # the seed's scoring adds its time to the evaluation's: the study's wall times cover every piece of scoring
    assert json.loads((out / "timings.json").read_text())["evaluate"] > timings["evaluate"]
    assert json.loads((out / "eval" / "results.json").read_text())["config"]["episodes_journaled"] >= 3
    with open(out / "eval" / "seeds.csv") as f:
        spread = {r["train_seed"]: float(r["seen success %"]) for r in csv.DictReader(f)}
    assert spread["mean"] == (spread["1"] + spread["2"]) / 2 and spread["lowest"] == min(spread["1"], spread["2"])
    assert "| expert BC no-load-size obs | 1, 2 |" in (out / "eval" / "seeds.md").read_text()
    # one demo count and no sweep: the learning curves of the runs before would describe other agents
    assert not (out / "eval" / "curves.csv").exists() and not (out / "eval" / "curves.png").exists()
    pooled = json.loads((out / "eval" / "seeds" / "results.json").read_text())
    assert [(s["agent"], s["episodes"]) for s in pooled["summary"]] == [("expert BC no-load-size obs", 2)]
    # back to one seed: the seed tables of the run before would describe agents this run's table does not hold
    one = run_program("veragmil-study", *seeds, "--no-operators", check=False)
    assert one.returncode == 0 and "; 0 to run" in one.stdout
    assert not any((out / "eval" / name).exists() for name in ("seeds.csv", "seeds.md", "seeds"))


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_study_refuses_to_mix_settings_in_one_folder_before_it_writes_anything(tmp_path):
    out = tmp_path / "study"
    (out / "runs").mkdir(parents=True)
    args = [*CHEAP_STUDY, "--output-dir", out, "--demos-per-food", "1", "--episodes", "1"]
    (out / "runs" / "expert_bc_1demos_10steps_obs-no-load-size.json").write_text(json.dumps({"another": "config"}))
    before = _tree(out)
    result = run_program("veragmil-study", *args, check=False)
    assert (
        result.returncode == 1 and "holds another config for expert_bc_1demos_10steps_obs-no-load-size" in result.stderr
    )
    assert _tree(out) == before and not (out / "data").exists()  # nothing recorded, merged or trained first


def test_a_study_folder_named_relative_or_absolute_is_one_folder(tmp_path, monkeypatch):
    """A study resumed with its folder spelled the other way finds its own runs, and still refuses another config."""
    from veragmil_suite.study.settings import StageError
    from veragmil_suite.study.training import finished_training, training_config

    monkeypatch.chdir(tmp_path)
    relative = training_config("bc", Path("study/data/expert.hdf5"), Path("study/runs"), "run", 2, 10)
    absolute = training_config("bc", tmp_path / "study/data/expert.hdf5", tmp_path / "study/runs", "run", 2, 10)
    (tmp_path / "study/runs").mkdir(parents=True)
    (tmp_path / "study/runs/run.json").write_text(json.dumps(relative))
    assert finished_training(absolute, tmp_path / "study/runs") is None  # the same run, not yet trained
    other = training_config("bc", tmp_path / "study/data/spacemouse.hdf5", tmp_path / "study/runs", "run", 2, 10)
    with pytest.raises(StageError, match="holds another config for run"):
        finished_training(other, tmp_path / "study/runs")


def test_a_killed_training_of_the_same_config_is_resumed_and_another_retrained(tmp_path, monkeypatch):
    """The study's training goes on from a killed run's resume state (veragmil-train --resume) when the run held
    this config; a run saved at other epochs is trained again from the start, saving both."""
    from veragmil_suite.study import training
    from veragmil_suite.study.settings import StageError

    commands = []

    def run_logged(command, *args, **kwargs):
        commands.append(command)
        return 1.0

    monkeypatch.setattr(training, "run_logged", run_logged)
    work = tmp_path / "runs"
    work.mkdir()
    config = training.training_config("bc", tmp_path / "data.hdf5", work, "run", 2, 10)
    (work / "run.json").write_text(json.dumps(config))
    (work / "run" / "stamp").mkdir(parents=True)
    with pytest.raises(StageError):  # the stand-in trains nothing
        training.train_checkpoint(config, work)
    assert commands[-1][-1] == "--resume" and (work / "run" / "stamp").exists()
    extra = training.training_config("bc", tmp_path / "data.hdf5", work, "run", 2, 10, save_epochs=[1])
    with pytest.raises(StageError):
        training.train_checkpoint(extra, work)
    assert "--resume" not in commands[-1] and not (work / "run").exists()
    assert json.loads((work / "run.json").read_text())["experiment"]["save"]["epochs"] == [1]


def test_a_run_whose_data_changed_since_it_trained_is_trained_again_from_the_start(tmp_path, monkeypatch):
    """A finished or killed run trained on a file since made again from other demos (or cut by another rule) is no
    model of that data: it is trained again, not skipped or resumed; the same data made again is skipped."""
    from helpers.recording import synthetic_episode, synthetic_writer

    from veragmil_suite.study import training

    commands = []

    def run_logged(command, *args, **kwargs):  # a training that saves its checkpoints
        commands.append(command)
        models = tmp_path / "runs" / "run" / f"t{len(commands)}" / "models"
        models.mkdir(parents=True)
        for epoch in (1, 2):
            (models / f"model_epoch_{epoch}.pth").write_bytes(b"")
        return 1.0

    def record(seeds):
        (tmp_path / "data.hdf5").unlink(missing_ok=True)
        with synthetic_writer(tmp_path / "data.hdf5") as writer:
            for seed in seeds:
                writer.write(synthetic_episode(seed=seed))

    monkeypatch.setattr(training, "run_logged", run_logged)
    work = tmp_path / "runs"
    work.mkdir()
    record([1, 2])
    config = training.training_config("bc", tmp_path / "data.hdf5", work, "run", 2, 10)
    training.train_checkpoint(config, work)
    assert len(commands) == 1 and training.finished_training(config, work) is not None
    record([1, 2])  # the same demos recorded again
    assert training.finished_training(config, work) is not None and not training.trained_on_other_data(config, work)
    record([1, 3])  # other demos
    assert training.trained_on_other_data(config, work) and training.finished_training(config, work) is None
    training.train_checkpoint(config, work)
    assert len(commands) == 2 and "--resume" not in commands[-1]
    assert [p.name for p in (work / "run").iterdir()] == ["t2"]  # the run on the old data is gone
    assert training.finished_training(config, work) is not None
    (work / "run.data.json").unlink()  # a run from before the digest was kept: taken as it is
    record([4])
    assert training.finished_training(config, work) is not None


def test_a_study_of_other_foods_leaves_another_studys_merged_dataset_alone(tmp_path):
    """Its training runs would otherwise be taken for runs on the foods asked (and the merged file was rewritten
    before the study refused)."""
    from helpers.recording import synthetic_episode, synthetic_writer

    from veragmil_suite.study.record import merge_profile_dataset

    out = tmp_path / "study"
    foods = [out / "data" / "expert" / f"{food}.hdf5" for food in ("pasta", "peas")]
    for seed, path in enumerate(foods):
        path.parent.mkdir(parents=True, exist_ok=True)
        with synthetic_writer(path) as writer:
            for k in range(4):
                writer.write(synthetic_episode(seed=10 * seed + k))
    merge_profile_dataset(out / "data" / "expert.hdf5", foods, [4])
    for path in foods:  # the merged dataset alone: the foods' files are checked on their own
        path.unlink()
    before = _tree(out)
    result = run_program(
        "veragmil-study", *CHEAP_STUDY, "--output-dir", out, "--demos-per-food", "1", "--episodes", "1", check=False
    )
    assert result.returncode == 1, result.stdout[-2000:] + result.stderr[-2000:]
    assert "expert.hdf5 merges pasta.hdf5, peas.hdf5 (asked: pasta.hdf5)" in result.stderr
    assert _tree(out) == before


def test_a_stage_called_as_a_function_logs_its_output_and_fails_with_the_tail_of_its_log(tmp_path):
    """The study's recording is a function in a fresh interpreter (run_logged_call): everything it prints, Python's
    and C's, is in its log; its progress is read from that log; an exception fails the stage with the log's tail."""
    from helpers.children import say_then

    from veragmil_suite.study.logged_run import RECORDING_PROGRESS, LogProgress, run_logged_call

    log = tmp_path / "stage.log"
    lines = ["  saved as demo_0 (1/2)", "  saved as demo_1 (2/2)"]
    bar = LogProgress(2, RECORDING_PROGRESS, "stage", "demo")
    before = dict(os.environ)
    call = dict(lines=lines, c_line="from C", variables=("PYNPUT_BACKEND",))
    assert run_logged_call(say_then, call, log, "stage", progress=bar) > 0
    # the child's environment has pynput's dummy backend; this process's is left as it was
    backend = before.get("PYNPUT_BACKEND", "dummy")
    assert log.read_text().splitlines() == [*lines, f"PYNPUT_BACKEND={backend}", "from C"]
    assert dict(os.environ) == before
    with pytest.raises(StageError, match=r"(?s)failing stage failed \(exit 1\); log .*stage.log:.*before.*it broke"):
        run_logged_call(say_then, dict(lines=["before"], error="it broke"), log, "failing stage")


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stage_signalled_as_it_exits_still_lets_go_of_its_semaphores(signum, tmp_path):
    """A SIGTERM (stop_tree's) or Ctrl-C (the terminal's, to the whole group) that reaches a stage after its function
    does not cut multiprocessing's exit clean-up short: otherwise its pools' semaphores leak, and a resource tracker
    reports them (the stage's own, in its log; never on the study's stderr)."""
    marker, log = tmp_path / "exiting", tmp_path / "stage.log"
    script = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "from helpers.children import hold_a_semaphore_and_exit_slowly\n"
        "from veragmil_suite.study.logged_run import run_logged_call\n"
        "run_logged_call(hold_a_semaphore_and_exit_slowly, dict(marker=sys.argv[2]), sys.argv[3], 'stage')\n"
    )
    study = subprocess.Popen(
        [sys.executable, "-c", script, str(Path(__file__).parent), str(marker), str(log)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not marker.exists() and study.poll() is None:
            time.sleep(0.02)
        assert marker.exists(), "the stage did not reach its exit"
        os.kill(int(marker.read_text()), signum)
        _, stderr = study.communicate(timeout=60)
    finally:
        study.kill()
    assert study.returncode == 0, stderr[-2000:]
    time.sleep(1)  # the stage's tracker writes once the stage is gone
    assert "leaked" not in stderr + log.read_text(), stderr[-2000:] + log.read_text()[-2000:]


def test_a_shorter_recording_is_continued_to_the_demos_one_run_records(tmp_path):
    whole, grown = tmp_path / "whole.hdf5", tmp_path / "grown.hdf5"
    kwargs = dict(food="pasta", profile="expert", seed=5, n_grains=12, horizon=250)
    assert record_food(whole, demos=2, **kwargs) > 0
    assert record_food(grown, demos=1, **kwargs) > 0
    assert record_food(grown, demos=2, **kwargs) > 0  # continued from the seed after its last attempt
    assert record_food(grown, demos=2, **kwargs) is None  # complete: skipped
    with h5py.File(whole) as a, h5py.File(grown) as b:
        assert sorted(a["data"].keys()) == sorted(b["data"].keys())
        for name in a["data"]:
            assert a["data"][name].attrs["seed"] == b["data"][name].attrs["seed"]
            assert (a["data"][name]["states"][:] == b["data"][name]["states"][:]).all()
    with pytest.raises(StageError, match="recorded with other settings: n_grains 12 \\(asked: 10\\)"):
        record_food(grown, demos=3, **dict(kwargs, n_grains=10))
    # demos on piles this code no longer settles (another grain model, lattice or solver), or observed otherwise
    # than it records (an observation added since), are not continued or taken as complete; the file is left as it was
    with h5py.File(grown) as f:
        assert all(f[f"data/{name}"].attrs["pile"] for name in f["data"])  # each demo names its settled pile

    def other_pile(f):
        f["data/demo_1"].attrs["pile"] = "0" * 24

    def one_observation_fewer(f):
        for name in f["data"]:
            del f[f"data/{name}/obs/bowl_pos"], f[f"data/{name}/next_obs/bowl_pos"]

    for change, said in (
        (other_pile, "on 1 settled piles this code no longer draws \\(its grains, lattice, settling or solver\\)"),
        (one_observation_fewer, "observed otherwise than this code records \\(bowl_pos\\)"),
    ):
        stale = tmp_path / f"{change.__name__}.hdf5"
        shutil.copyfile(grown, stale)
        with h5py.File(stale, "r+") as f:
            change(f)
        held = stale.read_bytes()
        for demos in (2, 3):
            with pytest.raises(StageError, match=f"{stale.name} holds demos {said}; move the file away"):
                record_food(stale, demos=demos, **kwargs)
        assert stale.read_bytes() == held
    with pytest.raises(StageError, match="physics 'calibrated' \\(asked: 'table1'\\)"):
        record_food(grown, demos=3, **dict(kwargs, physics="table1"))
    # the wrist sensor (the wrench observations): a file without it cannot serve a study that trains on it; a file
    # with it serves one that does not
    with pytest.raises(StageError, match="wrench False \\(asked: True\\)"):
        record_food(grown, demos=3, **dict(kwargs, wrench=True))
    felt = tmp_path / "felt.hdf5"
    assert record_food(felt, demos=1, **dict(kwargs, wrench=True)) > 0
    assert record_food(felt, demos=1, **kwargs) is None
    assert record_food(felt, demos=2, **kwargs) > 0  # continued with the sensor it was recorded with
    with h5py.File(felt) as f:
        for name in ("demo_0", "demo_1"):
            assert {"robot0_eef_force", "robot0_eef_torque"} <= set(f[f"data/{name}/obs"])


def test_a_study_records_on_its_physics(tmp_path):
    """The physics reaches the recorder's command and is refused when unknown (the evaluation's: the killed-study
    test)."""
    from veragmil_suite.study.settings import PipelineSettings

    with pytest.raises(ValueError, match="accepted physics: calibrated, table1"):
        PipelineSettings(output_dir=str(tmp_path), physics="sand")
    path = tmp_path / "rice.hdf5"
    assert record_food(path, "pasta", demos=1, n_grains=12, horizon=250, physics="table1") > 0
    with h5py.File(path) as f:
        assert json.loads(f["data"].attrs["env_args"])["env_kwargs"]["physics"] == "table1"


def test_a_study_with_drop_noops_trains_on_its_data_without_the_operators_pauses(tmp_path):
    """--drop-noops: the spacemouse operator's pauses (zero actions) are cut from the merged recording into
    data/<profile>-no-noops.hdf5, the models train on that file and their runs and columns say so (when the file
    is made again: the next test). With --rnn-horizon the BC-RNN is scored with its LSTM reset that often."""
    out = tmp_path / "study"
    args = ["--profiles", "spacemouse", "--algos", "bc_rnn", "--train-foods", "pasta", "--eval-foods", "pasta"]
    args += ["--n-grains", "12", "--demos-per-food", "1", "--epochs", "1", "--steps-per-epoch", "5", "--episodes", "1"]
    args += ["--no-operators", "--drop-noops", "--rnn-horizon", "3", "--output-dir", out]
    first = run_program("veragmil-study", *args, check=False)
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    merged, cut = out / "data" / "spacemouse.hdf5", out / "data" / "spacemouse-no-noops.hdf5"
    with h5py.File(merged) as a, h5py.File(cut) as b:
        before, after = int(a["data"].attrs["total"]), int(b["data"].attrs["total"])
        zero = sum(int((a[f"data/{n}/actions"][()] == 0).all(axis=1).sum()) for n in a["data"])
        assert zero > 0 and after == before - zero  # the operator paused, and every pause is gone
        assert not any((b[f"data/{n}/actions"][()] == 0).all(axis=1).any() for n in b["data"])
        assert b["mask/first1"][()].tolist() == a["mask/first1"][()].tolist()
    assert f"dropped {zero} no-op steps of {before} from spacemouse.hdf5" in first.stdout
    config = json.loads((out / "runs" / "spacemouse_bc_rnn_1demos_5steps_obs-no-load-size_no-noops.json").read_text())
    assert config["train"]["data"] == str(cut) and config["algo"]["rnn"]["horizon"] == 10
    results = json.loads((out / "eval" / "results.json").read_text())
    model = "spacemouse BC-RNN no-load-size obs no-noops rnn.horizon 3"
    assert {e["agent"] for e in results["episodes"]} == {model} and results["config"]["rnn_horizon"] == {model: 3}


def test_the_copy_without_noops_is_made_again_only_when_the_recording_changed(tmp_path):
    from helpers.recording import record_file

    from veragmil_suite.scripts.dataset_tools import drop_noops_main
    from veragmil_suite.study.record import drop_noops_once

    merged, path = tmp_path / "spacemouse.hdf5", tmp_path / "spacemouse-no-noops.hdf5"
    record_file(merged, episodes=1, steps=6)
    with h5py.File(merged, "r+") as f:
        actions = f["data/demo_0/actions"][()]
        actions[2] = 0.0
        f["data/demo_0/actions"][...] = actions
        f["data"].attrs["merged_inputs"] = "stamp 1"
    said = []
    drop_noops_once(merged, path, said.append)
    assert said[-1].startswith("dropped 1 no-op steps of 6 from spacemouse.hdf5")
    drop_noops_once(merged, path, said.append)
    assert said[-1].startswith("skipping dropping no-op steps")
    with h5py.File(merged, "r+") as f:
        f["data"].attrs["merged_inputs"] = "stamp 2"  # merged again from changed recordings
    drop_noops_once(merged, path, said.append)
    assert said[-1].startswith("dropped 1 no-op steps")
    shutil.copy(merged, path)  # a file there that is no copy without no-ops
    drop_noops_once(merged, path, said.append)
    assert said[-1].startswith("dropped 1 no-op steps")
    path.unlink()
    assert drop_noops_main([str(merged), "-o", str(path), "--keep-held"]) == 0  # made by the other rule
    drop_noops_once(merged, path, said.append)
    assert said[-1].startswith("dropped 1 no-op steps")
    with h5py.File(path) as f:
        assert f["data/demo_0"].attrs["num_samples"] == 5


def test_a_study_folder_copied_with_its_files_times_is_not_merged_again(tmp_path):
    """The merge's stamp names its inputs relative to the merged file: a copied study's data folder is used as it
    is (the 300 MB spacemouse file was merged and cut again, and its hard links to the first study broken)."""
    from helpers.recording import synthetic_episode, synthetic_writer

    from veragmil_suite.study.record import drop_noops_once, merge_profile_dataset

    first = tmp_path / "first" / "data"
    foods = [first / "spacemouse" / f"{food}.hdf5" for food in ("rice", "pasta")]
    for seed, path in enumerate(foods):
        path.parent.mkdir(parents=True, exist_ok=True)
        with synthetic_writer(path) as writer:
            for k in range(3):
                writer.write(synthetic_episode(seed=10 * seed + k))
    merge_profile_dataset(first / "spacemouse.hdf5", foods, [2])
    drop_noops_once(first / "spacemouse.hdf5", first / "spacemouse-no-noops.hdf5", lambda line: None)
    second = tmp_path / "second" / "data"
    shutil.copytree(first, second)  # copy2: the files keep their times
    held = {p: p.stat().st_mtime_ns for p in second.glob("*.hdf5")}
    copied = [second / "spacemouse" / p.name for p in foods]
    merge_profile_dataset(second / "spacemouse.hdf5", copied, [2])
    said = []
    drop_noops_once(second / "spacemouse.hdf5", second / "spacemouse-no-noops.hdf5", said.append)
    assert said[-1].startswith("skipping dropping no-op steps")
    assert {p: p.stat().st_mtime_ns for p in second.glob("*.hdf5")} == held
    merge_profile_dataset(second / "spacemouse.hdf5", copied, [1, 2])  # a new demo count: its mask is added
    with h5py.File(second / "spacemouse.hdf5") as f:
        assert 0 < len(f["mask/first1"][()]) < len(f["mask/first2"][()])
    copied[0].touch()  # a food recorded anew: merged again
    merge_profile_dataset(second / "spacemouse.hdf5", copied, [2])
    drop_noops_once(second / "spacemouse.hdf5", second / "spacemouse-no-noops.hdf5", said.append)
    assert said[-1].startswith("dropped")


def _alive(process: psutil.Process) -> bool:
    """Running, not a zombie, and not another process that took its pid since."""
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_a_terminated_study_takes_its_stage_processes_with_it(tmp_path):
    """SIGTERM (kill, a scheduler's stop) is one line and 143, and the stage under way goes with the study: a
    recorder left running would go on writing a file that the next run continues."""
    out = tmp_path / "study"
    args = [*CHEAP_STUDY, "--output-dir", out, "--demos-per-food", "2", "--episodes", "1", "--processes", "2"]
    study = _start_study(args, subprocess.PIPE)
    try:
        log = out / "data" / "expert" / "pasta.seed3000.log"
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (log.exists() and log.stat().st_size):
            time.sleep(0.1)
        assert log.exists(), "the recording did not start"
        # the recorder's worker pool under way: the recorder, its forkserver and its workers
        while time.monotonic() < deadline and len(psutil.Process(study.pid).children(recursive=True)) < 4:
            time.sleep(0.1)
        stage = psutil.Process(study.pid).children(recursive=True)
        assert len(stage) >= 4, stage
        study.send_signal(signal.SIGTERM)
        _, stderr = study.communicate(timeout=120)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and any(map(_alive, stage)):
            time.sleep(0.1)
        assert not [process for process in stage if _alive(process)]
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(study.pid, signal.SIGKILL)
    assert study.returncode == 128 + signal.SIGTERM
    assert [line for line in stderr.splitlines() if line.strip()][-1] == "veragmil-study: terminated"
    assert "Traceback" not in stderr
