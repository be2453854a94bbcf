"""
What one physics step of an awake pile costs under other MuJoCo settings than the task's: the constraint solver's
kind and effort, the friction cone, and the convex-collision flags. The pile is settled as the task settles it and
held still with sleeping off (every grain awake, as while the spoon is in it); each setting steps the same state.

A second table takes the physics step itself: the pile settled at each step, then left at rest (robot still,
sleeping off) for REST_S: the cost of a simulated second and how restless the pile stays (fastest and median grain
speed at the end, over two piles; the task's sleep tolerance is 3 mm/s).

Only cost and rest are shown here: whether a setting keeps the scoop what it is needs whole expert episodes
(``python -m veragmil_suite.scripts.measure_expert --solver KEY=VALUE``, ``--physics-timestep``).

    python results/awake_pile/bench_solvers.py                       # rice
    python results/awake_pile/bench_solvers.py --foods rice flakes --steps 24
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from veragmil_suite.models.foods import FOODS
from veragmil_suite.scripts.bench import make_env  # every grain awake: its sleep_tolerance is None

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
# physics steps of the second table (s), and how long each pile rests before its speeds are read
TIMESTEPS_S = (1 / 240, 1 / 200, 1 / 180, 1 / 160, 1 / 120)
REST_S = 2.0
REST_SEEDS = (0, 1)


def bench_steps(food: str) -> list[dict]:
    """Each TIMESTEPS_S: the pile settled at that step, at rest for REST_S; its cost per simulated second and its
    grains' speeds at the end (each REST_SEEDS draws another pile and bowl place)."""
    rows = []
    for timestep_s in TIMESTEPS_S:
        fastest, median, seconds = [], [], 0.0
        for seed in REST_SEEDS:
            env = make_env(food, seed=seed, pile_variants=4, physics_timestep_s=timestep_s)
            env.reset()
            action = np.zeros(env.action_dim)
            steps = int(round(REST_S * env.control_freq))
            t = time.perf_counter()
            for _ in range(steps):
                env.step(action)
            seconds += time.perf_counter() - t
            speed = np.linalg.norm(env.sim.data.qvel[env.grain_qvel_adr[:, None] + np.arange(3)], axis=1)
            fastest.append(1000 * float(speed.max()))
            median.append(1000 * float(np.median(speed)))
            env.close()
        rows.append(
            dict(
                label=f"1/{1 / timestep_s:.0f} s",
                ms_per_sim_s=1000 * seconds / (REST_S * len(REST_SEEDS)),
                fastest_mm_s=fastest,
                median_mm_s=median,
            )
        )
    return rows


def bench_food(food: str, steps: int) -> list[dict]:
    """Each SETTINGS row stepped ``steps`` physics steps from the same settled, awake pile."""
    env = make_env(food)
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
        rows = bench_steps(food)
        base = rows[0]["ms_per_sim_s"]
        print(f"\n{food}: physics steps, the pile settled at each and at rest for {REST_S:g} s (sleeping off)")
        print(f"{'step':<12} {'ms per simulated s':>19} {'vs 1/240':>9}   fastest grain (mm/s)   median grain (mm/s)")
        for r in rows:
            fastest = ", ".join(f"{v:.2f}" for v in r["fastest_mm_s"])
            median = ", ".join(f"{v:.3f}" for v in r["median_mm_s"])
            print(
                f"{r['label']:<12} {r['ms_per_sim_s']:>19.0f} {base / r['ms_per_sim_s']:>8.2f}x   "
                f"{fastest:<22} {median}",
                flush=True,
            )


if __name__ == "__main__":
    main()
