"""
Measure the scripted expert: success, spillage and completion time per food, over seeded episodes run as
veragmil-collect records them (restart from reset_to, observations of the recorded states), nothing written.
Episode s is a fresh environment made with seed s, so its bowl is not that of veragmil-collect's attempt of seed s
(an environment reset with that seed).

    python -m veragmil_suite.scripts.measure_expert --foods rice buckwheat barley pasta --episodes 10 --processes 2
    python -m veragmil_suite.scripts.measure_expert --robots G1FixedLowerBody --episodes 10 --processes 1
    python -m veragmil_suite.scripts.measure_expert --sleep-tolerance none --json before.json
    python -m veragmil_suite.scripts.measure_expert --compare before.json after.json
    python -m veragmil_suite.scripts.measure_expert --solver iterations=20 --json cg20.json
    python -m veragmil_suite.scripts.measure_expert --physics-timestep 1/160 --json dt160.json
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import sys
import time

import numpy as np
import robosuite

from veragmil_suite.data.recording import EpisodeRecorder, episode_metrics
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.environments.episode import SUCCESS_HOLD_S, run_until_done
from veragmil_suite.models.foods import TRAINING_FOODS
from veragmil_suite.models.scoop_task import (
    GRAIN_SLEEP_TOLERANCE,
    PHYSICS_TIMESTEP_S,
)
from veragmil_suite.utils import cli
from veragmil_suite.utils.distributed import run_pieces
from veragmil_suite.utils.numbers import seed_span_problem
from veragmil_suite.utils.rendering import use_headless_rendering
from veragmil_suite.utils.whole_files import written_whole


def run_expert_episode(
    food: str,
    seed: int,
    profile: str = "expert",
    success_hold_s: float = SUCCESS_HOLD_S,
    env_kwargs: dict | None = None,
    robot: str = "XArm7",
) -> dict:
    """One scripted episode of ``food`` with env and expert seeded by ``seed``; returns its metrics."""
    use_headless_rendering()
    import veragmil_suite  # noqa: F401  (registers ScoopGranular in a worker; the package imports this module)

    kwargs = dict(
        robots=robot, food=food, has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False, seed=seed
    )
    kwargs.update(env_kwargs or {})
    env = robosuite.make("ScoopGranular", **kwargs)
    expert = ScriptedScooper(env, profile, seed=seed)
    recorder = EpisodeRecorder(env)
    start = time.perf_counter()
    obs = recorder.reset()
    end = run_until_done(
        expert.agent,
        recorder.step,
        obs,
        env.control_freq,
        env.horizon,
        success_hold_s=success_hold_s,
    )
    env.close()
    out = episode_metrics(end.info, end.stage)
    out.update(
        food=food,
        seed=seed,
        profile=profile,
        robot=kwargs["robots"],
        steps=recorder.num_steps,
        end_reason=end.reason,
        peak_grains_in_spoon=end.peak_grains_in_spoon,
        wall_s=time.perf_counter() - start,
    )
    return out


def _episode_piece(context: tuple[str, str, dict], piece: tuple[str, int]) -> dict:
    """run_expert_episode as a piece of veragmil_suite.utils.distributed: (food, seed) of context's (profile, robot,
    env_kwargs)."""
    profile, robot, env_kwargs = context
    food, seed = piece
    return run_expert_episode(food, seed, profile, env_kwargs=env_kwargs, robot=robot)


def _label(run: dict) -> str:
    """A --json run's name in --compare: its MuJoCo, sleep tolerance, physics step and solver overrides."""
    solver = "".join(f", {k}={v}" for k, v in (run.get("solver") or {}).items())
    # a run that names no physics step ran at the task's default, 1/240 s
    step = f", step 1/{1 / run.get('physics_timestep_s', PHYSICS_TIMESTEP_S):.0f} s"
    return f"mujoco {run.get('mujoco', '?')}, sleep {run.get('sleep_tolerance') or 'off'}{step}{solver}"


def summarize(results: list[dict]) -> dict:
    """Per food: success rate, spilled pieces and volume, spill fraction, completion time (successes)."""
    out = {}
    for food in dict.fromkeys(r["food"] for r in results):
        rows = [r for r in results if r["food"] == food]
        ok = [r for r in rows if r["success"]]
        out[food] = dict(
            episodes=len(rows),
            success_rate=len(ok) / len(rows),
            mean_grains_spilled=float(np.mean([r["grains_spilled"] for r in rows])),
            mean_spilled_cm3=float(np.mean([r["spilled_volume_cm3"] for r in rows])),
            mean_spill_fraction=float(np.mean([r["spill_fraction"] for r in rows])),
            mean_grains_in_spoon=float(np.mean([r["grains_in_spoon"] for r in rows])),
            std_grains_in_spoon=float(np.std([r["grains_in_spoon"] for r in rows])),
            mean_completion_time_s=float(np.mean([r["completion_time_s"] for r in ok])) if ok else None,
            failures={r["seed"]: r["end_reason"] for r in rows if not r["success"]},
        )
    return out


def compare(paths: list[str]) -> str:
    """A markdown table of several --json runs side by side (per food: successes, load mean +- std, spilled pieces,
    time of successes), then each run's load against the first's on the seeds both ran (mean difference, how many
    seeds gave the same load): a paired view, since seed s has the same bowl and pile in every run."""
    runs = []
    for path in paths:
        with open(path) as f:
            runs.append(json.load(f))
    label = [_label(r) for r in runs]
    lines = ["| food | " + " | ".join(label) + " |", "|---|" + "---|" * len(runs)]
    foods = list(dict.fromkeys(e["food"] for r in runs for e in r["episodes"]))
    by_seed = [{(e["food"], e["seed"]): e for e in r["episodes"]} for r in runs]
    for food in foods:
        cells = []
        for r in runs:
            eps = [e for e in r["episodes"] if e["food"] == food]
            if not eps:
                cells.append("not run")
                continue
            load = np.array([e["grains_in_spoon"] for e in eps])
            times = [e["completion_time_s"] for e in eps if e["success"]]
            rate = sum(e["steps"] for e in eps) / sum(e["wall_s"] for e in eps) if "wall_s" in eps[0] else float("nan")
            spilled = np.mean([e["grains_spilled"] for e in eps])
            cells.append(
                f"{sum(e['success'] for e in eps)}/{len(eps)}, {load.mean():.1f} +- {load.std():.1f}, "
                f"{spilled:.1f}, {np.mean(times) if times else float('nan'):.2f} s, {rate:.1f}/s"
            )
        lines.append(f"| {food} | " + " | ".join(cells) + " |")
    lines.append(
        "\n(cells: successes, grains in the spoon at the end, spilled pieces, seconds to success, env steps per "
        "second of wall time over the episodes, resets included)\n"
    )
    for name, seeds in zip(label[1:], by_seed[1:]):
        parts = []
        for food in foods:
            diffs = [
                seeds[k]["grains_in_spoon"] - e["grains_in_spoon"]
                for k, e in by_seed[0].items()
                if k[0] == food and k in seeds
            ]
            if diffs:
                same = sum(d == 0 for d in diffs)
                parts.append(f"{food} {np.mean(diffs):+.1f} (same load {same}/{len(diffs)})")
        lines.append(f"- {name} against {label[0]}: " + "; ".join(parts))
    return "\n".join(lines)


def _measured_run(path: str) -> None:
    """Refuses a file --compare cannot read: not JSON, or without the episodes --json writes."""
    with open(path) as f:
        run = json.load(f)
    if not isinstance(run, dict) or not isinstance(run.get("episodes"), list):
        raise ValueError("no list of episodes, as --json writes them")


def build_parser() -> cli.Parser:
    parser = cli.Parser("python -m veragmil_suite.scripts.measure_expert", description=__doc__)
    parser.add_argument("--foods", type=cli.ListOf(cli.food), default=list(TRAINING_FOODS), help="foods measured")
    parser.add_argument("--episodes", type=cli.count, default=10, help="episodes per food (seeds SEED...)")
    parser.add_argument("--seed", aliases=["--first-seed"], type=cli.seed, default=0, help="the first episode's seed")
    parser.add_argument("--profile", type=cli.profile, default="expert", help="the scripted operator's profile")
    parser.add_argument(
        "--robots",
        aliases=["--robot"],
        type=cli.robot,
        default="XArm7",
        help="robosuite robot (G1FixedLowerBody: see veragmil_suite.models.humanoid)",
    )
    parser.add_argument(
        "--processes", aliases=["--workers"], type=cli.count, default=os.cpu_count() or 1, help="worker processes"
    )
    parser.add_argument(
        "--sleep-tolerance",
        type=cli.Real(0.0, open_low=True, none="none"),
        default=GRAIN_SLEEP_TOLERANCE,
        help="MuJoCo's sleep_tolerance for the grains, or none: sleeping off",
    )
    parser.add_argument(
        "--solver",
        type=cli.solver_option,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"override a MuJoCo solver option of the task (repeat for more): {cli.solver_option.accepted}",
    )
    parser.add_argument(
        "--physics-timestep",
        type=cli.physics_timestep,
        default=PHYSICS_TIMESTEP_S,
        metavar="SECONDS",
        help="the task's physics step, e.g. 1/200 (default 1/240; the pile is settled at it)",
    )
    parser.add_argument(
        "--json", type=cli.OutputFile("JSON file"), help="also write every episode and the summary to this file"
    )
    parser.add_argument("--force", action="store_true", help="overwrite the --json file if it exists")
    parser.add_argument(
        "--compare",
        nargs="+",
        type=cli.InputFile("--json file of this program", check=_measured_run),
        metavar="JSON",
        help="print earlier --json runs side by side, run nothing",
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """The episodes of every food, a line each, then the summary table (and --json); or --compare's table."""
    if args.compare:
        print(compare(args.compare))
        return 0
    cli.refuse_existing(args.json, args.force)
    problem = seed_span_problem(args.seed, args.episodes)
    if problem:
        raise cli.UsageError(problem)
    jobs = [(f, s) for s in range(args.seed, args.seed + args.episodes) for f in args.foods]
    results = []
    solver = dict(args.solver)
    env_kwargs = dict(sleep_tolerance=args.sleep_tolerance, physics_solver_options=solver or None)
    if args.physics_timestep != PHYSICS_TIMESTEP_S:
        env_kwargs["physics_timestep_s"] = args.physics_timestep
    context = (args.profile, args.robots, env_kwargs)
    pieces = run_pieces(_episode_piece, jobs, context=context, processes=args.processes, ordered=True)
    for _, r in pieces:
        results.append(r)
        print(
            f"{r['food']:<10} seed {r['seed']:<3} {'SUCCESS' if r['success'] else 'failure':<8} "
            f"{r['end_reason']:<8} {r['steps']:>4} steps  in spoon {r['grains_in_spoon']:>3} "
            f"(peak {r['peak_grains_in_spoon']})  spilled {r['grains_spilled']} ({100 * r['spill_fraction']:.1f}%)"
            f"  time {r['completion_time_s']:.2f} s",
            flush=True,
        )
    summary = summarize(results)
    print(
        f"\n{args.robots}, profile {args.profile}, {args.episodes} episodes per food, sleep {args.sleep_tolerance}, "
        f"physics step {args.physics_timestep:.6g} s" + "".join(f", {k}={v}" for k, v in solver.items())
    )
    print("food        success  spilled(pieces)  spilled(cm3)  spill%      in spoon  time(s)")
    for food, s in summary.items():
        t = "n/a" if s["mean_completion_time_s"] is None else f"{s['mean_completion_time_s']:.2f}"
        print(
            f"{food:<10} {100 * s['success_rate']:>6.0f}%  {s['mean_grains_spilled']:>15.2f}"
            f"  {s['mean_spilled_cm3']:>12.3f}"
            f"  {100 * s['mean_spill_fraction']:>5.1f}"
            f"  {s['mean_grains_in_spoon']:>6.1f} +-{s['std_grains_in_spoon']:>4.1f}  {t:>7}"
        )
    if args.json:
        with written_whole(args.json) as partial, open(partial, "w") as f:
            json.dump(
                dict(
                    robot=args.robots,
                    profile=args.profile,
                    sleep_tolerance=args.sleep_tolerance,
                    solver=solver,
                    physics_timestep_s=args.physics_timestep,
                    mujoco=importlib.metadata.version("mujoco"),
                    episodes=results,
                    summary=summary,
                ),
                f,
                indent=2,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
