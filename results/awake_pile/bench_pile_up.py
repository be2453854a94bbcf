"""
Whether a control step with the whole pile awake costs the same with sleeping on as off: the premise of the speed
benchmark's "ceiling" column (the gain sleeping could give if every other step cost nothing).

The same scripted expert episodes (same seeds) run with sleeping off and on; the steps that end with every grain
awake in the run with sleeping on are timed in both runs (the two runs follow the same actions closely, not
exactly: the physics differs by what sleeps), beside every other step.

    python results/awake_pile/bench_pile_up.py                       # rice, 4 seeds
    python results/awake_pile/bench_pile_up.py --foods rice buckwheat --seeds 2
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.environments.episode import run_until_done
from veragmil_suite.models.foods import FOODS
from veragmil_suite.models.scoop_task import GRAIN_SLEEP_TOLERANCE
from veragmil_suite.scripts.bench import make_env


def timed_episodes(food: str, sleep_tolerance: float | None, seeds: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per expert episode (seeds 0..seeds-1): each control step's wall time (s), and whether it ended with every
    grain awake."""
    env = make_env(food, sleep_tolerance=sleep_tolerance)
    expert = ScriptedScooper(env, "expert")
    episodes = []
    for seed in range(seeds):
        seconds, pile_up = [], []

        def step(action, seconds=seconds, pile_up=pile_up):
            start = time.perf_counter()
            out = env.step(action)
            seconds.append(time.perf_counter() - start)
            pile_up.append(bool(env.sim.data._data.body_awake[env.grain_body_ids].all()))
            return out

        obs = env.reset()
        expert.reset(seed=seed)
        run_until_done(expert.agent, step, obs, env.control_freq, env.horizon)
        episodes.append((np.array(seconds), np.array(pile_up)))
    env.close()
    return episodes


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--foods", nargs="+", default=["rice"], help=f"foods (accepted: {', '.join(FOODS)})")
    parser.add_argument("--seeds", type=int, default=4, help="expert episodes per food and setting")
    args = parser.parse_args(argv)
    unknown = [f for f in args.foods if f not in FOODS]
    if unknown:
        parser.error(f"unknown food(s) {', '.join(unknown)}; accepted foods: {', '.join(FOODS)}")
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")

    print(
        f"{'food':<10} {'seed':>4} {'steps':>11} {'pile up':>7} {'up: on':>9} {'up: off':>9} "
        f"{'other: on':>10} {'other: off':>10}   (ms per control step; steps: off/on)"
    )
    for food in args.foods:
        off = timed_episodes(food, None, args.seeds)
        on = timed_episodes(food, GRAIN_SLEEP_TOLERANCE, args.seeds)
        for seed, ((off_s, _), (on_s, up)) in enumerate(zip(off, on)):
            n = min(len(off_s), len(on_s))
            up_n, off_n = up[:n], off_s[:n]
            print(
                f"{food:<10} {seed:>4} {len(off_s):>5}/{len(on_s):<5} {int(up.sum()):>7} "
                f"{1e3 * on_s[up].mean():>9.1f} {1e3 * off_n[up_n].mean():>9.1f} "
                f"{1e3 * on_s[~up].mean():>10.1f} {1e3 * off_n[~up_n].mean():>10.1f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
