"""
How far the solver is from converged while the spoon is in the pile, and what a solver setting costs there.

States with every grain awake are taken from one scripted expert episode (every ``--every``-th such control step);
each is solved again by ``mj_forward`` from its own warm start, under the task's settings and under each variant,
and the iterations CG ran (on the largest island) and the time of the forward are printed.

    python results/awake_pile/probe_pile_up_solver.py                    # rice, seed 0
    python results/awake_pile/probe_pile_up_solver.py --food buckwheat --every 4
"""

from __future__ import annotations

import argparse
import copy
import time

import mujoco
import numpy as np

from veragmil_suite.devices.expert import ScriptedScooper
from veragmil_suite.environments.episode import run_until_done
from veragmil_suite.models.foods import FOODS
from veragmil_suite.models.scoop_task import GRAIN_SLEEP_TOLERANCE
from veragmil_suite.scripts.bench import make_env

FORWARD_REPEATS = 5


def _disable(flag: int):
    def apply(opt) -> None:
        opt.disableflags |= flag

    return apply


VARIANTS = {
    "the task's": lambda opt: None,
    "iterations 100": lambda opt: setattr(opt, "iterations", 100),
    "tolerance 1e-6": lambda opt: setattr(opt, "tolerance", 1e-6),
    "warm start off": _disable(mujoco.mjtDisableBit.mjDSBL_WARMSTART),
    "island discovery off": _disable(mujoco.mjtDisableBit.mjDSBL_ISLAND),
}


def pile_up_states(food: str, seed: int, every: int) -> tuple[mujoco.MjModel, list[mujoco.MjData]]:
    """Copies of the state after every ``every``-th control step that ends with the whole pile awake."""
    env = make_env(food, sleep_tolerance=GRAIN_SLEEP_TOLERANCE)
    expert = ScriptedScooper(env, "expert")
    states, count = [], 0

    def step(action):
        nonlocal count
        out = env.step(action)
        data = env.sim.data._data
        if data.body_awake[env.grain_body_ids].all():
            count += 1
            if count % every == 0:
                states.append(copy.copy(data))
        return out

    obs = env.reset()
    expert.reset(seed=seed)
    run_until_done(expert.agent, step, obs, env.control_freq, env.horizon)
    model = copy.copy(env.sim.model._model)
    env.close()
    return model, states


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--food", default="rice", help=f"the food (accepted: {', '.join(FOODS)})")
    parser.add_argument("--seed", type=int, default=0, help="the expert episode's seed")
    parser.add_argument("--every", type=int, default=8, help="keep every n-th control step with the pile awake")
    args = parser.parse_args(argv)
    if args.food not in FOODS:
        parser.error(f"unknown food {args.food!r}; accepted foods: {', '.join(FOODS)}")
    if args.every < 1:
        parser.error(f"--every must be at least 1, got {args.every}")

    model, states = pile_up_states(args.food, args.seed, args.every)
    if not states:
        raise SystemExit(f"no control step of seed {args.seed} ended with the whole {args.food} pile awake")
    print(f"{args.food}, seed {args.seed}: {len(states)} states with the whole pile awake, nv {model.nv}")
    print(f"{'setting':<22} {'iterations':>10} {'(max)':>6} {'forward ms':>11} {'contacts':>9}")
    for name, apply in VARIANTS.items():
        variant = copy.copy(model)
        apply(variant.opt)
        iterations, seconds, contacts = [], [], []
        for state in states:
            elapsed = 0.0
            for _ in range(FORWARD_REPEATS):
                data = copy.copy(state)
                start = time.perf_counter()
                mujoco.mj_forward(variant, data)
                elapsed += time.perf_counter() - start
            seconds.append(elapsed / FORWARD_REPEATS)
            iterations.append(int(data.solver_niter[: max(1, data.nisland)].max()))
            contacts.append(data.ncon)
        print(
            f"{name:<22} {np.mean(iterations):>10.1f} {max(iterations):>6} {1e3 * np.mean(seconds):>11.2f} "
            f"{np.mean(contacts):>9.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
