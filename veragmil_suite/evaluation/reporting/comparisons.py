"""What compares models across one evaluation and across several: learning curves over checkpoints, seed tables over
training seeds, two models episode by episode on the same bowls, and pooling the agents of finished evaluations into
one, as if one run had scored them all."""

from __future__ import annotations

import csv
import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from veragmil_suite.evaluation.agents import EpisodeRecord
from veragmil_suite.evaluation.reporting.tables import (
    SEEN_LABEL,
    UNSEEN_LABEL,
    EvaluationResult,
    food_groups,
    table_rows,
    wilson_interval,
)
from veragmil_suite.learning.algorithms import ALGORITHMS
from veragmil_suite.utils.whole_files import write_text_whole, written_whole

# the evaluation settings two results.json must share for their episodes to be comparable
SHARED_SETTINGS = ("foods", "episodes", "seed", "horizon", "robot", "success_hold_s", "env_kwargs", "versions")
SEED_LABEL = re.compile(r"^(?P<recipe>.+) seed (?P<seed>\d+)$")


def _average_rows(result) -> dict[str, dict]:
    """Table II's average rows of ``result`` by group, "seen", "unseen" and "overall" (those its foods have)."""
    names = {SEEN_LABEL: "seen", UNSEEN_LABEL: "unseen", "all": "overall"}
    rows = table_rows(result.summary, result.agents, result.foods)["table2"]
    return {names[r["group"]]: r for r in rows if r["food"].endswith(" average")}


def learning_curves(result: EvaluationResult, points: list[dict]) -> list[dict]:
    """Success on seen and unseen foods (each food weighing the same, 95% Wilson intervals of the group's totals)
    per checkpoint of a sweep: ``points`` name each checkpoint agent's profile, algo, demos per food and steps."""
    averages = _average_rows(result)
    out = []
    for point in points:
        row = dict(point)
        for key in ("seen", "unseen"):
            group = averages.get(key)
            if group is None:
                continue
            a = point["agent"]
            low, high = wilson_interval(group[f"{a} successes"], group[f"{a} episodes"])
            row.update({f"{key} success %": group[a], f"{key} ci95 low": 100 * low, f"{key} ci95 high": 100 * high})
        out.append(row)
    return out


def write_learning_curves(result: EvaluationResult, points: list[dict], out_dir: Path) -> None:
    """curves.csv and curves.png: success against gradient steps (one line per demo count) and against demos
    per food (one line per step count), seen and unseen foods."""
    import matplotlib  # heavy: matplotlib, only when plotting

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # heavy: matplotlib, only when plotting

    rows = learning_curves(result, points)
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with written_whole(out_dir / "curves.csv") as partial, open(partial, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    axes_of = [("steps", "gradient steps", "demos_per_food", "demos/food"), ("demos_per_food", "demos per food",
               "steps", "steps")]  # fmt: skip
    axes_of = [a for a in axes_of if len({r[a[0]] for r in rows}) > 1]
    fig, axes = plt.subplots(1, len(axes_of), figsize=(5.5 * len(axes_of), 3.8), squeeze=False)
    several_seeds = len({r["train_seed"] for r in rows}) > 1
    for ax, (x_key, x_label, line_key, line_label) in zip(axes[0], axes_of):
        by_line = _groups_by(rows, ("profile", "algo", "obs_set", line_key, "train_seed"))
        for (profile, algo, obs, line, seed), group in by_line.items():
            group = sorted(group, key=lambda r: r[x_key])
            x = [r[x_key] for r in group]
            for key, style in (("seen", "-o"), ("unseen", "--s")):
                if f"{key} success %" not in group[0]:
                    continue
                y = np.array([r[f"{key} success %"] for r in group])
                err = np.array([[y_ - r[f"{key} ci95 low"], r[f"{key} ci95 high"] - y_] for y_, r in zip(y, group)]).T
                seed_label = f", seed {seed}" if several_seeds else ""
                name = f"{profile} {ALGORITHMS[algo].label} {obs} obs, {line} {line_label}{seed_label}, {key}"
                ax.errorbar(x, y, yerr=err.tolist(), fmt=style, capsize=3, label=name)  # lists: see plot_success
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks(sorted({r[x_key] for r in rows}), [str(v) for v in sorted({r[x_key] for r in rows})])
        ax.set_xlabel(x_label)
        ax.set_ylabel("success (%, 95% CI)")
        ax.set_ylim(0, 100)
        ax.legend(fontsize="x-small")
    fig.tight_layout()
    with written_whole(out_dir / "curves.png", keep_suffix=True) as partial:
        fig.savefig(partial, dpi=100)
    plt.close(fig)


def seed_spread(result: EvaluationResult, points: list[dict]) -> list[dict]:
    """Success on seen, unseen and all foods (each food weighing the same) of every training seed of each recipe
    (``points`` name each checkpoint agent's recipe and training seed), then the recipe's mean, lowest and highest
    over its seeds."""
    averages = _average_rows(result)
    out = []
    for (recipe,), seeds in _groups_by(points, ("recipe",)).items():
        per_seed = [
            dict(
                recipe=recipe,
                train_seed=p["train_seed"],
                **{f"{g} success %": averages[g][p["agent"]] for g in averages},
            )
            for p in seeds
        ]
        out += per_seed
        for stat, reduce in (("mean", np.mean), ("lowest", np.min), ("highest", np.max)):
            values = {f"{g} success %": float(reduce([r[f"{g} success %"] for r in per_seed])) for g in averages}
            out.append(dict(recipe=recipe, train_seed=stat, **values))
    return out


def seed_markdown(rows: list[dict]) -> str:
    """The seed table: per recipe, its mean success and the range over its training seeds, then each seed's."""
    groups = [g for g in ("seen", "unseen", "overall") if f"{g} success %" in rows[0]]
    lines = [
        "Success over training seeds (%, each food weighing the same; mean and lowest-highest over the seeds, "
        "every seed's model scored on the same episodes)",
        "",
        "| model | training seeds | " + " | ".join(groups) + " | " + " | ".join(f"{g} per seed" for g in groups) + " |",
        "|---|---|" + "---:|" * (2 * len(groups)),
    ]
    for (recipe,), group in _groups_by(rows, ("recipe",)).items():
        stats = {r["train_seed"]: r for r in group if isinstance(r["train_seed"], str)}
        seeds = [r for r in group if not isinstance(r["train_seed"], str)]
        cells = [
            f"{stats['mean'][f'{g} success %']:.0f} ({stats['lowest'][f'{g} success %']:.0f}-"
            f"{stats['highest'][f'{g} success %']:.0f})"
            for g in groups
        ]
        cells += [", ".join(f"{r[f'{g} success %']:.0f}" for r in seeds) for g in groups]
        lines.append(f"| {recipe} | {', '.join(str(r['train_seed']) for r in seeds)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_seed_tables(result: EvaluationResult, points: list[dict], out_dir: Path) -> None:
    """seeds.md and seeds.csv (seed_spread), and seeds/: the tables, stages and chart with each recipe's seeds
    pooled into one column (its episodes of every seed; intervals over the pooled episodes)."""
    rows = seed_spread(result, points)
    with written_whole(out_dir / "seeds.csv") as partial, open(partial, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    write_text_whole(out_dir / "seeds.md", seed_markdown(rows))
    recipe_of = {p["agent"]: p["recipe"] for p in points}
    config = dict(result.config, pooled_training_seeds=sorted({p["train_seed"] for p in points}))
    if "rnn_horizon" in config:
        config["rnn_horizon"] = {recipe_of.get(a, a): h for a, h in config["rnn_horizon"].items()}
    pooled = EvaluationResult(
        episodes=[replace(e, agent=recipe_of.get(e.agent, e.agent)) for e in result.episodes],
        agents=list(dict.fromkeys(recipe_of.get(a, a) for a in result.agents)),
        foods=result.foods,
        config=config,
    )
    pooled.write(str(out_dir / "seeds"))


def paired_comparison(result: EvaluationResult, first: str, second: str, points: list[dict] = ()) -> list[dict]:
    """
    ``second`` against ``first`` episode by episode on the same bowls, per group of foods (seen, unseen, overall):
    the pairs where only ``second`` succeeds (gained) and where only ``first`` does (lost), and the exact two-sided
    sign test of those (McNemar's exact test). Each bowl's difficulty cancels in a pair, so this separates two models
    that two overlapping intervals cannot. ``first`` and ``second`` are agents of ``result``, or both recipes of
    ``points`` (their training seeds paired seed by seed: seed 1 with seed 1, and so on).

    Raises:
        ValueError: [a name that is neither an agent nor a recipe, names with no training seed or episode in common]
    """
    from scipy.stats import binomtest  # heavy: scipy, only when comparing

    def agents_of(name: str) -> dict[int | None, str]:
        seeds = {p["train_seed"]: p["agent"] for p in points if p["recipe"] == name}
        if seeds:
            return seeds
        if name in result.agents:
            return {None: name}
        recipes = sorted({p["recipe"] for p in points})
        raise ValueError(f"{name!r} is neither an agent nor a recipe here; agents {result.agents}, recipes {recipes}")

    a, b = agents_of(first), agents_of(second)
    seeds = [s for s in a if s in b]
    if not seeds:
        raise ValueError(f"{first!r} and {second!r} have no training seed in common (seeds {list(a)} and {list(b)})")
    outcome = {(e.agent, e.food, e.episode): e.success for e in result.episodes}
    pairs = [
        (food, outcome[(a[s], food, i)], outcome[(b[s], food, i)])
        for s in seeds
        for (agent, food, i) in outcome
        if agent == a[s] and (b[s], food, i) in outcome
    ]
    if not pairs:
        raise ValueError(f"{first!r} and {second!r} have no episode in common")
    groups = [(g, set(foods)) for g, foods in food_groups(result.foods)] + [("overall", set(result.foods))]
    rows = []
    for group, foods in groups:
        chosen = [(x, y) for food, x, y in pairs if food in foods]
        if not chosen:
            continue
        gained, lost = sum(y and not x for x, y in chosen), sum(x and not y for x, y in chosen)
        rows.append(
            dict(
                group=group,
                pairs=len(chosen),
                first=sum(x for x, _ in chosen),
                second=sum(y for _, y in chosen),
                gained=gained,
                lost=lost,
                p=binomtest(gained, gained + lost).pvalue if gained + lost else 1.0,
            )
        )
    return rows


def paired_markdown(comparisons: list[tuple[str, str, list[dict]]]) -> str:
    """The paired comparisons (first, second, paired_comparison's rows) as one table."""
    lines = [
        "Episode by episode on the same bowls (training seeds paired seed by seed): successes of each model, the pairs "
        "only the second wins (gained) and only the first (lost), and the exact two-sided sign test of those",
        "",
        "| first | second | foods | pairs | first wins | second wins | gained | lost | p |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for first, second, rows in comparisons:
        for r in rows:
            p = f"{r['p']:.3f}" if r["p"] >= 0.001 else "< 0.001"
            lines.append(
                f"| {first} | {second} | {r['group']} | {r['pairs']} | {r['first']} | {r['second']} | {r['gained']} "
                f"| {r['lost']} | {p} |"
            )
    return "\n".join(lines) + "\n"


def _groups_by(rows: list[dict], keys: tuple[str, ...]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(r[k] for k in keys), []).append(r)
    return out


def _check_piles(episodes: list[EpisodeRecord], source: str, seen: dict[tuple, tuple[str, str]]) -> None:
    """Refuses an episode whose food, seed and physics ran on another settled pile in an episode already pooled
    (``seen``: (food, seed, physics) -> (pile, source)); records that name no pile are not compared."""
    for e in episodes:
        if not e.pile:
            continue
        first = seen.setdefault((e.food, e.seed, e.physics), (e.pile, source))
        if first[0] != e.pile:
            raise ValueError(
                f"{source} and {first[1]} ran {e.food}'s episode of seed {e.seed} on different settled piles "
                f"({e.pile} against {first[0]}: the code that builds the pile changed between them); their episodes "
                "are not comparable"
            )


def pool(choices: list[tuple[str, Path, str]]) -> tuple[EvaluationResult, list[dict]]:
    """
    The chosen agents (new name, results.json, agent there) with their episodes under their new names, and the seed
    points (agent, recipe, train_seed) of the names that carry a training seed ("<recipe> seed <n>").

    Raises:
        ValueError: [a name given twice, a file that is missing or not an evaluation's, an agent the file does not
            hold, evaluations that differ in a setting of SHARED_SETTINGS (named with both values), episodes of one
            food, seed and physics that ran on different settled piles (a code change between the evaluations)]
    """
    loaded: dict[Path, dict] = {}
    episodes: list[EpisodeRecord] = []
    agents: dict[str, str] = {}
    sources: dict[str, str] = {}
    rnn_horizons: dict[str, int] = {}
    hosts: dict[str, dict] = {}
    piles: dict[tuple, tuple[str, str]] = {}
    reference: tuple[Path, dict] | None = None
    for name, source, agent in choices:
        if name in agents:
            raise ValueError(f"the name {name!r} is given twice")
        if source not in loaded:
            if not source.is_file():
                raise ValueError(f"{source} not found (expected an evaluation's results.json)")
            try:
                loaded[source] = json.loads(source.read_text())
            except ValueError:
                raise ValueError(f"{source} is not an evaluation's results.json (not JSON)") from None
            if not isinstance(loaded[source], dict) or "config" not in loaded[source]:
                raise ValueError(f"{source} is not an evaluation's results.json (no config)")
        config = loaded[source]["config"]
        if reference is None:
            reference = (source, config)
        for key in SHARED_SETTINGS:
            if config.get(key) != reference[1].get(key):
                raise ValueError(
                    f"{source} and {reference[0]} differ in {key!r} "
                    f"({config.get(key)!r} against {reference[1].get(key)!r}); their episodes are not comparable"
                )
        known = config.get("agents", {})
        if agent not in known:
            raise ValueError(f"{source} has no agent {agent!r}; it has {sorted(known)}")
        agents[name] = known[agent]
        sources[name] = f"{source}:{agent}"
        if agent in config.get("rnn_horizon", {}):  # its LSTM's reset period, when the evaluation set it
            rnn_horizons[name] = config["rnn_horizon"][agent]
        scored_on = config.get("hosts", {}).get(agent) or config.get("host")
        if scored_on:  # the machine that scored it, where its evaluation recorded one
            hosts[name] = scored_on
        chosen = [
            replace(EpisodeRecord.from_dict(e, config.get("env_kwargs")), agent=name)
            for e in loaded[source]["episodes"]
            if e["agent"] == agent
        ]
        _check_piles(chosen, f"{source}:{agent}", piles)
        episodes += chosen
    config = {k: reference[1][k] for k in SHARED_SETTINGS if k in reference[1]}
    if rnn_horizons:
        config["rnn_horizon"] = rnn_horizons
    if hosts:
        config["hosts"] = hosts
    result = EvaluationResult(
        episodes=episodes,
        agents=list(agents),
        foods=list(config["foods"]),
        config=dict(config, agents=agents, pooled_from=sources),
    )
    points = []
    for name in agents:
        match = SEED_LABEL.match(name)
        if match:
            points.append(dict(agent=name, recipe=match["recipe"], train_seed=int(match["seed"])))
    return result, points
