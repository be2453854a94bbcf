"""Publishing a study: its tables and records copied into results/ with how they were made (the command, the host,
the package versions and the wall times of the pieces behind its models). Datasets and checkpoints stay behind: the
command regenerates them."""

from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path

from veragmil_suite.utils.host import host
from veragmil_suite.utils.whole_files import write_text_whole, write_whole

# what a study's eval/ folder holds that results/ keeps
EVAL_FILES = (
    "table.md",
    "table.csv",
    "stages.md",
    "stages.csv",
    "results.json",
    "episodes.csv",
    "success.png",
    "curves.csv",
    "curves.png",
    "seeds.md",
    "seeds.csv",
    # each recipe's training seeds pooled (its per-episode records are those of the seeds above)
    "seeds/table.md",
    "seeds/table.csv",
    "seeds/stages.md",
    "seeds/stages.csv",
    "seeds/success.png",
)


def own_timings(timings: dict[str, float], agents: dict[str, str]) -> dict[str, float]:
    """The pieces behind ``agents``: their training runs, the recording of each dataset they trained on, and the
    evaluation. A study's timings.json keeps every piece its output directory ever ran, most of them another
    evaluation's. A pooled study's timings (veragmil-pool-results of several) name each evaluation it joins
    ("evaluate (seeds 2-3)")."""
    # a checkpoint lies at <runs>/<run name>/<timestamp>/models/<file>; an operator ("expert:expert") is no path
    runs = {Path(spec).parents[2].name for spec in agents.values() if Path(spec).suffix == ".pth"}
    kept = {}
    for key, seconds in timings.items():
        kind, _, name = key.partition(" ")
        if (
            kind == "evaluate"
            or (kind == "train" and name in runs)
            or (kind == "record" and any(run.startswith(f"{name}_") for run in runs))
        ):
            kept[key] = seconds
    return kept


def _study_folder(results_json: Path) -> Path:
    """The folder of the run that wrote ``results_json``: a study's, above its eval/; else the file's own."""
    return results_json.parent.parent if results_json.parent.name == "eval" else results_json.parent


def study_timings(results_json: Path) -> dict[str, float]:
    """The wall times of the run that wrote ``results_json``: the timings.json beside it (a pooled evaluation's, a
    published results/ folder's) or in the study folder above its eval/ (a study's); empty when neither is there (a
    folder published before publish kept them), so a pool of published folders keeps the times behind its agents."""
    for folder in dict.fromkeys([results_json.parent, _study_folder(results_json)]):
        if (folder / "timings.json").is_file():
            return json.loads((folder / "timings.json").read_text())
    return {}


def pooled_timings(config: dict) -> dict[str, float]:
    """
    The pieces behind a pooled evaluation's agents (its config's ``pooled_from`` and ``agents``): each source's own
    timings for the agents taken from it. Each source's evaluation, and a piece two sources time differently, carry
    the source's folder ("evaluate (runs/bc_seeds_2_3)"), so the pool's timings.json says which run took how long.
    """
    by_source: dict[Path, dict[str, str]] = {}
    for name, origin in config.get("pooled_from", {}).items():
        by_source.setdefault(Path(origin.rpartition(":")[0]), {})[name] = config["agents"][name]
    pieces = {source: own_timings(study_timings(source), agents) for source, agents in by_source.items()}
    # how many different times each piece has across the sources
    times = Counter(key for key, _ in {(key, s) for piece in pieces.values() for key, s in piece.items()})
    merged: dict[str, float] = {}
    for source, piece in pieces.items():
        for key, seconds in piece.items():
            named = key == "evaluate" or times[key] > 1
            merged[f"{key} ({_study_folder(source)})" if named else key] = seconds
    return merged


def _described(machine: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in machine.items())


def host_lines(config: dict) -> list[str]:
    """Where the evaluation's episodes were scored: its own ``host``, or a pool's ``hosts`` by agent, each machine
    with the agents it scored when they differ (a results/ folder pooled from seeds scored on two kinds of CPU names
    both). Evaluations from before results recorded a host name this machine, which published them, and say so."""
    agents = list(config.get("agents", {}))
    if config.get("host"):
        return ["Host: " + _described(config["host"])]
    scored = config.get("hosts", {})
    by_machine: dict[str, list[str]] = {}
    for agent in agents:
        if agent in scored:
            by_machine.setdefault(_described(scored[agent]), []).append(agent)
    if not by_machine:
        return [
            "Host: " + _described(host()) + " (this machine, which published the folder: its evaluation recorded none)"
        ]
    unknown = [agent for agent in agents if agent not in scored]
    if unknown:
        by_machine["not recorded (scored before evaluations recorded their host)"] = unknown
    if len(by_machine) == 1:
        return ["Host: " + next(iter(by_machine))]
    return ["Hosts (the machines that scored each model's episodes):", ""] + [
        f"- {machine}: {', '.join(names)}" for machine, names in by_machine.items()
    ]


def publish(study_dir: Path, dest: Path, command: str) -> list[str]:
    """
    Copies the study's eval outputs and timings to ``dest`` and writes RUN.md; returns the files written.

    Raises:
        ValueError: [``study_dir`` holds no finished evaluation]
    """
    eval_dir = study_dir / "eval"
    if not (eval_dir / "results.json").is_file():
        raise ValueError(f"{eval_dir}/results.json not found: is {study_dir} a finished study?")
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for name in EVAL_FILES:
        if (eval_dir / name).is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            write_whole(dest / name, lambda partial, name=name: shutil.copy2(eval_dir / name, partial))
            written.append(name)
    timings = study_timings(eval_dir / "results.json")
    config = json.loads((eval_dir / "results.json").read_text())["config"]
    timings = own_timings(timings, config.get("agents", {}))
    if timings:  # beside results.json, where a later pool of this folder finds them (study_timings)
        write_text_whole(dest / "timings.json", json.dumps(timings, indent=2) + "\n")
        written.append("timings.json")
    lines = [
        f"# {dest.name}",
        "",
        "Made with:",
        "",
        "```bash",
        command,
        "```",
        "",
        *host_lines(config),
        "",
        "Versions: " + _described(config.get("versions", {})),
        "",
        "Evaluation: "
        + ", ".join(f"{k} {config[k]}" for k in ("episodes", "seed", "horizon", "success_hold_s") if k in config),
        "",
        "Wall times (s, each piece timed where it ran; the pieces behind this folder's models: their training, the"
        " recording of their data, the evaluation; a piece a study skipped keeps the time of the run that performed"
        " it, and the evaluation sums the runs that added episodes to it):",
        "",
        "| piece | seconds |",
        "|---|---:|",
        *(f"| {k} | {v} |" for k, v in timings.items()),
        "",
    ]
    write_text_whole(dest / "RUN.md", "\n".join(lines))
    return [*written, "RUN.md"]
