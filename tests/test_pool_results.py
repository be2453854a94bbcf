"""veragmil-pool-results: agents of separate evaluations pooled into one, their training seeds into seed tables."""

import json
from pathlib import Path

import pytest

from veragmil_suite.evaluation.agents import EpisodeRecord
from veragmil_suite.evaluation.reporting import pool
from veragmil_suite.scripts.pool_results import main
from veragmil_suite.study.publish import publish

FOODS = ["rice", "pasta"]


def _episode(agent: str, food: str, episode: int, success: bool, pile: str = "") -> dict:
    return EpisodeRecord(
        agent=agent, food=food, episode=episode, seed=100000 + episode, success=success, grains_spilled=0,
        spilled_volume_cm3=0.0, completion_time_s=8.0 if success else 20.0, steps=200, end_reason="success"
        if success else "horizon", physics_error="", grains_in_spoon=30, spill_fraction=0.0,
        stage="held" if success else "loaded spoon", peak_grains_in_spoon=60, wall_s=5.0, pile=pile,
    ).to_dict()  # fmt: skip


def _evaluation(path: Path, wins: dict[str, int], piles: dict[str, str] | None = None, **config) -> Path:
    """A results.json whose agents each win their first ``wins[agent]`` of 4 episodes per food; ``piles``: the
    settled pile each food's episodes name (none: records from before piles were named)."""
    settings = dict(foods=FOODS, episodes=4, seed=100000, horizon=400, robot="XArm7", success_hold_s=1.0,
                    env_kwargs={}, versions={"mujoco": "3.8.1"})  # fmt: skip
    settings.update(config, agents={a: f"runs/grid/runs/{a.replace(' ', '_')}/t/models/m.pth" for a in wins})
    piles = piles or {}
    episodes = [_episode(a, f, i, i < n, piles.get(f, "")) for a, n in wins.items() for f in FOODS for i in range(4)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(dict(config=settings, summary=[], episodes=episodes)))
    return path


def test_agents_of_two_evaluations_pool_into_one_with_seed_tables(tmp_path):
    old = _evaluation(tmp_path / "old.json", {"expert BC seed 1": 4, "expert BC seed 2": 2, "expert BCQ seed 1": 0})
    new = _evaluation(tmp_path / "new.json", {"expert BC": 1})
    out = tmp_path / "pooled"
    assert (
        main(
            [
                str(out),
                "--agent",
                f"{old}:expert BC seed 1",
                "--agent",
                f"{old}:expert BC seed 2",
                "--agent",
                f"expert BC seed 4={new}:expert BC",
            ]
        )
        == 0
    )
    results = json.loads((out / "results.json").read_text())
    assert list(results["config"]["agents"]) == ["expert BC seed 1", "expert BC seed 2", "expert BC seed 4"]
    assert results["config"]["pooled_from"]["expert BC seed 4"] == f"{new}:expert BC"
    rates = {(s["agent"], s["food"]): s["success_rate"] for s in results["summary"]}
    assert rates[("expert BC seed 4", "rice")] == 0.25 and rates[("expert BC seed 2", "pasta")] == 0.5
    assert not any(e["agent"].startswith("expert BCQ") for e in results["episodes"])
    # the three seeds pooled: (4 + 2 + 1) wins of 12 episodes per food
    pooled = {s["food"]: s for s in json.loads((out / "seeds" / "results.json").read_text())["summary"]}
    assert pooled["rice"]["agent"] == "expert BC" and pooled["rice"]["successes"] == 7
    assert pooled["rice"]["episodes"] == 12
    assert "| expert BC | 1, 2, 4 |" in (out / "seeds.md").read_text()


def test_the_pool_times_the_pieces_behind_its_agents_from_each_source_study(tmp_path):
    """Each source study's recording, the trainings of the agents taken from it and its evaluation, named by study
    where two studies time a piece differently; veragmil-publish-results lists them in RUN.md."""
    first = _evaluation(tmp_path / "s1" / "eval" / "results.json", {"expert BC": 4, "expert BCQ": 1})
    later = _evaluation(tmp_path / "s23" / "eval" / "results.json", {"expert BC seed 2": 3})
    for study, timings in [
        ("s1", {"record expert": 500.0, "train expert_BC": 800.0, "train expert_BCQ": 900.0, "evaluate": 400.0}),
        ("s23", {"record expert": 510.0, "train expert_BC_seed_2": 790.0, "evaluate": 380.0}),
    ]:
        (tmp_path / study / "timings.json").write_text(json.dumps(timings))
    out = tmp_path / "pooled" / "eval"
    assert (
        main([str(out), "--agent", f"expert BC seed 1={first}:expert BC", "--agent", f"{later}:expert BC seed 2"]) == 0
    )
    assert json.loads((out / "timings.json").read_text()) == {
        f"record expert ({tmp_path / 's1'})": 500.0,
        "train expert_BC": 800.0,
        f"evaluate ({tmp_path / 's1'})": 400.0,
        f"record expert ({tmp_path / 's23'})": 510.0,
        "train expert_BC_seed_2": 790.0,
        f"evaluate ({tmp_path / 's23'})": 380.0,
    }
    publish(tmp_path / "pooled", tmp_path / "published", "pool.sh")
    assert f"| evaluate ({tmp_path / 's23'}) | 380.0 |" in (tmp_path / "published" / "RUN.md").read_text()


def test_a_pool_of_published_folders_keeps_their_times_and_names_each_seeds_machine(tmp_path):
    """Seeds scored on two kinds of CPU, each published, then pooled from the published folders (a later seed joining
    a committed results/ folder): the pool keeps each folder's timed pieces and its RUN.md names each machine with the
    seeds it scored."""
    published = []
    for seed, cpu in [(1, "Intel Xeon"), (2, "AMD EPYC")]:
        study = tmp_path / f"s{seed}"
        _evaluation(study / "eval" / "results.json", {"expert BC": seed}, host={"cpu": cpu, "cores": 2})
        (study / "timings.json").write_text(json.dumps({"train expert_BC": 800.0 + seed, "evaluate": 400.0 + seed}))
        publish(study, tmp_path / "results" / f"seed{seed}", f"study {seed}")
        published.append(tmp_path / "results" / f"seed{seed}" / "results.json")
    out = tmp_path / "pooled" / "eval"
    agents = [f"expert BC seed {s}={published[s - 1]}:expert BC" for s in (1, 2)]
    assert main([str(out), "--agent", agents[0], "--agent", agents[1]]) == 0
    timings = json.loads((out / "timings.json").read_text())
    assert timings[f"evaluate ({tmp_path / 'results' / 'seed2'})"] == 402.0
    assert timings[f"train expert_BC ({tmp_path / 'results' / 'seed1'})"] == 801.0
    config = json.loads((out / "results.json").read_text())["config"]
    assert config["hosts"] == {"expert BC seed 1": {"cpu": "Intel Xeon", "cores": 2},
                               "expert BC seed 2": {"cpu": "AMD EPYC", "cores": 2}}  # fmt: skip
    publish(tmp_path / "pooled", tmp_path / "results" / "pooled", "pool")
    run_md = (tmp_path / "results" / "pooled" / "RUN.md").read_text()
    assert "- cpu Intel Xeon, cores 2: expert BC seed 1\n- cpu AMD EPYC, cores 2: expert BC seed 2\n" in run_md
    assert "which published" not in run_md


def test_an_agents_rnn_horizon_comes_with_it_into_the_pool_and_its_seed_tables(tmp_path):
    """A BC-RNN scored with --rnn-horizon keeps that setting under its new name; the others have none."""
    reset = _evaluation(tmp_path / "h20.json", {"BC-RNN": 3, "expert BC": 1}, rnn_horizon={"BC-RNN": 20})
    stock = _evaluation(tmp_path / "h10.json", {"BC-RNN": 2})
    out = tmp_path / "pooled"
    choices = ["BC-RNN h20 seed 1=" + f"{reset}:BC-RNN", "BC-RNN h20 seed 2=" + f"{reset}:BC-RNN"]
    choices += [f"BC-RNN seed 1={stock}:BC-RNN", f"BC={reset}:expert BC"]
    assert main([str(out), *[a for c in choices for a in ("--agent", c)]]) == 0
    config = json.loads((out / "results.json").read_text())["config"]
    assert config["rnn_horizon"] == {"BC-RNN h20 seed 1": 20, "BC-RNN h20 seed 2": 20}
    assert json.loads((out / "seeds" / "results.json").read_text())["config"]["rnn_horizon"] == {"BC-RNN h20": 20}
    assert (
        (out / "table.md")
        .read_text()
        .endswith("(--rnn-horizon; others: their config's): BC-RNN h20 seed 1 20, BC-RNN h20 seed 2 20\n")
    )


def test_evaluations_that_differ_in_what_decides_an_episode_are_refused(tmp_path):
    old = _evaluation(tmp_path / "old.json", {"expert BC seed 1": 4})
    new = _evaluation(tmp_path / "new.json", {"expert BC": 1}, horizon=300)
    with pytest.raises(ValueError, match="differ in 'horizon' \\(300 against 400\\)"):
        pool([("a", old, "expert BC seed 1"), ("b", new, "expert BC")])


def test_episodes_of_one_bowl_on_different_settled_piles_are_refused(tmp_path):
    """Two evaluations alike in every setting whose code built one food's pile differently (a changed lattice) do not
    score the same bowls: pooling them is refused, naming the food and seed; records that name no pile pool."""
    old = _evaluation(tmp_path / "old.json", {"expert BC seed 1": 4}, piles={"rice": "a" * 24, "pasta": "b" * 24})
    new = _evaluation(tmp_path / "new.json", {"expert BCQ seed 1": 1}, piles={"rice": "a" * 24, "pasta": "c" * 24})
    with pytest.raises(
        ValueError, match=f"ran pasta's episode of seed 100000 on different settled piles \\({'c' * 24}"
    ):
        pool([("a", old, "expert BC seed 1"), ("b", new, "expert BCQ seed 1")])
    same = _evaluation(tmp_path / "same.json", {"expert BCQ seed 1": 1}, piles={"rice": "a" * 24, "pasta": "b" * 24})
    unnamed = _evaluation(tmp_path / "unnamed.json", {"spacemouse BC seed 1": 2})
    result, _ = pool(
        [("a", old, "expert BC seed 1"), ("b", same, "expert BCQ seed 1"), ("c", unnamed, "spacemouse BC seed 1")]
    )
    assert len(result.episodes) == 3 * 2 * 4


def test_an_unknown_agent_is_refused_with_the_agents_there(tmp_path):
    old = _evaluation(tmp_path / "old.json", {"expert BC seed 1": 4})
    with pytest.raises(ValueError, match="has no agent 'expert BCQ'; it has \\['expert BC seed 1'\\]"):
        pool([("a", old, "expert BCQ")])


def test_a_malformed_agent_argument_names_the_expected_form(tmp_path, capsys):
    assert main([str(tmp_path), "--agent", "expert BC seed 4=results.json"]) == 2
    assert "expected NAME=RESULTS_JSON:AGENT" in capsys.readouterr().err


@pytest.mark.parametrize("content", [None, "not JSON", "[1, 2]"])
def test_a_file_that_is_not_an_evaluation_exits_2_in_one_line_and_writes_nothing(tmp_path, capsys, content):
    source = tmp_path / "results.json"
    if content is not None:
        source.write_text(content)
    out = tmp_path / "pooled"
    assert main([str(out), "--agent", f"{source}:expert BC"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("veragmil-pool-results: ") and str(source) in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_two_recipes_are_compared_seed_by_seed_on_the_same_bowls_with_the_exact_sign_test(tmp_path, capsys):
    # per food, BC seed 1 wins episode 0 and BCQ seed 1 episodes 0-2; BC seed 2 wins 0-1 and BCQ seed 2 all four
    wins = {"expert BC seed 1": 1, "expert BC seed 2": 2, "expert BCQ seed 1": 3, "expert BCQ seed 2": 4}
    source = _evaluation(tmp_path / "old.json", wins)
    out = tmp_path / "pooled"
    agents = [a for name in wins for a in ("--agent", f"{source}:{name}")]
    paired = ["--paired", "expert BC", "expert BCQ", "--paired", "expert BCQ seed 2", "expert BC seed 1"]
    assert main([str(out), *agents, *paired]) == 0
    lines = (out / "paired.md").read_text().splitlines()
    assert lines[-1] in capsys.readouterr().out
    # 2 seeds x 2 foods x 4 bowls: BCQ wins alone on 2 bowls a seed and food, BC never does; p = 2 / 2^8
    assert "| expert BC | expert BCQ | seen (training) | 16 | 6 | 14 | 8 | 0 | 0.008 |" in lines
    # agents are paired bowl by bowl whatever their seeds: BC seed 1 wins 1 of 4 a food, BCQ seed 2 all
    assert "| expert BCQ seed 2 | expert BC seed 1 | overall | 8 | 8 | 2 | 0 | 6 | 0.031 |" in lines


@pytest.mark.parametrize(
    "first, second, said",
    [
        ("expert BC", "expert DP", "'expert DP' is neither an agent nor a recipe here"),
        ("expert BC", "expert BCQ", "no training seed in common (seeds [1] and [2])"),
    ],
)
def test_a_paired_comparison_that_cannot_be_made_exits_2_and_writes_nothing(tmp_path, capsys, first, second, said):
    source = _evaluation(tmp_path / "old.json", {"expert BC seed 1": 1, "expert BCQ seed 2": 3})
    out = tmp_path / "pooled"
    args = [str(out), "--agent", f"{source}:expert BC seed 1", "--agent", f"{source}:expert BCQ seed 2"]
    assert main([*args, "--paired", first, second]) == 2
    err = capsys.readouterr().err
    assert said in err and len(err.splitlines()) == 1
    assert not out.exists()
