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

from veragmil_suite.utils import cli

REPO = Path(__file__).resolve().parent.parent


def _run_side(name: str, checkout: Path, extra_path: str | None, args) -> dict:
    """One side's figures from a child process with the checkout (and extra_path, e.g. another MuJoCo) first."""
    path = [str(checkout)] + ([extra_path] if extra_path else [])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path + [os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    if args.cache_root:
        env["VERAGMIL_CACHE_DIR"] = str(Path(args.cache_root) / name)
    code = (
        f"import json, sys; sys.path.insert(0, {str(Path(__file__).resolve().parent)!r}); import against_side as s; "
        f"print('RESULT ' + json.dumps(s.side_figures({args.food!r}, {args.episodes}, {args.lift_steps}, "
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


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_against.py", description=__doc__)
    parser.add_argument(
        "--base",
        type=cli.InputFolder("checkout", holds="veragmil_suite/__init__.py"),
        required=True,
        help="the other checkout's top level (e.g. from git archive)",
    )
    parser.add_argument(
        "--base-path", type=cli.InputFolder(), help="a folder put first on the base side's path (e.g. its MuJoCo)"
    )
    parser.add_argument("--food", type=cli.food, default="rice", help="the food of the episodes")
    parser.add_argument("--episodes", type=cli.count, default=4, help="timed expert episodes per side and round")
    parser.add_argument("--rounds", type=cli.count, default=3, help="rounds, each running both sides once")
    parser.add_argument("--lift-steps", type=cli.count, default=200, help="steps of robosuite's Lift timed per side")
    parser.add_argument(
        "--sleep", type=cli.Choice("setting", ("on", "off")), default="on", help="this checkout's island sleeping"
    )
    parser.add_argument("--physics", type=cli.physics, help="this checkout's physics (default: its default)")
    parser.add_argument("--n-grains", type=cli.count, help="grains in the bowl, both sides (default: the food's own)")
    parser.add_argument(
        "--cache-root", type=cli.output_folder, help="settled piles cached per side under this folder (default: shared)"
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Both sides, --rounds times, and the ratio of their episode rates."""
    args.base = Path(args.base)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
