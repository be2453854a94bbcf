"""
Console programs for ScoopGranular demonstration files (robomimic's HDF5 schema, see veragmil_suite.recording):
argument parsing, printing and exit codes around veragmil_suite.datasets.

    veragmil-dataset-info   demos, lengths, per-food counts, success rate, spillage, obs keys and shapes
    veragmil-merge          merge several files into one (demos renumbered, provenance kept per demo)
    veragmil-split          train/valid split with a ratio (robomimic's mask/train and mask/valid)
    veragmil-replay         replay demos to an mp4 from their states (or their actions, checking the states)
    veragmil-render-obs     re-render camera observations from the states, for other cameras or sizes
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from veragmil_suite.datasets import (
    clean_dataset,
    dataset_summary,
    merge_datasets,
    render_observations,
    replay_demos,
    split_dataset,
)
from veragmil_suite.recording import DatasetError
from veragmil_suite.rendering import use_headless_rendering
from veragmil_suite.scripts.cli import positive_int


def _fail(tool: str, error: Exception) -> int:
    print(f"{tool}: {error}", file=sys.stderr)
    return 2


# ---------------------------------------------------------------------------------------------------------------- #
# info                                                                                                             #
# ---------------------------------------------------------------------------------------------------------------- #


def _pct(x) -> str:
    return "n/a" if x is None else f"{100 * x:.0f}%"


def format_summary(s: dict, verbose: bool = False) -> str:
    """veragmil-dataset-info's text for one dataset_summary (``verbose``: a line per demo)."""
    env = s["env"]
    length = s["length_steps"]
    hz = env["control_freq"]
    lines = [
        f"{s['path']}: {s['demos']} demos, {s['transitions']} transitions ({s['duration_s']:.1f} s)",
        f"  env: {env['env_name']}, robot {env['robot']}, controller {env['controller']}, {hz:g} Hz, "
        f"horizon {env['horizon']}, cameras {env['cameras'] or 'none'}",
        f"  length: mean {length['mean']:.1f} steps ({length['mean'] / hz:.2f} s), min {length['min']}, "
        f"max {length['max']}",
        "  foods: " + ", ".join(f"{k} {v}" for k, v in sorted(s["foods"].items())),
        "  devices: " + ", ".join(f"{k} {v}" for k, v in sorted(s["devices"].items()))
        + "; operators: " + ", ".join(f"{k or '?'} {v}" for k, v in sorted(s["operators"].items())),
        f"  success: {_pct(s['success_rate'])} of demos; {s['attempts']} attempts logged, "
        f"{_pct(s['attempt_success_rate'])} successful (discarded ones included)",
        f"  spilled: {s['mean_grains_spilled']:.2f} pieces, {s['mean_spilled_cm3']:.3f} cm3 per demo; completion "
        + ("n/a" if s["mean_completion_time_s"] is None else f"{s['mean_completion_time_s']:.2f} s on success"),
        "  per food:   demos  success  spilled(pieces)  spilled(cm3)  time(s)",
    ]  # fmt: skip
    if env["env_kwargs_variants"]:  # demos recorded with other env_kwargs than the file's (another food, grain count)
        variants = (
            " ".join(f"{k}={v!r}" for k, v in variant["env_kwargs"].items()) + f" ({variant['demos']} demos)"
            for variant in env["env_kwargs_variants"]
        )
        lines.insert(4, "  env kwargs per demo: " + "; ".join(variants))
    for food, r in s["per_food"].items():
        t = "n/a" if r["mean_time_s"] is None else f"{r['mean_time_s']:.2f}"
        lines.append(
            f"    {food:<10}{r['demos']:>5}  {r['success']:>4}/{r['demos']:<3} {r['mean_spilled']:>10.2f}"
            f"  {r['mean_spilled_cm3']:>12.3f}  {t:>7}"
        )
    lines.append("  filter keys: " + ", ".join(f"{k} {v}" for k, v in sorted(s["filter_keys"].items())))
    if s.get("being_written"):
        lines.append("  BEING WRITTEN by another process: this is the file as of its last complete write")
    if s["interrupted_writes"]:
        lines.append(
            f"  INTERRUPTED WRITES (not part of the dataset): {', '.join(s['interrupted_writes'])}; each was a write "
            "cut short (killed, disk full or an I/O error): the episode it was writing is lost, every demo above is "
            "complete; veragmil-dataset-info --clean removes them"
        )
    for name, problems in s.get("problems", {}).items():
        lines.append(f"  FLAGGED {name}: {'; '.join(problems)}")
    for group in s["duplicates"]:
        lines.append(f"  DUPLICATES: {', '.join(group)} are the same episode (same start state and actions)")
    lines.append("  obs keys (per-step shape, dtype):")
    for key, (shape, dtype) in sorted(s["obs_keys"].items()):
        lines.append(f"    {key:<28}{str(tuple(shape)):<16}{dtype}")
    p = s["provenance"]
    versions = ", ".join(
        f"{k.replace('_version', '')} {p[k]}" for k in sorted(p) if k.endswith("_version") and p[k] != ""
    )
    lines.append(f"  made by: {p.get('writer', 'unknown writer')}; {versions}; {p.get('date', '')}")
    if verbose:
        lines.append("  demos:")
        for d in s["demo_list"]:
            ok = "?" if d["success"] is None else ("success" if d["success"] else "failure")
            lines.append(
                f"    {d['name']:<10}{d['steps']:>5} steps  {d['food']:<10}{d['device']:<11}{ok:<8}"
                f" spilled {d['grains_spilled']} ({d['spilled_volume_cm3']:.3f} cm3)"
                f"  time {d['completion_time_s']:.2f} s"
            )
    return "\n".join(lines)


def info_main(argv: list[str] | None = None) -> int:
    """veragmil-dataset-info: summarize demonstration files."""
    p = argparse.ArgumentParser(
        prog="veragmil-dataset-info", description="Summarize ScoopGranular demonstration files."
    )
    p.add_argument("datasets", nargs="+", help="HDF5 files")
    p.add_argument("--verbose", "-v", action="store_true", help="one line per demo")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--clean", action="store_true", help="remove what interrupted writes left (never a finished demo)")
    args = p.parse_args(argv)
    out = []
    for path in args.datasets:
        try:
            if args.clean:
                removed = clean_dataset(path)
                print(f"{path}: removed {', '.join(removed)}" if removed else f"{path}: nothing to clean")
            summary = dataset_summary(path)
        except DatasetError as e:
            return _fail("veragmil-dataset-info", e)
        if not args.verbose:
            summary.pop("demo_list")
        out.append(summary)
    if args.json:
        print(json.dumps(out if len(out) > 1 else out[0], indent=2, default=str))
    else:
        print("\n\n".join(format_summary(s, args.verbose) for s in out))
    return 0


# ---------------------------------------------------------------------------------------------------------------- #
# merge and split                                                                                                  #
# ---------------------------------------------------------------------------------------------------------------- #


def merge_main(argv: list[str] | None = None) -> int:
    """veragmil-merge: merge demonstration files into a new one."""
    p = argparse.ArgumentParser(
        prog="veragmil-merge",
        description="Merge ScoopGranular demonstration files into a new file (demos renumbered demo_0...; each "
        "keeps its food, device, operator and metrics; the attempt logs are joined; masks are redone).",
    )
    p.add_argument("inputs", nargs="+", help="HDF5 files to merge, in order")
    p.add_argument("--output", "-o", required=True, help="the merged file (must not exist unless --force)")
    p.add_argument("--valid-ratio", type=float, default=0.1, help="fraction of demos in mask/valid")
    p.add_argument("--force", action="store_true", help="overwrite --output")
    args = p.parse_args(argv)
    if Path(args.output).exists() and not args.force:
        return _fail("veragmil-merge", DatasetError(f"{args.output} exists (use --force to overwrite it)"))
    try:
        n = merge_datasets(args.inputs, args.output, args.valid_ratio)
    except DatasetError as e:
        return _fail("veragmil-merge", e)
    print(f"merged {n} demos from {len(args.inputs)} files into {args.output}")
    return 0


def split_main(argv: list[str] | None = None) -> int:
    """veragmil-split: redo the train/valid split."""
    p = argparse.ArgumentParser(
        prog="veragmil-split",
        description="Split a demonstration file into train and valid demos (robomimic's mask/train, mask/valid), "
        "in place.",
    )
    p.add_argument("dataset", help="HDF5 file")
    p.add_argument("--ratio", type=float, default=0.1, help="fraction of demos for validation")
    p.add_argument("--seed", type=int, default=0, help="seed of the shuffle")
    p.add_argument(
        "--filter-key", default=None, help="split only these demos (e.g. success, rice), into <key>_train/_valid"
    )
    args = p.parse_args(argv)
    try:
        n_train, n_valid = split_dataset(args.dataset, args.ratio, args.seed, args.filter_key)
    except DatasetError as e:
        return _fail("veragmil-split", e)
    prefix = f"{args.filter_key}_" if args.filter_key else ""
    print(f"{args.dataset}: mask/{prefix}train {n_train} demos, mask/{prefix}valid {n_valid} demos")
    return 0


# ---------------------------------------------------------------------------------------------------------------- #
# replay and re-rendering                                                                                          #
# ---------------------------------------------------------------------------------------------------------------- #


def replay_main(argv: list[str] | None = None) -> int:
    """veragmil-replay: replay demonstrations to a video."""
    p = argparse.ArgumentParser(
        prog="veragmil-replay",
        description="Replay demos of a ScoopGranular file to an mp4: from the recorded states (default), or by "
        "replaying the actions open loop from the first state, which also checks that replay reproduces the states.",
    )
    p.add_argument("dataset", help="HDF5 file")
    p.add_argument("--output", "-o", default=None, help="mp4 to write (all selected demos in sequence)")
    p.add_argument("--demos", nargs="+", default=None, help="demo names (default: all)")
    p.add_argument("--n", type=positive_int, default=None, help="only the first N selected demos")
    p.add_argument("--camera", default="agentview", help="camera to render (overhead, agentview, frontview, ...)")
    p.add_argument("--size", type=positive_int, nargs="+", default=[480, 640], metavar="PX", help="height [width]")
    p.add_argument("--fps", type=float, default=None, help="video frame rate (default: real time)")
    p.add_argument("--skip", type=positive_int, default=1, help="render every k-th step")
    p.add_argument("--use-actions", action="store_true", help="replay actions open loop and report the state error")
    args = p.parse_args(argv)
    if args.output is None and not args.use_actions:
        p.error("give --output (a video) and/or --use-actions (a replay check)")
    use_headless_rendering()
    height, width = (args.size * 2)[:2]
    try:
        results = replay_demos(
            args.dataset,
            args.output,
            args.demos,
            args.n,
            args.camera,
            height,
            width,
            args.fps,
            args.skip,
            args.use_actions,
        )
    except DatasetError as e:
        return _fail("veragmil-replay", e)
    for r in results:
        line = f"{r['demo']}: {r['steps']} steps"
        if "max_state_error" in r:
            exact = "exact" if r["max_state_error"] == 0.0 else "NOT exact"
            line += (
                f"; action replay {exact} (largest state error {r['max_state_error']:.3g}); "
                f"{'success' if r['success'] else 'failure'}, {r['grains_in_spoon']} grains in the spoon, "
                f"{r['grains_spilled']} spilled"
            )
        print(line)
    if args.output:
        print(f"wrote {args.output}")
    return 0 if all(r.get("max_state_error", 0.0) == 0.0 for r in results) else 1


def render_obs_main(argv: list[str] | None = None) -> int:
    """veragmil-render-obs: re-render camera observations from the states."""
    p = argparse.ArgumentParser(
        prog="veragmil-render-obs",
        description="Write a copy of a ScoopGranular dataset whose camera observations (<camera>_image, "
        "<camera>_depth) are re-rendered from the recorded states, for other cameras or image sizes.",
    )
    p.add_argument("dataset", help="HDF5 file")
    p.add_argument("--output", "-o", required=True, help="new HDF5 file")
    p.add_argument("--cameras", nargs="+", default=["overhead"], help="cameras to render")
    p.add_argument("--size", type=positive_int, nargs="+", default=[84], metavar="PX", help="height [width]")
    p.add_argument("--depth", action="store_true", help="also render <camera>_depth")
    p.add_argument("--demos", nargs="+", default=None, help="only these demos")
    p.add_argument("--force", action="store_true", help="overwrite --output")
    args = p.parse_args(argv)
    if Path(args.output).exists() and not args.force:
        return _fail("veragmil-render-obs", DatasetError(f"{args.output} exists (use --force to overwrite it)"))
    use_headless_rendering()
    height, width = (args.size * 2)[:2]
    try:
        n = render_observations(args.dataset, args.output, args.cameras, height, width, args.depth, args.demos)
    except DatasetError as e:
        return _fail("veragmil-render-obs", e)
    print(f"wrote {n} demos with {', '.join(args.cameras)} at {height}x{width} to {args.output}")
    return 0
