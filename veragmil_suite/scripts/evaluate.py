"""
veragmil-evaluate: score checkpoints, the scripted expert and recorded datasets on ScoopGranular, per food, and
write the paper's Tables II and III (markdown, CSV, JSON), a success bar chart and optional videos.

    veragmil-evaluate --agent BC=runs/bc/model_epoch_50.pth --agent expert --agent human=dataset:demos/vr.hdf5 \\
        --foods rice peas --episodes 20 --processes 2 --output-dir eval/

Episode i of every food runs with env seed --seed + i for every agent (the same bowls for all). Table III's time
is the mean over successful episodes ("-" when none succeeded); failures' episode lengths stay in episodes.csv.
With --ray [ADDRESS] every episode is a Ray task of one CPU (on a cluster: docs/study.md), scored on the piles
settled on this machine.
"""

from __future__ import annotations

import argparse
import os
import sys

from veragmil_suite.evaluation.agents import (
    ALL_FOODS,
    DEFAULT_VIDEO_CAMERA,
    POLICY_DEVICES,
    SPEC_HELP,
    parse_agent_argument,
)
from veragmil_suite.evaluation.evaluate import evaluate
from veragmil_suite.utils import cli
from veragmil_suite.utils.cli.handler import UsageError, command
from veragmil_suite.utils.cli.parser import Parser
from veragmil_suite.utils.distributed import add_ray_argument, check_ray_argument

# ScoopGranular arguments this program sets from its own options
RESERVED_ENV_KWARGS = {"food": "--foods", "seed": "--seed", "horizon": "--horizon", "robots": "--robots"}


def build_parser() -> Parser:
    p = Parser(
        "veragmil-evaluate",
        description=__doc__.split("\n\n")[0].strip(),
        epilog=__doc__.split("\n\n", 1)[1],
    )
    p.add_argument(
        "--agent",
        action="append",
        type=cli.agent,
        required=True,
        metavar="NAME=SPEC",
        help=f"an agent column (repeat for more): SPEC is {SPEC_HELP}; without NAME= it is named after SPEC",
    )
    p.add_argument("--foods", type=cli.ListOf(cli.food), default=list(ALL_FOODS), help="foods")
    p.add_argument("--episodes", type=cli.count, default=10, help="episodes per agent and food")
    p.add_argument(
        "--processes",
        type=cli.count,
        default=2,
        help="parallel worker processes (with --ray, the least number of episodes in flight)",
    )
    p.add_argument(
        "--output-dir", type=cli.output_folder, required=True, help="folder for the tables, plot, episodes and videos"
    )
    p.add_argument("--seed", type=cli.seed, default=0, help="episode i runs with env seed SEED + i")
    p.add_argument("--horizon", type=cli.count, default=None, help="steps per episode (default: the env's)")
    p.add_argument("--videos", type=cli.count_or_zero, default=0, help="save the first K episodes per agent and food")
    p.add_argument(
        "--camera",
        aliases=["--video-camera"],
        type=cli.camera,
        default=DEFAULT_VIDEO_CAMERA,
        help="camera of the videos",
    )
    p.add_argument(
        "--env-kwargs",
        type=cli.EnvKwargs(reserved=RESERVED_ENV_KWARGS),
        default=None,
        help="JSON of robosuite.make keyword arguments for every env, e.g. '{\"n_grains\": 12}'",
    )
    p.add_argument(
        "--robots",
        aliases=["--robot"],
        type=cli.robot,
        default=None,
        help="the robot every agent scoops with (default: the checkpoints', else XArm7; G1FixedLowerBody: the G1)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="take the episodes journaled in OUTPUT_DIR/episodes.jsonl (same agent SPEC, food, seed, horizon and "
        "env kwargs, whatever the agent's name; one on a settled pile this code no longer draws runs again) instead "
        "of running them again; without it an earlier journal is "
        "kept aside (episodes.replaced.jsonl) and a new one started",
    )
    p.add_argument(
        "--policy-device",
        type=cli.Choice("policy device", POLICY_DEVICES),
        default="cpu",
        help="where the checkpoints' networks run in this machine's workers (cuda: each worker on the GPU)",
    )
    p.add_argument(
        "--rnn-horizon",
        type=cli.count,
        default=None,
        help="reset the recurrent checkpoints' (BC-RNN's) hidden state every N rollout steps instead of their "
        "config's algo.rnn.horizon (robomimic's: the training sequence length); other agents run as they are",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_ray_argument(p, "the episodes")
    return p


@command(build_parser)
def main(args: argparse.Namespace) -> int:
    check_ray_argument(args)
    if args.policy_device == "cuda":
        os.environ["PYTORCH_NVML_BASED_CUDA_CHECK"] = "1"  # asks NVML: this process leaves CUDA to the workers
        import torch  # heavy: torch, only when asked for the GPU

        if not torch.cuda.is_available():
            raise UsageError("--policy-device cuda: torch finds no CUDA device here (accepted: cpu, cuda)")
    agents: dict[str, str] = {}
    for text in args.agent:
        name, spec = parse_agent_argument(text)
        if name in agents:
            raise UsageError(f"two agents are named {name!r}: give each a NAME= of its own")
        agents[name] = spec
    if args.env_kwargs and "n_grains" in args.env_kwargs:
        for food in args.foods:  # the grain count's limit is each food's own
            try:
                cli.check_env_kwargs({**args.env_kwargs, "food": food})
            except argparse.ArgumentTypeError as e:
                raise UsageError(f"--env-kwargs: {e}") from None
    try:
        result = _evaluate(agents, args)
    except ValueError as e:
        raise UsageError(str(e)) from None
    print(result.markdown())
    print(f"written to {args.output_dir}")
    return 0


def _evaluate(agents: dict[str, str], args: argparse.Namespace):
    return evaluate(
        agents,
        foods=list(dict.fromkeys(args.foods)),
        episodes=args.episodes,
        processes=args.processes,
        seed=args.seed,
        horizon=args.horizon,
        videos=args.videos,
        output_dir=args.output_dir,
        progress=not args.quiet,
        env_kwargs=args.env_kwargs,
        video_camera=args.camera,
        ray=args.ray,
        robot=args.robots,
        resume=args.resume,
        policy_device=args.policy_device,
        rnn_horizon=args.rnn_horizon,
        say=print,
    )


if __name__ == "__main__":
    sys.exit(main())
