"""Speed of ScoopGranular: env steps/s and real-time factor per food, against robosuite's Lift and bare MuJoCo.

    python -m veragmil_suite.bench                    # every food, 1x/2x/4x its default grain count
    python -m veragmil_suite.bench --foods rice --scales 1 --steps 40
    python -m veragmil_suite.bench --robot XArm7,G1FixedLowerBody --foods rice --scales 1   # robots side by side

Real time at 20 Hz control is 20 env steps/s (RTF 1.0). "bare mj_step" steps the same compiled scene with no
controller and no robosuite, so env/bare shows what robosuite's Python costs; "vs Lift" compares with robosuite's
Lift task on the same robot (the G1 with robosuite's default two-arm controller and hands). The robot holds still
(zero delta actions), the pile at rest: the steady state of most of an episode. Run on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import robosuite

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.foods import FOODS, TRAINING_FOODS
from veragmil_suite.humanoid import check_robot

REAL_TIME_STEPS_PER_S = 20.0  # the default 20 Hz control rate
AIM_RTF = 2.0  # the environment issue's aim: twice real time...
AIM_VS_LIFT = 0.8  # ...and 0.8x robosuite's Lift on the same robot


def _env_rate(env, steps: int) -> float:
    env.reset()
    action = np.zeros(env.action_dim)
    env.step(action)  # first step pays one-off costs
    start = time.perf_counter()
    for _ in range(steps):
        env.step(action)
    return steps / (time.perf_counter() - start)


def _bare_rate(env, steps: int) -> float:
    """Env steps/s if each env step were only its physics substeps: MuJoCo alone on the same compiled scene.

    The arm is held up by applying its gravity and Coriolis forces once per env step, in place of a controller.
    """
    env.reset()
    model, data = env.sim.model._model, env.sim.data._data
    arm_dofs = np.asarray(env.robots[0]._ref_joint_vel_indexes)
    substeps = int(round(env.control_timestep / env.model_timestep))
    start = time.perf_counter()
    for _ in range(steps):
        data.qfrc_applied[arm_dofs] = data.qfrc_bias[arm_dofs]
        mujoco.mj_step(model, data, nstep=substeps)
    return steps / (time.perf_counter() - start)


def make_env(food: str, n_grains: int | None = None, robot: str = "XArm7"):
    return robosuite.make(
        "ScoopGranular",
        robots=robot,
        food=food,
        n_grains=n_grains,
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        pile_variants=1,
        seed=0,
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--foods", default=",".join(FOODS), help="comma-separated foods (default: all)")
    parser.add_argument("--scales", default="1,2,4", help="grain counts as multiples of each food's default")
    parser.add_argument("--steps", type=int, default=60, help="env steps timed per configuration")
    parser.add_argument(
        "--robot", default="XArm7", help="comma-separated robots, each benched in turn (G1FixedLowerBody: the G1)"
    )
    args = parser.parse_args(argv)
    foods = [f.strip() for f in args.foods.split(",") if f.strip()]
    unknown = [f for f in foods if f not in FOODS]
    if unknown:
        parser.error(f"unknown food(s) {', '.join(unknown)}; accepted foods: {', '.join(FOODS)}")
    try:
        scales = [float(s) for s in args.scales.split(",")]
    except ValueError:
        parser.error(f"--scales takes comma-separated numbers, got {args.scales!r}")

    robots = [r.strip() for r in args.robot.split(",") if r.strip()]
    for robot in robots:
        try:
            check_robot(robot)
        except ValueError as e:
            parser.error(str(e))
    for i, robot in enumerate(robots):
        if i:
            print()
        _bench_robot(robot, foods, scales, args.steps)


def _bench_robot(robot: str, foods: list[str], scales: list[float], steps: int) -> None:
    """The table of one robot: robosuite's Lift with it, then each food at each scale."""
    lift = robosuite.make("Lift", robots=robot, has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    lift_rate = _env_rate(lift, steps)
    lift.close()
    print(f"robosuite Lift ({robot}): {lift_rate:7.1f} steps/s  RTF {lift_rate / REAL_TIME_STEPS_PER_S:5.2f}")
    print()
    columns = ("grains", "steps/s", "RTF", "vs Lift", "bare mj", "env/bare", "contacts")
    header = f"{'food':<10}" + "".join(f" {c:>8}" for c in columns)
    print(header)
    print("-" * len(header))
    training_defaults: dict[str, float] = {}
    for food in foods:
        for scale in scales:
            n = max(1, int(round(FOODS[food].default_grains * scale)))
            env = make_env(food, n, robot)
            rate = _env_rate(env, steps)
            contacts = env.sim.data.ncon
            bare = _bare_rate(env, steps)
            env.close()
            flag = " *" if food in TRAINING_FOODS and scale == 1 and rate < REAL_TIME_STEPS_PER_S else ""
            if food in TRAINING_FOODS and scale == 1:
                training_defaults[food] = rate
            print(
                f"{food:<10} {n:>8} {rate:>8.1f} {rate / REAL_TIME_STEPS_PER_S:>6.2f} {rate / lift_rate:>8.2f} "
                f"{bare:>8.1f} {rate / bare:>8.2f} {contacts:>8}{flag}",
                flush=True,
            )
    if training_defaults:
        slowest = min(training_defaults, key=training_defaults.get)
        rate = training_defaults[slowest]
        below = [f for f, r in training_defaults.items() if r < REAL_TIME_STEPS_PER_S]
        print(
            f"\nslowest training food at its default: {slowest} {rate:.1f} steps/s, "
            f"RTF {rate / REAL_TIME_STEPS_PER_S:.2f} (must: 1.0, aim: {AIM_RTF:.1f}), "
            f"{rate / lift_rate:.2f}x Lift (aim: {AIM_VS_LIFT:.1f}x)"
        )
        if below:
            print(f"* below real time: {', '.join(below)}")


if __name__ == "__main__":
    main()
