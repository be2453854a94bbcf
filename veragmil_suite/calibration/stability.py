"""Settled piles stay still: many piles per food settled as the task settles them, then watched at rest.

Each pile is a new draw of grain sizes and lattice (seeded), settled by veragmil_suite.environments.settling in its
standalone model (table, bowl, grains), then run a further ``watch_s`` seconds as the task runs it (island sleeping
at the task's tolerance; ``--sleep off`` for the physics alone), which must move no grain more than CREEP_LIMIT_M,
leave every grain inside the bowl and raise no physics error.

    python -m veragmil_suite.calibration.stability --foods rice --settles 100 \
        --jsonl results/calibration/stability.jsonl

Rows are appended per pile; a rerun skips the (food, physics, seed, sleeping) rows already in the file, so a long
run resumes.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from veragmil_suite.environments.settling import pile_model_xml, simulate_settling
from veragmil_suite.models.bowl import Bowl
from veragmil_suite.models.foods import FOODS
from veragmil_suite.models.grains import GrainPile
from veragmil_suite.models.scoop_task import GRAIN_SLEEP_TOLERANCE, PHYSICS_TIMESTEP_S, pile_solver_options
from veragmil_suite.utils import cli
from veragmil_suite.utils.whole_files import append_line, json_lines

CREEP_LIMIT_M = 5e-4  # a grain of a pile at rest moves less than this over the watch


def settle_and_watch(
    food: str, physics: str, seed: int, watch_s: float = 2.0, sleep_tolerance: float | None = None
) -> dict:
    """One pile of the default grain count: settle it, watch it, report its creep, escapes and errors.

    ``sleep_tolerance`` watches the pile as the task runs it, with MuJoCo's island sleeping at that tolerance; None
    watches the physics alone, where the contact solver's residual keeps a pile jiggling at about 0.3 mm/s.
    """
    spec = FOODS[food]
    pile = GrainPile(spec, spec.grain(physics).default_grains, np.random.default_rng(seed), physics=physics)
    bowl = Bowl(name="bowl")
    option = pile_solver_options(pile.grain, physics)
    xml = pile_model_xml(bowl, pile, option, PHYSICS_TIMESTEP_S)
    row = {"food": food, "physics": physics, "seed": seed, "sleep_tolerance": sleep_tolerance}
    start = time.perf_counter()
    try:
        settled = simulate_settling(xml, bowl, pile)
    except RuntimeError as e:
        return {**row, "error": str(e), "wall_s": time.perf_counter() - start}
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    bowl_adr = model.joint(bowl.joints[0]).qposadr[0]
    adr = np.array([model.joint(j).qposadr[0] for j in pile.joint_names])
    data.qpos[bowl_adr : bowl_adr + 7] = settled.bowl_qpos
    data.qpos[adr[:, None] + np.arange(7)] = settled.grain_qpos
    if sleep_tolerance is not None:
        model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
        model.opt.sleep_tolerance = sleep_tolerance
    mujoco.mj_forward(model, data)
    before = settled.grain_qpos[:, :3].copy()
    mujoco.mj_step(model, data, nstep=int(round(watch_s / model.opt.timestep)))
    after = data.qpos[adr[:, None] + np.arange(3)]
    rel = after[:, :2] - data.qpos[bowl_adr : bowl_adr + 2]
    escaped = int((np.hypot(rel[:, 0], rel[:, 1]) > min(bowl.shape.rim_semi_axes)).sum())
    creep = float(np.linalg.norm(after - before, axis=1).max()) if np.isfinite(after).all() else float("inf")
    return {
        **row,
        "error": "" if np.isfinite(after).all() else "non-finite state while watching",
        "settle_time_s": settled.settle_time_s,
        "settle_speed_m_s": settled.max_speed_m_s,
        "max_creep_m": creep,
        "escaped": escaped,
        "still": creep < CREEP_LIMIT_M and escaped == 0,
        "wall_s": time.perf_counter() - start,
    }


def build_parser() -> cli.Parser:
    parser = cli.Parser("python -m veragmil_suite.calibration.stability", description=__doc__)
    parser.add_argument("--foods", type=cli.ListOf(cli.food), default=list(FOODS), help="foods whose piles are watched")
    parser.add_argument("--physics", type=cli.physics, default="calibrated", help="the grains' physics")
    parser.add_argument("--settles", type=cli.count, default=100, help="piles per food")
    parser.add_argument(
        "--sleep",
        type=cli.Choice("sleeping", ("task", "off")),
        default="task",
        help=f"watch with the task's island sleeping (sleep_tolerance {GRAIN_SLEEP_TOLERANCE}) or with sleeping off",
    )
    parser.add_argument(
        "--jsonl",
        type=cli.OutputFile("JSON-lines file"),
        required=True,
        help="rows are appended here; a rerun resumes",
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Settles and watches the piles --jsonl does not hold yet, then counts each food's still piles."""
    args.jsonl = Path(args.jsonl)
    tolerance = GRAIN_SLEEP_TOLERANCE if args.sleep == "task" else None
    done = set()
    if args.jsonl.exists():
        for r in json_lines(args.jsonl):
            done.add((r["food"], r["physics"], r["seed"], r.get("sleep_tolerance")))
    for food in args.foods:
        for seed in range(args.settles):
            if (food, args.physics, seed, tolerance) in done:
                continue
            row = settle_and_watch(food, args.physics, seed, sleep_tolerance=tolerance)
            append_line(args.jsonl, json.dumps(row))
    rows = json_lines(args.jsonl)
    for food in args.foods:
        mine = [
            r
            for r in rows
            if r["food"] == food and r["physics"] == args.physics and r.get("sleep_tolerance") == tolerance
        ]
        still = sum(bool(r.get("still")) for r in mine)
        errors = sum(bool(r["error"]) for r in mine)
        creep = max((r.get("max_creep_m", 0.0) for r in mine), default=0.0)
        print(
            f"{food:<10} {args.physics}, sleeping {args.sleep}: {still}/{len(mine)} still, {errors} errors, "
            f"worst creep {creep * 1000:.2f} mm"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
