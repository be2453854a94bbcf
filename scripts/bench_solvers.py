"""
What one physics step of an awake pile costs under other MuJoCo settings than the task's: the constraint solver's
kind and effort, the friction cone, and the convex-collision flags. The pile is settled as the task settles it and
held still with sleeping off (every grain awake, as while the spoon is in it); each setting steps the same state.

Only the cost is shown here: whether a setting keeps the scoop what it is needs whole expert episodes
(``python -m veragmil_suite.scripts.measure_expert --solver KEY=VALUE``, ``--physics-timestep``).

    python scripts/bench_solvers.py                       # rice
    python scripts/bench_solvers.py --foods rice flakes --steps 24
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import robosuite

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.foods import FOODS

# (label, MuJoCo option attributes changed from the task's); the first row is the task's own
SETTINGS = (
    ("task's: CG, 30 iterations, elliptic cone", {}),
    ("Newton", {"solver": mujoco.mjtSolver.mjSOL_NEWTON}),
    ("PGS", {"solver": mujoco.mjtSolver.mjSOL_PGS}),
    ("pyramidal cone", {"cone": mujoco.mjtCone.mjCONE_PYRAMIDAL}),
    ("multi-contact CCD off", {"disableflags": mujoco.mjtDisableBit.mjDSBL_MULTICCD}),
    ("libccd instead of native CCD", {"disableflags": mujoco.mjtDisableBit.mjDSBL_NATIVECCD}),
)
COLLISION_TIMER = mujoco.mjtTimer.mjTIMER_POS_COLLISION


def bench_food(food: str, steps: int) -> list[dict]:
    """Each SETTINGS row stepped ``steps`` physics steps from the same settled, awake pile."""
    env = robosuite.make(
        "ScoopGranular",
        robots="XArm7",
        food=food,
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        pile_variants=1,
        seed=0,
        sleep_tolerance=None,
    )
    env.reset()
    model, data = env.sim.model._model, env.sim.data._data
    start = (data.qpos.copy(), data.qvel.copy(), data.qacc_warmstart.copy(), data.time)
    task_options = {key: getattr(model.opt, key) for key in ("solver", "cone", "disableflags")}
    rows = []
    for label, options in SETTINGS:
        for key, value in task_options.items():
            setattr(model.opt, key, value)
        for key, value in options.items():
            setattr(model.opt, key, value | task_options[key] if key == "disableflags" else value)
        data.qpos[:], data.qvel[:], data.qacc_warmstart[:], data.time = start
        mujoco.mj_forward(model, data)
        collide_before = data.timer[COLLISION_TIMER].duration
        t = time.perf_counter()
        mujoco.mj_step(model, data, nstep=steps)
        seconds = (time.perf_counter() - t) / steps
        speed = np.linalg.norm(data.cvel[env.grain_body_ids, 3:], axis=1).max()
        rows.append(
            dict(
                label=label,
                ms=1000 * seconds,
                collide_ms=1000 * (data.timer[COLLISION_TIMER].duration - collide_before) / steps,
                contacts=int(data.ncon),
                iterations=int(data.solver_niter[0]),
                fastest_grain_mm_s=1000 * float(speed),
            )
        )
    env.close()
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--foods", nargs="+", choices=list(FOODS), default=["rice"], metavar="FOOD")
    parser.add_argument("--steps", type=int, default=24, help="physics steps timed per setting (24: 0.1 s)")
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error(f"--steps must be a positive integer, got {args.steps}")
    for food in args.foods:
        rows = bench_food(food, args.steps)
        base = rows[0]["ms"]
        print(f"\n{food}: a settled pile, every grain awake, {args.steps} physics steps per setting")
        columns = ("ms/step", "vs task", "collide", "contacts", "iters", "fastest")
        print(f"{'setting':<42}" + "".join(f" {c:>8}" for c in columns))
        for r in rows:
            print(
                f"{r['label']:<42} {r['ms']:>8.2f} {r['ms'] / base:>7.2f}x {r['collide_ms']:>8.2f} {r['contacts']:>8} "
                f"{r['iterations']:>8} {r['fastest_grain_mm_s']:>4.1f} mm/s",
                flush=True,
            )


if __name__ == "__main__":
    main()
