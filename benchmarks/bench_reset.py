"""
Reset cost of ScoopGranular, and the ratios of what it keeps between resets:
- with an offscreen camera, a hard reset that keeps the render context of the last scene
  (veragmil_suite.environments.render_context) against one that makes a new context, as robosuite does;
- without a camera, a reset that takes its grain pile from the process's kept piles
  (veragmil_suite.environments.pile_variants.pile_variant) against one that builds the pile anew.

All rebuild the simulation on each reset and draw the same episodes (seeds 0.., so the same pile variants); an
untimed round of the same resets first settles their piles or reads them from the cache.

    python benchmarks/bench_reset.py                      # rice, 300 grains, 84x84 overhead camera, 10 resets
    python benchmarks/bench_reset.py --food pasta --resets 20
"""

from __future__ import annotations

import argparse
import os
import sys

# OSMesa whatever the display (veragmil_suite.utils.rendering's forced choice), set before robosuite is imported
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

# the package imports robosuite: after MUJOCO_GL
from veragmil_suite.environments.pile_variants import kept_pile  # noqa: E402
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.timing import stopwatch  # noqa: E402

CAMERA_SIZE = 84


def time_resets(env, resets: int, keep_context: bool = True, keep_piles: bool = True) -> float:
    """Mean wall time (s) of ``resets`` resets of ``env``, keeping its render context and the built piles or making
    new ones each."""
    for seed in range(resets):
        env.reset(seed=seed)  # untimed: settles the piles these seeds draw, or reads them
    with stopwatch() as elapsed:
        for seed in range(resets):
            if not keep_context:
                env._render_context = None  # the next simulation makes a context of its own, as robosuite's does
            if not keep_piles:
                kept_pile.cache_clear()
            env.reset(seed=seed)
    return elapsed.wall_s / resets


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_reset.py", description=__doc__)
    parser.add_argument("--food", type=cli.food, default="rice", help="the food in the bowl")
    parser.add_argument("--n-grains", type=cli.count, default=300, help="grains in the bowl")
    parser.add_argument("--resets", type=cli.count, default=10, help="timed resets per measurement")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Mean reset time without a camera, with a camera and a new context each, and with the kept context."""
    import robosuite

    import veragmil_suite  # noqa: F401  (registers ScoopGranular)

    camera = dict(camera_names=["overhead"], camera_heights=CAMERA_SIZE, camera_widths=CAMERA_SIZE, camera_depths=True)
    common = dict(robots="XArm7", food=args.food, n_grains=args.n_grains, has_renderer=False)
    blind = robosuite.make("ScoopGranular", **common, has_offscreen_renderer=False, use_camera_obs=False)
    seeing = robosuite.make("ScoopGranular", **common, has_offscreen_renderer=True, use_camera_obs=True, **camera)
    print(f"load average before: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    print(f"{args.food}, {args.n_grains} grains, {args.resets} resets each")
    new_piles = time_resets(blind, args.resets, keep_piles=False)
    no_camera = time_resets(blind, args.resets)
    fresh = time_resets(seeing, args.resets, keep_context=False)
    kept = time_resets(seeing, args.resets)
    print(f"{'reset':<36} {'ms':>7}")
    print(f"{'no camera, piles built anew':<36} {new_piles * 1e3:>7.1f}")
    print(f"{'no camera, the kept piles':<36} {no_camera * 1e3:>7.1f}")
    print(f"{'camera, a new render context':<36} {fresh * 1e3:>7.1f}")
    print(f"{'camera, the kept render context':<36} {kept * 1e3:>7.1f}")
    print(f"new piles / kept piles = {new_piles / no_camera:.2f}x")
    print(f"new context / kept context = {fresh / kept:.2f}x")
    print(f"load average after: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    blind.close(), seeing.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
