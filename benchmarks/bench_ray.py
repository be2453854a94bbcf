"""
The price of --ray on one machine: the same tiny pieces in local worker processes and as Ray tasks on a local Ray
instance of as many CPUs, wall times and their ratio (Ray / local). Ray gains nothing on one machine (its worth is
spreading the pieces over a cluster's nodes); this measures what it costs.

Rows: starting the Ray instance (a program with a bare --ray pays it; one on a running cluster only connects),
empty pieces (dispatch alone), veragmil-evaluate and veragmil-collect as whole programs (--processes/--workers vs
--ray on the running instance: the Ray side connects, starts its workers and settles the piles on the driver),
evaluation episodes again in this process with Ray's workers already warm, and a short training run (veragmil-train
here vs in a Ray task). Each side is measured --repeats times, alternating, and its fastest time kept; the load
average is printed before and after: other processes on the cores slow both sides.

    python benchmarks/bench_ray.py                      # about 5 minutes on 2 idle cores
    python benchmarks/bench_ray.py --episodes 8 --recorded-demos 4 --steps 50 --repeats 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# OSMesa whatever the display (veragmil_suite.utils.rendering's forced choice), set before robosuite is imported
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

# the package imports robosuite: after MUJOCO_GL
from veragmil_suite.evaluation.evaluate import evaluate  # noqa: E402
from veragmil_suite.study.logged_run import console  # noqa: E402
from veragmil_suite.study.training import train_piece, training_config, training_resources  # noqa: E402
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.distributed import THIS_MACHINE, ray_session, run_pieces  # noqa: E402
from veragmil_suite.utils.timing import stopwatch  # noqa: E402

FOOD = "pasta"
N_GRAINS = 12
HORIZON = 250
EMPTY_PIECES = 200


def _empty(_context: None, piece: int) -> int:
    return piece


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_ray.py", description=__doc__)
    parser.add_argument("--cpus", type=cli.count, default=2, help="local worker processes, and the Ray instance's CPUs")
    parser.add_argument("--episodes", type=cli.count, default=4, help="expert episodes per evaluation")
    parser.add_argument("--recorded-demos", type=cli.count, default=2, help="demos per recording")
    parser.add_argument("--steps", type=cli.count, default=10, help="gradient steps of the training run")
    parser.add_argument("--repeats", type=cli.count, default=2, help="measurements of each side (the fastest is kept)")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Each row's pieces locally and on a local Ray instance, alternating, and the ratio of their fastest times."""

    print(f"load average before: {_load()}", flush=True)
    work = Path(tempfile.mkdtemp(prefix="bench_ray_"))
    (work / "runs").mkdir()
    env_kwargs = {"n_grains": N_GRAINS}
    runs = iter(range(10**6))  # a fresh output name per measurement

    def evaluation(**where) -> None:
        agents = {"expert": "expert"}
        kwargs = dict(processes=args.cpus, horizon=HORIZON, env_kwargs=env_kwargs, progress=False)
        evaluate(agents, [FOOD], args.episodes, **kwargs, **where)

    def program(name: str, *where: str) -> None:
        if name == "veragmil-evaluate":
            command = [sys.executable, "-m", "veragmil_suite.scripts.evaluate", "--agent", "expert", "--foods", FOOD]
            command += ["--episodes", str(args.episodes), "--env-kwargs", json.dumps(env_kwargs), "--quiet"]
            command += ["--output-dir", str(work / f"eval{next(runs)}"), "--horizon", str(HORIZON)]
        else:
            command = [*console(name), "--device", "scripted", "--food", FOOD, "--n-grains", str(N_GRAINS), "--quiet"]
            command += ["--episodes", str(args.recorded_demos), "--horizon", str(HORIZON), "--cameras"]
            command += ["--output", str(work / f"data{next(runs)}.hdf5")]
        subprocess.run([*command, *where], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def training(**where) -> None:
        name = f"bc{next(runs)}"
        config = training_config("bc", work / "data0.hdf5", work / "runs", name, epochs=1, steps_per_epoch=args.steps)
        if where:
            held = training_resources()
            context = (work / "runs", int(held.cpus), False, False)
            list(run_pieces(train_piece, [config], context=context, on_ray=True, resources=held))
        else:
            train_piece((work / "runs", None, False, False), config)

    def row(name: str, local, on_ray) -> None:
        """The fastest of --repeats alternating measurements of each side."""
        times: dict[str, list[float]] = {"local": [], "ray": []}
        for _ in range(args.repeats):
            for side, run in (("local", local), ("ray", on_ray)):
                with stopwatch() as elapsed:
                    run()
                times[side].append(elapsed.wall_s)
        a, b = min(times["local"]), min(times["ray"])
        print(f"{name:<48} {a:>8.1f} {b:>8.1f} {b / a:>9.2f}", flush=True)

    program("veragmil-collect")  # a dataset for training, and the piles of this food in this machine's cache
    print(f"\n{'pieces':<48} {'local s':>8} {'Ray s':>8} {'Ray/local':>9}", flush=True)
    start = time.perf_counter()
    with ray_session(THIS_MACHINE, num_cpus=args.cpus) as address:
        print(f"{'start a local Ray instance':<48} {'':>8} {time.perf_counter() - start:>8.1f}", flush=True)
        empty = range(EMPTY_PIECES)
        row(
            f"{EMPTY_PIECES} empty pieces",
            lambda: list(run_pieces(_empty, empty, processes=args.cpus)),
            lambda: list(run_pieces(_empty, empty, on_ray=True)),
        )
        row(
            f"veragmil-evaluate, {args.episodes} expert episodes",
            lambda: program("veragmil-evaluate", "--processes", str(args.cpus)),
            lambda: program("veragmil-evaluate", "--ray", address),
        )
        row(
            f"veragmil-collect, {args.recorded_demos} demos",
            lambda: program("veragmil-collect", "--workers", str(args.cpus)),
            lambda: program("veragmil-collect", "--ray", address),
        )
        row(f"{args.episodes} episodes in this process, warm Ray workers", evaluation, lambda: evaluation(ray=address))
        row(f"training BC {args.steps} steps", training, lambda: training(ray=address))
    print(f"\nload average after: {_load()}  ({os.cpu_count()} cores; other processes' load slows both sides)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
