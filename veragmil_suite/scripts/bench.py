"""Speed of ScoopGranular: env steps/s and real-time factor per food, against robosuite's Lift and bare MuJoCo.

    python -m veragmil_suite.scripts.bench                  # every food, 1x/2x/4x its default grain count
    python -m veragmil_suite.scripts.bench --foods rice --scales 1 --steps 40 --episodes 2
    python -m veragmil_suite.scripts.bench --robots XArm7,G1FixedLowerBody --foods rice --scales 1  # robots
    python -m veragmil_suite.scripts.bench --foods rice --scales 1 --sleep-tolerance 3e-3          # a tolerance

Real time at 20 Hz control is 20 env steps/s (RTF 1.0). "bare mj_step" steps the same compiled scene with no
controller and no robosuite, so env/bare shows what robosuite's Python costs; "vs Lift" compares with robosuite's
Lift task on the same robot (the G1 with robosuite's default two-arm controller and hands).

The first table holds the robot still (zero delta actions) over the pile at rest, with the grains awake (island
sleeping off) and asleep (on, after REST_WARMUP_STEPS to fall asleep). The second runs whole scripted expert episodes
(the unit recording and evaluation spend), with sleeping off and on: env steps/s, expert episodes per minute on
one core, the share of MuJoCo's step spent finding contacts, building the constraints and solving them, and the
share of control steps with the whole pile awake (what sleeping leaves to pay), and the gain sleeping could give at
most (those steps cost the same with sleeping on or off).
Run on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import robosuite

import veragmil_suite  # noqa: F401  (registers ScoopGranular)
from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.environments.arguments import MAX_GRAINS_PER_DEFAULT
from veragmil_suite.environments.episode import run_until_done
from veragmil_suite.models.foods import DEFAULT_PHYSICS, FOODS, TRAINING_FOODS
from veragmil_suite.models.scoop_task import GRAIN_SLEEP_TOLERANCE
from veragmil_suite.utils import cli
from veragmil_suite.utils.timing import per_call, stopwatch

if TYPE_CHECKING:
    from robosuite.environments.base import MujocoEnv

    from veragmil_suite.environments.scoop import ScoopGranular

REAL_TIME_STEPS_PER_S = 20.0  # the default 20 Hz control rate
# the speed issue's goals: at rest, asleep, 0.6x Lift; whole expert episodes of the slowest training food 1.5x (aim
# 3x) the rate of the task as the issue found it, which benchmarks/bench_against.py measures (this benchmark's gain is
# sleeping's alone, against today's code with sleeping off)
REST_MUST_VS_LIFT = 0.6
# control steps a settled pile is given to fall asleep (within 10 at GRAIN_SLEEP_TOLERANCE, 40 at 1e-3)
REST_WARMUP_STEPS = 40
# MuJoCo's timers of a step's parts: contacts found (broad and narrow phase), constraints built, constraints solved
STEP_PARTS = {
    "collide": mujoco.mjtTimer.mjTIMER_POS_COLLISION,
    "build": mujoco.mjtTimer.mjTIMER_POS_MAKE,
    "solve": mujoco.mjtTimer.mjTIMER_CONSTRAINT,
}


def env_rate(env: MujocoEnv, steps: int, warmup: int = 1) -> float:
    """Env steps/s holding still, timed after ``warmup`` steps (the first pays one-off costs)."""
    env.reset()
    action = np.zeros(env.action_dim)
    return 1.0 / per_call(lambda: env.step(action), steps, warmup).wall_s


def _bare_rate(env, steps: int) -> float:
    """Env steps/s if each env step were only its physics substeps: MuJoCo alone on the same compiled scene.

    The arm is held up by applying its gravity and Coriolis forces once per env step, in place of a controller.
    """
    env.reset()
    model, data = env.sim.model._model, env.sim.data._data
    arm_dofs = np.asarray(env.robots[0]._ref_joint_vel_indexes)
    substeps = int(round(env.control_timestep / env.model_timestep))

    def env_step_of_physics() -> None:
        data.qfrc_applied[arm_dofs] = data.qfrc_bias[arm_dofs]
        mujoco.mj_step(model, data, nstep=substeps)

    return 1.0 / per_call(env_step_of_physics, steps, warmup=0).wall_s


def make_env(
    food: str,
    n_grains: int | None = None,
    robot: str = "XArm7",
    sleep_tolerance: float | None = None,
    **overrides: Any,
) -> ScoopGranular:
    """A headless ScoopGranular of one pile variant, seed 0; ``overrides`` replace or add any of its arguments."""
    kwargs = dict(
        robots=robot,
        food=food,
        n_grains=n_grains,
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        pile_variants=1,
        seed=0,
        sleep_tolerance=sleep_tolerance,
    )
    return robosuite.make("ScoopGranular", **{**kwargs, **overrides})


def expert_episodes(food: str, robot: str, sleep_tolerance: float | None, episodes: int) -> dict:
    """Whole scripted expert episodes (seeds 0..episodes-1; resets untimed): env steps/s, seconds per episode,
    successes, each STEP_PARTS share of MuJoCo's step time, the share of control steps that end with the whole pile
    awake (the steps sleeping cannot make cheaper) and of the wall time they take, and MuJoCo's share of the wall
    time (the rest is robosuite's Python)."""
    env = make_env(food, robot=robot, sleep_tolerance=sleep_tolerance)
    expert = ScriptedScooper(env, "expert")
    steps, seconds, successes, pile_awake_steps, pile_awake_s = 0, 0.0, 0, 0, 0.0
    parts = dict.fromkeys([*STEP_PARTS, "step"], 0.0)

    def step(action: np.ndarray) -> tuple:
        nonlocal pile_awake_steps, pile_awake_s
        with stopwatch() as elapsed:
            out = env.step(action)
        if env.sim.data._data.body_awake[env.grain_body_ids].all():
            pile_awake_steps += 1
            pile_awake_s += elapsed.wall_s
        return out

    timers = {**STEP_PARTS, "step": mujoco.mjtTimer.mjTIMER_STEP}
    for seed in range(episodes):
        obs = env.reset()
        expert.reset(seed=seed)
        data = env.sim.data._data
        before = {name: data.timer[t].duration for name, t in timers.items()}
        with stopwatch() as elapsed:
            end = run_until_done(expert.agent, step, obs, env.control_freq, env.horizon)
        seconds += elapsed.wall_s
        steps += end.steps
        successes += end.reason == "success"
        for name, t in timers.items():
            parts[name] += data.timer[t].duration - before[name]
    env.close()
    shares = {name: parts[name] / parts["step"] for name in STEP_PARTS}
    return dict(
        rate=steps / seconds,
        episode_s=seconds / episodes,
        successes=successes,
        pile_awake=pile_awake_steps / steps,
        pile_awake_time=pile_awake_s / seconds,
        mujoco=parts["step"] / seconds,
        **shares,
    )


def sleeping_ceiling(off: dict, on: dict) -> float:
    """The gain over ``off`` if every step of ``on`` without the whole pile awake cost nothing: with the pile awake a
    step costs the same with sleeping on or off, so those steps bound what sleeping can give."""
    pile_up_s_per_step = on["pile_awake_time"] / on["rate"]
    return (1.0 / off["rate"]) / pile_up_s_per_step if pile_up_s_per_step > 0 else float("inf")


def build_parser() -> cli.Parser:
    parser = cli.Parser("veragmil-bench", description=__doc__)
    parser.add_argument("--foods", type=cli.ListOf(cli.food), default=list(FOODS), help="foods (default: all)")
    parser.add_argument(
        "--scales",
        type=cli.ListOf(cli.Real(0.0, MAX_GRAINS_PER_DEFAULT, open_low=True)),
        default=[1.0, 2.0, 4.0],
        help=f"grain counts as multiples of each food's default (at most {MAX_GRAINS_PER_DEFAULT})",
    )
    parser.add_argument("--steps", type=cli.count, default=60, help="env steps timed per configuration")
    parser.add_argument(
        "--episodes",
        type=cli.count_or_zero,
        default=2,
        help="whole expert episodes per food and setting (0: skip that table)",
    )
    parser.add_argument(
        "--robots",
        aliases=["--robot"],
        type=cli.ListOf(cli.robot),
        default=["XArm7"],
        help="robots, each benched in turn (G1FixedLowerBody: the G1)",
    )
    parser.add_argument(
        "--sleep-tolerance",
        type=cli.positive,
        default=GRAIN_SLEEP_TOLERANCE,
        help=f"MuJoCo's sleep_tolerance of the 'asleep' columns (default {GRAIN_SLEEP_TOLERANCE}, the task's)",
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """veragmil-bench (python -m veragmil_suite.scripts.bench): the speed tables (see the module's docstring)."""
    foods = list(dict.fromkeys(args.foods))
    for i, robot in enumerate(dict.fromkeys(args.robots)):
        if i:
            print()
        _bench_robot(robot, foods, args.scales, args.steps, args.episodes, args.sleep_tolerance)
    return 0


def _bench_robot(
    robot: str, foods: list[str], scales: list[float], steps: int, episodes: int, sleep_tolerance: float
) -> None:
    """The tables of one robot: robosuite's Lift with it, each food at rest at each scale, whole expert episodes."""
    lift = robosuite.make("Lift", robots=robot, has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    lift_rate = env_rate(lift, steps)
    lift.close()
    print(f"robosuite Lift ({robot}): {lift_rate:7.1f} steps/s  RTF {lift_rate / REAL_TIME_STEPS_PER_S:5.2f}")
    print(
        f"\nAt rest (steps/s awake: sleeping off; asleep: sleep_tolerance {sleep_tolerance:g}, "
        "after the pile fell asleep)"
    )
    columns = ("grains", "awake", "asleep", "gain", "RTF", "vs Lift", "bare mj", "env/bare", "contacts")
    header = f"{'food':<10}" + "".join(f" {c:>8}" for c in columns)
    print(header)
    print("-" * len(header))
    at_rest: dict[str, float] = {}
    for food in foods:
        for scale in scales:
            n = max(1, int(round(FOODS[food].grain(DEFAULT_PHYSICS).default_grains * scale)))
            env = make_env(food, n, robot)
            awake = env_rate(env, steps, warmup=REST_WARMUP_STEPS)
            contacts = env.sim.data.ncon
            bare = _bare_rate(env, steps)
            env.close()
            env = make_env(food, n, robot, sleep_tolerance=sleep_tolerance)
            asleep = env_rate(env, steps, warmup=REST_WARMUP_STEPS)
            env.close()
            if food in TRAINING_FOODS and scale == 1:
                at_rest[food] = asleep
            print(
                f"{food:<10} {n:>8} {awake:>8.1f} {asleep:>8.1f} {asleep / awake:>7.2f}x "
                f"{asleep / REAL_TIME_STEPS_PER_S:>8.2f} {asleep / lift_rate:>8.2f} {bare:>8.1f} {awake / bare:>8.2f} "
                f"{contacts:>8}",
                flush=True,
            )
    if at_rest:
        slowest = min(at_rest, key=at_rest.get)
        rate = at_rest[slowest]
        print(
            f"\nslowest training food at rest, asleep: {slowest} {rate:.1f} steps/s, "
            f"RTF {rate / REAL_TIME_STEPS_PER_S:.2f}, {rate / lift_rate:.2f}x Lift (must: {REST_MUST_VS_LIFT:.1f}x)"
        )
    if episodes < 1:
        return
    print(
        f"\nWhole expert episodes ({episodes} per food and setting; share of MuJoCo's step: collide/build/solve; "
        "pile up: control steps ending with every grain awake, sleeping on; up time: their share of the wall time; "
        "ceiling: the gain if every other step cost nothing, all sleeping can give; "
        "mujoco: MuJoCo's step in the wall time, sleeping on)"
    )
    columns = ("awake", "asleep", "gain", "vs Lift", "ep/min", "success", "awake %", "asleep %")
    columns += ("pile up", "up time", "ceiling", "mujoco")
    header = f"{'food':<10}" + "".join(f" {c:>8}" for c in columns[:6])
    header += f" {columns[6]:>14} {columns[7]:>14}" + "".join(f" {c:>8}" for c in columns[8:])
    print(header)
    print("-" * len(header))
    gains: dict[str, tuple[float, float, float]] = {}
    for food in foods:
        off = expert_episodes(food, robot, None, episodes)
        on = expert_episodes(food, robot, sleep_tolerance, episodes)
        ceiling = sleeping_ceiling(off, on)
        if food in TRAINING_FOODS:
            gains[food] = (off["rate"], on["rate"], ceiling)
        shares = ["/".join(f"{100 * r[k]:.0f}" for k in STEP_PARTS) for r in (off, on)]
        print(
            f"{food:<10} {off['rate']:>8.1f} {on['rate']:>8.1f} {on['rate'] / off['rate']:>7.2f}x "
            f"{on['rate'] / lift_rate:>8.2f} {60 / on['episode_s']:>8.1f} "
            f"{off['successes']:>3}/{on['successes']:<4} {shares[0]:>14} {shares[1]:>14} "
            f"{100 * on['pile_awake']:>7.0f}% {100 * on['pile_awake_time']:>7.0f}% {ceiling:>7.2f}x "
            f"{100 * on['mujoco']:>7.0f}%",
            flush=True,
        )
    if gains:
        slowest = min(gains, key=lambda f: gains[f][0])
        off, on, ceiling = gains[slowest]
        print(
            f"\nslowest training food over whole episodes: {slowest} {off:.1f} -> {on:.1f} steps/s with sleeping, "
            f"{on / off:.2f}x (the goal, 1.5x the task as the speed issue found it: benchmarks/bench_against.py); "
            f"{off / lift_rate:.2f} -> {on / lift_rate:.2f}x Lift; sleeping's ceiling {ceiling:.2f}x"
        )


if __name__ == "__main__":
    sys.exit(main())
