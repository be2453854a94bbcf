"""
Whole scripted expert episodes of this checkout against another one (the code a speed goal is counted from),
each side in its own process with its own MuJoCo, the two sides alternating on the same machine.

A speed goal such as "1.5x today's episode rate" compares the task now with the task as it was, not sleeping on
with sleeping off in today's code (both of which have gained since). The ratio of two sides run one after another
on the same host is the figure that carries across hosts; robosuite's Lift, timed in each process, shows whether
the host stayed the same through the run.

    # the task as the speed issue found it (16c283c, MuJoCo 3.3.7) against this checkout
    git archive 16c283c --prefix=base/ | tar -x -C /tmp
    pip install --no-deps --target /tmp/mj337 mujoco==3.3.7
    python benchmarks/bench_against.py --base /tmp/base --base-path /tmp/mj337 --food rice --episodes 4 --rounds 3

Each side runs the episodes of seeds 0..episodes-1 on pile variant 0 (resets untimed; a first untimed episode
settles or loads the piles). A side's own defaults apply (this checkout's sleeping among them); ``--sleep
off`` switches this checkout's sleeping off, ``--physics`` picks this checkout's physics
(veragmil_suite.models.foods.PHYSICS).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _first_module(*names: str):
    """The first of ``names`` that imports (a module's place in this checkout, then in older ones)."""
    import importlib  # in the child, from that side's checkout

    for name in names:
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError:
            continue
    raise ModuleNotFoundError(f"none of {names} in this checkout")


def _child(
    food: str, episodes: int, lift_steps: int, sleep_off: bool, physics: str | None = None, n_grains: int | None = None
) -> dict:
    """One side's figures, in the process of that side's checkout and MuJoCo (only API both sides have)."""
    import time  # in the child, from that side's checkout

    import mujoco  # in the child, from that side's checkout
    import robosuite  # in the child, from that side's checkout

    import veragmil_suite  # in the child, from that side's checkout

    # each module where this checkout keeps it, or where a checkout from before the role folders (#35) did
    expert = _first_module("veragmil_suite.devices.expert", "veragmil_suite.expert")
    episode = _first_module("veragmil_suite.environments.episode", "veragmil_suite.episode")
    bench = _first_module("veragmil_suite.scripts.bench", "veragmil_suite.bench")
    ScriptedScooper, run_until_done = expert.ScriptedScooper, episode.run_until_done
    env_rate = getattr(bench, "env_rate", None) or bench._env_rate  # steps/s held still, after one step

    headless = dict(has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False)
    lift = robosuite.make("Lift", robots="XArm7", **headless)
    lift_rate = env_rate(lift, lift_steps)
    lift.close()

    kwargs = dict(robots="XArm7", food=food, pile_variants=1, seed=0, **headless)
    if sleep_off:
        kwargs["sleep_tolerance"] = None
    if physics is not None:
        kwargs["physics"] = physics
    if n_grains is not None:
        kwargs["n_grains"] = n_grains
    env = robosuite.make("ScoopGranular", **kwargs)
    expert = ScriptedScooper(env, "expert")

    def agent(obs):
        return None if expert.done else expert.executed(expert.act(obs))

    steps, seconds, successes = 0, 0.0, 0
    for k, seed in enumerate([0, *range(episodes)]):  # the first, untimed, settles or loads the piles
        obs = env.reset()
        expert.reset(seed=seed)
        start = time.perf_counter()
        end = run_until_done(agent, env.step, obs, env.control_freq, env.horizon)
        if k:
            seconds += time.perf_counter() - start
            steps += end.steps
            successes += end.reason == "success"
    env.close()
    return dict(
        checkout=str(Path(veragmil_suite.__file__).resolve().parent.parent),
        mujoco=mujoco.__version__,
        lift_rate=lift_rate,
        rate=steps / seconds,
        steps=steps,
        successes=successes,
    )


def _run_side(name: str, checkout: Path, extra_path: str | None, args) -> dict:
    """One side's figures from a child process with the checkout (and extra_path, e.g. another MuJoCo) first."""
    path = [str(checkout)] + ([extra_path] if extra_path else [])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path + [os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    if args.cache_root:
        env["VERAGMIL_CACHE_DIR"] = str(Path(args.cache_root) / name)
    code = (
        f"import json, sys; sys.path.insert(0, {str(Path(__file__).resolve().parent)!r}); import bench_against as b; "
        f"print('RESULT ' + json.dumps(b._child({args.food!r}, {args.episodes}, {args.lift_steps}, "
        f"{name == 'this' and args.sleep == 'off'}, {args.physics if name == 'this' else None!r}, {args.n_grains!r})))"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=checkout, capture_output=True, text=True)
    lines = [line for line in out.stdout.splitlines() if line.startswith("RESULT ")]
    if out.returncode or not lines:
        raise SystemExit(f"the {name} side ({checkout}) failed:\n{out.stderr[-3000:]}")
    result = json.loads(lines[-1][len("RESULT ") :])
    if Path(result["checkout"]) != checkout.resolve():
        raise SystemExit(f"the {name} side imported veragmil_suite from {result['checkout']}, not {checkout}")
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", type=Path, required=True, help="the other checkout (e.g. from git archive)")
    parser.add_argument("--base-path", help="a folder put first on the base side's path (e.g. its MuJoCo)")
    parser.add_argument("--food", default="rice", help="the food of the episodes (default rice)")
    parser.add_argument("--episodes", type=int, default=4, help="timed expert episodes per side and round")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, each running both sides once")
    parser.add_argument("--lift-steps", type=int, default=200, help="steps of robosuite's Lift timed per side")
    parser.add_argument("--sleep", choices=("on", "off"), default="on", help="this checkout's island sleeping")
    parser.add_argument("--physics", help="this checkout's physics (calibrated or table1; default: its default)")
    parser.add_argument("--n-grains", type=int, help="grains in the bowl, both sides (default: the food's own)")
    parser.add_argument("--cache-root", help="settled piles cached per side under this folder (default: shared)")
    args = parser.parse_args(argv)
    if not (args.base / "veragmil_suite" / "__init__.py").is_file():
        parser.error(f"--base {args.base} holds no veragmil_suite package (a checkout's top level is expected)")
    from veragmil_suite.models.foods import FOODS, PHYSICS  # this checkout's, after --base is checked

    if args.physics is not None and args.physics not in PHYSICS:
        parser.error(f"unknown physics {args.physics!r}; accepted physics: {', '.join(PHYSICS)}")
    if args.food not in FOODS:
        parser.error(f"unknown food {args.food!r}; accepted foods: {', '.join(FOODS)}")
    if args.episodes < 1 or args.rounds < 1:
        parser.error(f"--episodes and --rounds must be at least 1, got {args.episodes} and {args.rounds}")
    if args.n_grains is not None and args.n_grains < 1:
        parser.error(f"--n-grains must be at least 1, got {args.n_grains}")

    print(f"{'round':<6} {'side':<5} {'mujoco':<7} {'Lift/s':>7} {'steps/s':>8} {'vs Lift':>8} {'success':>8}")
    ratios, lift_ratios = [], []
    for r in range(1, args.rounds + 1):
        sides = {}
        for name, checkout, extra in (("base", args.base, args.base_path), ("this", REPO, None)):
            res = sides[name] = _run_side(name, checkout, extra, args)
            print(
                f"{r:<6} {name:<5} {res['mujoco']:<7} {res['lift_rate']:>7.1f} {res['rate']:>8.1f} "
                f"{res['rate'] / res['lift_rate']:>8.3f} {res['successes']:>4}/{args.episodes:<3}",
                flush=True,
            )
        ratios.append(sides["this"]["rate"] / sides["base"]["rate"])
        lift_ratios.append(sides["this"]["lift_rate"] / sides["base"]["lift_rate"])
    print(
        f"\n{args.food}, whole expert episodes, this / base: "
        + ", ".join(f"{x:.2f}x" for x in ratios)
        + f" (Lift this / base: {', '.join(f'{x:.2f}' for x in lift_ratios)})"
    )


if __name__ == "__main__":
    main()
