"""The paper's Tables II and III, the stage table, success intervals and the success chart, from episode records.

Table II: success % per food, grouped seen (training) / unseen, with per-group and overall averages (each food
weighs the same). Table III: spilled pieces (mean +- std over all episodes) and completion time. The paper reports
the time of successful runs, so a failure's time (its episode length, kept in episodes.csv) is left out of the
mean; with no success the cell is "-" (NaN in table.csv).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from veragmil_suite.environments.stages import SCOOP_STAGES
from veragmil_suite.environments.task_state import DEFAULT_SPILL_LIMIT
from veragmil_suite.evaluation.agents import MISSING, EpisodeRecord
from veragmil_suite.models.foods import PRE_CALIBRATION_PHYSICS, TRAINING_FOODS
from veragmil_suite.utils.whole_files import write_text_whole, written_whole

SEEN_LABEL = "seen (training)"
UNSEEN_LABEL = "unseen"
# 95% two-sided normal quantile, for the Wilson intervals of success rates
WILSON_Z = 1.959964


def wilson_interval(successes: int, n: int, z: float = WILSON_Z) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95% by default), as fractions; (nan, nan) for n = 0.

    Unlike the normal approximation it stays inside [0, 1] and is not empty at 0 or n successes, which 20
    episodes often give.
    """
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def summarize(episodes: list[EpisodeRecord]) -> dict[tuple[str, str], dict]:
    """Per (agent, food): success rate, spilled pieces mean and std (all episodes), completion time over successes."""
    out = {}
    for key in dict.fromkeys((e.agent, e.food) for e in episodes):
        rows = [e for e in episodes if (e.agent, e.food) == key]
        ok = [e for e in rows if e.success]
        spilled = np.array([e.grains_spilled for e in rows], dtype=float)
        times = np.array([e.completion_time_s for e in ok], dtype=float)
        out[key] = dict(
            agent=key[0],
            food=key[1],
            episodes=len(rows),
            successes=len(ok),
            success_rate=len(ok) / len(rows),
            success_ci95=wilson_interval(len(ok), len(rows)),
            grains_spilled_mean=float(spilled.mean()),
            grains_spilled_std=float(spilled.std()),
            spilled_volume_cm3_mean=float(np.mean([e.spilled_volume_cm3 for e in rows])),
            spilled_mass_g_mean=float(np.mean([e.spilled_mass_g for e in rows])),
            spoon_mass_g_mean=float(np.mean([e.spoon_mass_g for e in rows])),
            completion_time_s_mean=float(times.mean()) if ok else math.nan,
            completion_time_s_std=float(times.std()) if ok else math.nan,
            physics_errors=sum(bool(e.physics_error) for e in rows),
            physics=sorted({e.physics for e in rows}),
            spill_limit_of=sorted({e.spill_limit_of for e in rows}),
            stages={stage: sum(e.stage == stage for e in rows) for stage in _stage_columns(rows)},
        )
    return out


def _stage_columns(rows: list[EpisodeRecord]) -> list[str]:
    """SCOOP_STAGES, and "-" for recorded demos that predate stage labels (only when there are any)."""
    return [*SCOOP_STAGES] + ([MISSING] if any(r.stage not in SCOOP_STAGES for r in rows) else [])


def stage_table(summary: dict, agents: list[str], foods: list[str], fmt: str = "markdown") -> str:
    """
    Where episodes stopped: per agent and food, how many ended at each furthest stage (SCOOP_STAGES, "held" being
    success), as markdown or CSV.
    """
    columns = list(dict.fromkeys(c for s in summary.values() for c in s["stages"]))
    rows = [(a, f, summary[(a, f)]) for a in agents for f in foods if (a, f) in summary]
    if fmt == "csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["agent", "food", "episodes", *columns])
        for a, f, s in rows:
            writer.writerow([a, f, s["episodes"], *(s["stages"].get(c, 0) for c in columns)])
        return buf.getvalue()
    lines = [
        "Furthest stage reached (episodes per agent and food; 'held' is success)",
        "",
        "| agent | food | episodes | " + " | ".join(columns) + " |",
        "|---|---|---:|" + "---:|" * len(columns),
    ]
    for a, f, s in rows:
        counts = " | ".join(str(s["stages"].get(c, 0)) for c in columns)
        lines.append(f"| {a} | {f if f in TRAINING_FOODS else f + ' (unseen)'} | {s['episodes']} | {counts} |")
    return "\n".join(lines) + "\n"


def _mean(values: list[float]) -> float:
    values = [v for v in values if not math.isnan(v)]
    return float(np.mean(values)) if values else math.nan


def food_groups(foods: list[str]) -> list[tuple[str, list[str]]]:
    """``foods`` split into Table II's groups, seen (training) then unseen, each with its label; none left empty."""
    seen = [f for f in foods if f in TRAINING_FOODS]
    unseen = [f for f in foods if f not in TRAINING_FOODS]
    return [(label, group) for label, group in ((SEEN_LABEL, seen), (UNSEEN_LABEL, unseen)) if group]


def table_rows(summary: dict, agents: list[str], foods: list[str]) -> dict[str, list[dict]]:
    """
    Both tables as rows of numbers (NaN where an agent has no entry or no success): "table2" success % per food
    (with its successes and episodes), "table3" spilled pieces mean/std and completion time mean per food. Each
    group of foods is followed by its average row, and the overall average closes the table; averages weigh each
    food the same, and their successes and episodes are the group's totals.
    """
    table2, table3 = [], []
    per_group = food_groups(foods)
    for label, group in per_group:
        for food in group:
            s = {a: summary.get((a, food)) for a in agents}
            row = dict(group=label, food=food)
            for a in agents:
                row[a] = 100 * s[a]["success_rate"] if s[a] else math.nan
                row[f"{a} successes"] = s[a]["successes"] if s[a] else 0
                row[f"{a} episodes"] = s[a]["episodes"] if s[a] else 0
            table2.append(row)
            row = dict(group=label, food=food)
            for a in agents:
                row[f"{a} spilled"] = s[a]["grains_spilled_mean"] if s[a] else math.nan
                row[f"{a} spilled std"] = s[a]["grains_spilled_std"] if s[a] else math.nan
                row[f"{a} spilled g"] = s[a].get("spilled_mass_g_mean", math.nan) if s[a] else math.nan
                row[f"{a} carried g"] = s[a].get("spoon_mass_g_mean", math.nan) if s[a] else math.nan
                row[f"{a} time"] = s[a]["completion_time_s_mean"] if s[a] else math.nan
            table3.append(row)
        table2.append(_average_row(table2, label, group, f"{label} average"))
        table3.append(_average_row(table3, label, group, f"{label} average"))
    if len(per_group) > 1:
        table2.append(_average_row(table2, "all", foods, "overall average"))
        table3.append(_average_row(table3, "all", foods, "overall average"))
    return dict(table2=table2, table3=table3)


def _average_row(rows: list[dict], group: str, foods: list[str], label: str) -> dict:
    """Mean over the rows of ``foods``, a food without an entry (NaN) left out; no std (it would mix foods); counts
    (successes, episodes) summed."""
    food_rows = [r for r in rows if r["food"] in foods]
    row = dict(group=group, food=label)
    for c in (k for k in food_rows[0] if k not in ("group", "food")):
        if c.endswith((" successes", " episodes")):
            row[c] = sum(r[c] for r in food_rows)
        else:
            row[c] = math.nan if c.endswith(" std") else _mean([r[c] for r in food_rows])
    return row


def _ci_percent(row: dict, agent: str) -> tuple[float, float]:
    low, high = wilson_interval(row[f"{agent} successes"], row[f"{agent} episodes"])
    return 100 * low, 100 * high


def _rate_cell(row: dict, agent: str) -> str:
    """A success rate with its 95% Wilson interval, e.g. "70 (48-85)"."""
    if math.isnan(row[agent]):
        return MISSING
    low, high = _ci_percent(row, agent)
    return f"{row[agent]:.0f} ({low:.0f}-{high:.0f})"


def _fmt(value: float, digits: int = 1) -> str:
    return MISSING if value is None or math.isnan(value) else f"{value:.{digits}f}"


def markdown_tables(
    summary: dict, agents: list[str], foods: list[str], rnn_horizons: dict[str, int] | None = None
) -> str:
    """Tables II and III as markdown (the paper's layout: rows are foods, one column per agent), ending with what
    decided the episodes beside the agents: the physics, the spill limit and, where set, the recurrent agents'
    hidden-state reset period (``rnn_horizons``)."""
    tables = table_rows(summary, agents, foods)
    lines = [
        "Table II: success rate (%, 95% Wilson interval in brackets)",
        "",
        "| food | " + " | ".join(agents) + " |",
    ]
    lines.append("|---|" + "---:|" * len(agents))
    group = None
    for row in tables["table2"]:
        if row["group"] != group and row["group"] != "all":
            group = row["group"]
            lines.append(f"| **{group}** |" + " |" * len(agents))
        food = row["food"] if row["food"] in foods else f"*{row['food']}*"
        lines.append(f"| {food} | " + " | ".join(_rate_cell(row, a) for a in agents) + " |")
    lines += [
        "",
        "Table III: spillage (pieces, mean ± std over all episodes; grams, mean), food carried at the end (g, mean)"
        " and completion time (s, mean over successes)",
        "",
        "| food | "
        + " | ".join(f"{a} spillage | {a} spilled (g) | {a} carried (g) | {a} time (s)" for a in agents)
        + " |",
        "|---|" + "---:|---:|---:|---:|" * len(agents),
    ]
    group = None
    for row in tables["table3"]:
        if row["group"] != group and row["group"] != "all":
            group = row["group"]
            lines.append(f"| **{group}** |" + " | | | |" * len(agents))
        is_food = row["food"] in foods
        cells = []
        for a in agents:
            spilled = _fmt(row[f"{a} spilled"])
            if is_food and spilled != MISSING:
                spilled += f" ± {_fmt(row[f'{a} spilled std'])}"
            cells += [spilled, _fmt(row[f"{a} spilled g"], 2), _fmt(row[f"{a} carried g"], 2), _fmt(row[f"{a} time"])]
        lines.append(f"| {row['food'] if is_food else '*' + row['food'] + '*'} | " + " | ".join(cells) + " |")
    lines += ["", f"Physics (grain models, veragmil_suite.models.foods): {', '.join(physics_of(summary))}"]
    lines += [f"Spill limit of success (ScoopGranular's spill_limit_of): {', '.join(spill_limits_of(summary))}"]
    if rnn_horizons:
        every = ", ".join(f"{agent} {steps}" for agent, steps in rnn_horizons.items())
        lines += [f"RNN hidden state reset every N rollout steps (--rnn-horizon; others: their config's): {every}"]
    return "\n".join(lines) + "\n"


def _named_in(summary: dict, key: str, before: str) -> list[str]:
    """The values of a per-(agent, food) list ``key`` over a summary; ``before`` for summaries written without it."""
    return sorted({v for s in summary.values() for v in s.get(key, [before])})


def physics_of(summary: dict) -> list[str]:
    """The physics a summary's episodes ran on (summaries written before the choice ran on PRE_CALIBRATION_PHYSICS)."""
    return _named_in(summary, "physics", PRE_CALIBRATION_PHYSICS)


def spill_limits_of(summary: dict) -> list[str]:
    """What the success rule's spill limit was a fraction of in a summary's episodes (summaries written before the
    choice existed were scored under DEFAULT_SPILL_LIMIT)."""
    return _named_in(summary, "spill_limit_of", DEFAULT_SPILL_LIMIT)


def csv_tables(summary: dict, agents: list[str], foods: list[str]) -> str:
    """Tables II and III as one CSV: a table column, then group, food and one column per agent and metric."""
    tables = table_rows(summary, agents, foods)
    columns = ["group", "food"]
    columns += [f"{a} {m}" for a in agents for m in ("success %", "success % ci95 low", "success % ci95 high")]
    columns += [
        f"{a} {m}"
        for a in agents
        for m in ("spilled pieces mean", "spilled pieces std", "spilled g mean", "carried g mean", "time s mean")
    ]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for r2, r3 in zip(tables["table2"], tables["table3"]):
        values = [r2["group"], r2["food"]]
        for a in agents:
            low, high = _ci_percent(r2, a) if not math.isnan(r2[a]) else (math.nan, math.nan)
            values += [_csv_number(r2[a]), _csv_number(low), _csv_number(high)]
        for a in agents:
            values += [_csv_number(r3[f"{a} spilled"]), _csv_number(r3[f"{a} spilled std"])]
            values += [_csv_number(r3[f"{a} spilled g"]), _csv_number(r3[f"{a} carried g"])]
            values += [_csv_number(r3[f"{a} time"])]
        writer.writerow(values)
    return buf.getvalue()


def _csv_number(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.4g}"


def json_safe(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [json_safe(v) for v in value]
    return value


def plot_success(summary: dict, agents: list[str], foods: list[str], path: str) -> None:
    """Bar chart of success % per food: one group of bars per food, one bar per agent, with 95% Wilson intervals."""
    import matplotlib  # heavy: matplotlib, only when plotting

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # heavy: matplotlib, only when plotting

    width = 0.8 / max(1, len(agents))
    x = np.arange(len(foods))
    fig, ax = plt.subplots(figsize=(max(4.0, 1.2 * len(foods) + 1), 3.5))
    for i, agent in enumerate(agents):
        entries = [summary.get((agent, f)) for f in foods]
        rates = np.array([100 * e["success_rate"] if e else 0.0 for e in entries])
        bounds = np.array([100 * np.array(e["success_ci95"]) if e else (0.0, 0.0) for e in entries])
        # clipped: an interval's end at 0 or 100 can miss the rate by a rounding error, and matplotlib refuses < 0
        errors = np.clip(np.stack([rates - bounds[:, 0], bounds[:, 1] - rates]), 0.0, None)
        # as lists: a (2, 1) array (one food) takes a path of matplotlib's that NumPy deprecates (an error in NumPy 2)
        ax.bar(x + (i - (len(agents) - 1) / 2) * width, rates, width, label=agent, yerr=errors.tolist(), capsize=2)
    ax.set_xticks(x, [f if f in TRAINING_FOODS else f"{f}\n(unseen)" for f in foods])
    ax.set_ylabel("success (%, 95% CI)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize="small")
    fig.tight_layout()
    with written_whole(path, keep_suffix=True) as partial:
        fig.savefig(partial, dpi=100)
    plt.close(fig)


@dataclass
class EvaluationResult:
    """Every episode, the per (agent, food) summary, and the run's configuration."""

    episodes: list[EpisodeRecord]
    agents: list[str]
    foods: list[str]
    config: dict = field(default_factory=dict)
    summary: dict = field(init=False)

    def __post_init__(self):
        self.summary = summarize(self.episodes)

    def markdown(self) -> str:
        return markdown_tables(self.summary, self.agents, self.foods, self.config.get("rnn_horizon"))

    def stages_markdown(self) -> str:
        return stage_table(self.summary, self.agents, self.foods)

    def write(self, output_dir: str) -> dict[str, str]:
        """Writes episodes.csv, results.json, table.md, table.csv, stages.md, stages.csv and success.png; returns
        their paths."""
        out = Path(output_dir)
        out.mkdir(parents=True, exist_ok=True)
        names = ("episodes.csv", "results.json", "table.md", "table.csv", "stages.md", "stages.csv")
        paths = {name: str(out / name) for name in names}
        with written_whole(paths["episodes.csv"]) as partial, open(partial, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=EpisodeRecord.columns())
            writer.writeheader()
            writer.writerows(e.to_dict() for e in self.episodes)
        episodes = [e.to_dict() for e in self.episodes]
        config = {**self.config, "physics": physics_of(self.summary), "spill_limit_of": spill_limits_of(self.summary)}
        results = dict(config=config, summary=list(self.summary.values()), episodes=episodes)
        write_text_whole(paths["results.json"], json.dumps(json_safe(results), indent=2))
        write_text_whole(paths["table.md"], self.markdown())
        write_text_whole(paths["table.csv"], csv_tables(self.summary, self.agents, self.foods))
        write_text_whole(paths["stages.md"], self.stages_markdown())
        write_text_whole(paths["stages.csv"], stage_table(self.summary, self.agents, self.foods, fmt="csv"))
        paths["success.png"] = str(out / "success.png")
        plot_success(self.summary, self.agents, self.foods, paths["success.png"])
        for e in self.episodes:  # this run's videos only, not those an earlier run left in the folder
            video = out / "videos" / video_name(e.agent, e.food, e.episode)
            if e.episode < self.config.get("videos", 0) and video.is_file():
                paths[f"videos/{video.name}"] = str(video)
        return paths


def video_name(agent: str, food: str, episode: int) -> str:
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in agent)
    return f"{safe}_{food}_{episode}.mp4"
