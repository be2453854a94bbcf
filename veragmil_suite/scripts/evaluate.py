"""
veragmil-evaluate: score checkpoints, the scripted expert and recorded datasets on ScoopGranular, per food, and
write the paper's Tables II and III (markdown, CSV, JSON), a success bar chart and optional videos.

    veragmil-evaluate --agent BC=runs/bc/model_epoch_50.pth --agent expert --agent human=dataset:demos/vr.hdf5 \\
        --foods rice peas --episodes 20 --processes 2 --output-dir eval/

Episode i of every food runs with env seed --seed + i for every agent (the same bowls for all). Table III's time
is the mean over successful episodes ("-" when none succeeded); failures' episode lengths stay in episodes.csv.
With --ray [ADDRESS] every episode is a Ray task of one CPU (on a cluster: see the README), scored on the piles
settled on this machine.
"""

from __future__ import annotations

import argparse
import inspect
import json
import sys

from veragmil_suite.distributed import add_ray_argument, check_ray_argument
from veragmil_suite.evaluation import ALL_FOODS, DEFAULT_VIDEO_CAMERA, SPEC_HELP, evaluate, parse_agent_argument
from veragmil_suite.scripts.cli import non_negative_int, positive_int


def _env_kwargs(text: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        raise argparse.ArgumentTypeError(f"not JSON: {e}") from e
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object of robosuite.make keyword arguments")
    from veragmil_suite.environments.scoop import ScoopGranular

    accepted = [name for name in inspect.signature(ScoopGranular.__init__).parameters if name != "self"]
    unknown = sorted(set(value) - set(accepted))
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown ScoopGranular argument(s) {', '.join(unknown)}; accepted: {', '.join(accepted)}"
        )
    return value


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="veragmil-evaluate",
        description=__doc__.split("\n\n")[0].strip(),
        epilog=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--agent",
        action="append",
        required=True,
        metavar="NAME=SPEC",
        help=f"an agent column (repeat for more): SPEC is {SPEC_HELP}; without NAME= it is named after SPEC",
    )
    p.add_argument("--foods", nargs="+", default=list(ALL_FOODS), help=f"foods (default: all, {' '.join(ALL_FOODS)})")
    p.add_argument("--episodes", type=positive_int, default=10, help="episodes per agent and food (default 10)")
    p.add_argument(
        "--processes",
        type=positive_int,
        default=2,
        help="parallel worker processes (default 2; with --ray, the least number of episodes in flight)",
    )
    p.add_argument("--output-dir", required=True, help="folder for the tables, plot, episodes and videos")
    p.add_argument("--seed", type=int, default=0, help="episode i runs with env seed SEED + i (default 0)")
    p.add_argument("--horizon", type=positive_int, default=None, help="steps per episode (default: the env's)")
    p.add_argument("--videos", type=non_negative_int, default=0, help="save the first K episodes per agent and food")
    p.add_argument("--video-camera", default=DEFAULT_VIDEO_CAMERA, help="camera of the videos (default overhead)")
    p.add_argument(
        "--env-kwargs",
        type=_env_kwargs,
        default=None,
        help="JSON of robosuite.make keyword arguments for every env, e.g. '{\"n_grains\": 12}'",
    )
    p.add_argument(
        "--robot",
        default=None,
        help="the robot every agent scoops with (default: the checkpoints', else XArm7; G1FixedLowerBody: the G1)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="take the episodes journaled in OUTPUT_DIR/episodes.jsonl (same agent SPEC, food, seed, horizon and "
        "env kwargs, whatever the agent's name) instead of running them again; without it the journal is replaced",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_ray_argument(p, "the episodes")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    check_ray_argument(parser, args)
    from veragmil_suite.evaluation import check_foods

    agents: dict[str, str] = {}
    try:
        check_foods(args.foods)
        for text in args.agent:
            name, spec = parse_agent_argument(text)
            if name in agents:
                raise ValueError(f"two agents are named {name!r}: give each a NAME= of its own")
            agents[name] = spec
    except ValueError as e:
        parser.error(str(e))
    try:
        result = _evaluate(agents, args)
    except ValueError as e:
        parser.error(str(e))
    print(result.markdown())
    print(f"written to {args.output_dir}")
    return 0


def _evaluate(agents: dict[str, str], args: argparse.Namespace):
    return evaluate(
        agents,
        foods=args.foods,
        episodes=args.episodes,
        processes=args.processes,
        seed=args.seed,
        horizon=args.horizon,
        videos=args.videos,
        output_dir=args.output_dir,
        progress=not args.quiet,
        env_kwargs=args.env_kwargs,
        video_camera=args.video_camera,
        ray=args.ray,
        robot=args.robot,
        resume=args.resume,
        say=print,
    )


if __name__ == "__main__":
    sys.exit(main())
