"""
Console programs for ScoopGranular demonstration files (robomimic's HDF5 schema, see veragmil_suite.data.recording):
argument parsing, printing and exit codes around veragmil_suite.data.datasets.

    veragmil-dataset-info   demos, lengths, per-food counts, success rate, spillage, obs keys and shapes
    veragmil-merge          merge several files into one (demos renumbered, provenance kept per demo)
    veragmil-split          train/valid split with a ratio (robomimic's mask/train and mask/valid)
    veragmil-replay         replay demos to an mp4 from their states (or their actions, checking the states)
    veragmil-render-obs     re-render camera observations from the states, for other cameras or sizes
    veragmil-drop-noops     a copy without the steps whose action is a no-op (a teleoperator's pauses)
"""

from __future__ import annotations

import argparse
import json

from veragmil_suite.data.datasets import clean_dataset, dataset_summary, drop_noops, merge_datasets, split_dataset
from veragmil_suite.data.replay import render_observations, replay_demos
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command, refuse_existing
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.rendering import use_headless_rendering


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
            "cut short (killed, disk full or an I/O error): what it was writing (an episode, a merge, a copy) is lost, "
            "every demo above is complete; veragmil-dataset-info --clean or the file's next write removes them"
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


def build_info_parser() -> Parser:
    p = Parser("veragmil-dataset-info", description="Summarize ScoopGranular demonstration files.")
    p.add_input("dataset", "--dataset", cli.dataset, many=True, help="HDF5 files")
    p.add_argument("--verbose", "-v", action="store_true", help="one line per demo")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--clean", action="store_true", help="remove what interrupted writes left (never a finished demo)")
    return p


@command(build_info_parser)
def info_main(args: argparse.Namespace) -> int:
    """veragmil-dataset-info: summarize demonstration files."""
    out = []
    for path in args.dataset:
        if args.clean:
            removed = clean_dataset(path)
            print(f"{path}: removed {', '.join(removed)}" if removed else f"{path}: nothing to clean")
        summary = dataset_summary(path)
        if not args.verbose:
            summary.pop("demo_list")
        out.append(summary)
    if args.json:
        print(json.dumps(out if len(out) > 1 else out[0], indent=2, default=str))
    else:
        print("\n\n".join(format_summary(s, args.verbose) for s in out))
    return 0


def build_merge_parser() -> Parser:
    p = Parser(
        "veragmil-merge",
        description="Merge ScoopGranular demonstration files into a new file (demos renumbered demo_0...; each "
        "keeps its food, device, operator and metrics; the attempt logs are joined; masks are redone).",
    )
    p.add_input("inputs", "--dataset", cli.dataset, many=True, help="HDF5 files to merge, in order")
    p.add_argument(
        "--output", "-o", type=cli.output_dataset, required=True, help="the merged file (must not exist unless --force)"
    )
    p.add_argument("--valid-ratio", type=cli.fraction_below_one, default=0.1, help="fraction of demos in mask/valid")
    p.add_argument("--force", action="store_true", help="overwrite --output")
    return p


@command(build_merge_parser)
def merge_main(args: argparse.Namespace) -> int:
    """veragmil-merge: merge demonstration files into a new one."""
    refuse_existing(args.output, args.force)
    n = merge_datasets(args.inputs, args.output, args.valid_ratio)
    print(f"merged {n} demos from {len(args.inputs)} files into {args.output}")
    return 0


def build_split_parser() -> Parser:
    p = Parser(
        "veragmil-split",
        description="Split a demonstration file into train and valid demos (robomimic's mask/train, mask/valid), "
        "in place.",
    )
    p.add_input("dataset", "--dataset", cli.dataset, help="HDF5 file")
    p.add_argument(
        "--valid-ratio",
        aliases=["--ratio"],
        type=cli.fraction_below_one,
        default=0.1,
        help="fraction of demos for validation",
    )
    p.add_argument("--seed", type=cli.seed, default=0, help="seed of the shuffle")
    p.add_argument(
        "--filter-key",
        type=cli.text,
        default=None,
        help="split only these demos (e.g. success, rice), into <key>_train/_valid",
    )
    return p


@command(build_split_parser)
def split_main(args: argparse.Namespace) -> int:
    """veragmil-split: redo the train/valid split."""
    n_train, n_valid = split_dataset(args.dataset, args.valid_ratio, args.seed, args.filter_key)
    prefix = f"{args.filter_key}_" if args.filter_key else ""
    print(f"{args.dataset}: mask/{prefix}train {n_train} demos, mask/{prefix}valid {n_valid} demos")
    return 0


def build_replay_parser() -> Parser:
    p = Parser(
        "veragmil-replay",
        description="Replay demos of a ScoopGranular file to an mp4: from the recorded states (default), or by "
        "replaying the actions open loop from the first state, which also checks that replay reproduces the states.",
    )
    p.add_input("dataset", "--dataset", cli.dataset, help="HDF5 file")
    p.add_argument(
        "--output",
        "-o",
        aliases=["--video-path"],
        type=cli.output_video,
        default=None,
        help="video to write, all selected demos in sequence (must not exist unless --force)",
    )
    p.add_argument("--demos", type=cli.ListOf(cli.demo_name), default=None, help="demo names (default: all)")
    p.add_argument("--n", type=cli.count, default=None, help="only the first N selected demos")
    p.add_argument("--camera", type=cli.camera, default="agentview", help="camera to render")
    cli.add_image_size(p, 480, 640, old=["--size"])
    p.add_argument("--fps", type=cli.positive, default=None, help="video frame rate (default: real time)")
    p.add_argument("--video-skip", aliases=["--skip"], type=cli.count, default=1, help="render every k-th step")
    p.add_argument("--use-actions", action="store_true", help="replay actions open loop and report the state error")
    p.add_argument("--force", action="store_true", help="overwrite --output")
    return p


@command(build_replay_parser)
def replay_main(args: argparse.Namespace) -> int:
    """veragmil-replay: replay demonstrations to a video."""
    if args.output is None and not args.use_actions:
        raise UsageError("give --output (a video) and/or --use-actions (a replay check)")
    refuse_existing(args.output, args.force)
    use_headless_rendering()
    results = replay_demos(
        args.dataset,
        args.output,
        args.demos,
        args.n,
        args.camera,
        args.camera_height,
        args.camera_width,
        args.fps,
        args.video_skip,
        args.use_actions,
    )
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


def build_render_obs_parser() -> Parser:
    p = Parser(
        "veragmil-render-obs",
        description="Write a copy of a ScoopGranular dataset whose camera observations (<camera>_image, "
        "<camera>_depth) are re-rendered from the recorded states, for other cameras or image sizes.",
    )
    p.add_input("dataset", "--dataset", cli.dataset, help="HDF5 file")
    p.add_argument("--output", "-o", type=cli.output_dataset, required=True, help="new HDF5 file")
    p.add_argument(
        "--camera-names",
        aliases=["--cameras"],
        type=cli.ListOf(cli.camera),
        default=["overhead"],
        help="cameras to render",
    )
    cli.add_image_size(p, 84, 84, old=["--size"])
    p.add_argument("--depth", action="store_true", help="also render <camera>_depth")
    p.add_argument("--demos", type=cli.ListOf(cli.demo_name), default=None, help="only these demos")
    p.add_argument("--force", action="store_true", help="overwrite --output")
    return p


@command(build_render_obs_parser)
def render_obs_main(args: argparse.Namespace) -> int:
    """veragmil-render-obs: re-render camera observations from the states."""
    refuse_existing(args.output, args.force)
    use_headless_rendering()
    height, width = args.camera_height, args.camera_width
    n = render_observations(args.dataset, args.output, args.camera_names, height, width, args.depth, args.demos)
    print(f"wrote {n} demos with {', '.join(args.camera_names)} at {height}x{width} to {args.output}")
    return 0


def build_drop_noops_parser() -> Parser:
    p = Parser(
        "veragmil-drop-noops",
        description="Write a copy of a demonstration file without its no-op steps: the steps whose every action "
        "component is at most --threshold in magnitude (a teleoperator's released input). Policies trained on "
        "data with such pauses learn to stall; next_obs is joined up across the dropped steps, masks are kept.",
    )
    p.add_input("dataset", "--dataset", cli.dataset, help="HDF5 file")
    p.add_argument("--output", "-o", type=cli.output_dataset, required=True, help="new HDF5 file")
    p.add_argument(
        "--threshold",
        type=cli.fraction_below_one,
        default=0.0,
        help="largest action magnitude of a no-op, a fraction of full scale (default 0: exactly zero)",
    )
    p.add_argument(
        "--keep-held",
        action="store_true",
        help="keep the no-ops at which the task's success held (its reward is the env's reward_scale): the hold "
        "at the goal",
    )
    p.add_argument("--force", action="store_true", help="overwrite --output")
    return p


@command(build_drop_noops_parser)
def drop_noops_main(args: argparse.Namespace) -> int:
    """veragmil-drop-noops: copy a dataset without its no-op steps."""
    refuse_existing(args.output, args.force)
    demos, before, after, held = drop_noops(args.dataset, args.output, args.threshold, args.keep_held)
    dropped = before - after
    share = dropped / before if before else 0.0
    kept = f"; kept {held} at which the task's success held" if args.keep_held else ""
    print(f"wrote {demos} demos to {args.output}: dropped {dropped} no-op steps of {before} ({_pct(share)}){kept}")
    return 0
