"""
Training throughput of robomimic's BC, BC-RNN, BCQ and our Diffusion Policy with our configs: gradient steps and samples
per second.

Runs robomimic's own training epoch (data loading, batch processing, forward and backward pass) on a dataset of
ScoopGranular episodes, with the configs' own batch sizes and networks, for 1 and 2 torch threads (robomimic's
train.py uses 2; set VERAGMIL_TORCH_THREADS for veragmil-train). Without --dataset, a small random-action dataset
(low-dim plus 84x84 overhead RGB-D) is recorded first. Wall-clock rates hold only on an otherwise idle machine; the
rate per CPU second (this process's CPU time, all its threads) stands for an idle core with 1 thread even when other
jobs load the machine.

    python benchmarks/bench_training.py                       # bc, bc_rnn, bcq, bc_image, diffusion_policy
    python benchmarks/bench_training.py --algos bc_rnn_image --image-steps 2
    python benchmarks/bench_training.py --algos diffusion_policy --diffusion-steps 5 --threads 1 2
    python benchmarks/bench_training.py --algos diffusion_policy bc --threads 2 --precision fp32 bf16
    python benchmarks/bench_training.py --device cuda --steps 100 --image-steps 30 --diffusion-steps 30
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# robomimic's run_epoch times these parts of each gradient step: reading the batch from the dataset, moving it to
# tensors, the forward and backward pass with the optimizer step, and logging
EPOCH_PARTS = ("Data_Loading", "Process_Batch", "Train_Batch", "Log_Info")
CONFIG_DIR = ROOT / "configs" / "json"

# OSMesa unless MUJOCO_GL names another (EGL on a GPU machine), set before robosuite is imported
os.environ.setdefault("MUJOCO_GL", "osmesa")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

# the package imports robosuite: after MUJOCO_GL
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.timing import stopwatch  # noqa: E402

TORCH_DEVICES = ("cpu", "cuda")
# the arithmetic of the forward and backward passes: float32 as robomimic trains, or torch's autocast to bfloat16
PRECISIONS = ("fp32", "bf16")


def bench_algo(name: str, dataset: str, steps: int, device: str = "cpu", precision: str = "fp32") -> dict:
    """Times ``steps`` gradient steps of config ``name`` on ``dataset`` (after 2 warm-up steps) on torch ``device``;
    ``precision`` bf16 runs them under torch's autocast to bfloat16 (the weights and the optimizer stay float32)."""
    import torch  # heavy: torch, after robomimic_compat.install()
    from robomimic.algo import algo_factory  # robomimic: after robomimic_compat.install()
    from robomimic.config import config_factory  # robomimic: after robomimic_compat.install()
    from robomimic.utils import file_utils, obs_utils, train_utils  # robomimic: after robomimic_compat.install()
    from torch.utils.data import DataLoader  # heavy: torch, after robomimic_compat.install()

    with open(CONFIG_DIR / f"{name}.json") as f:
        ours = json.load(f)
    config = config_factory(ours["algo_name"])
    with config.values_unlocked():
        config.update(ours)
        config.train.data = dataset
        config.experiment.validate = False
    obs_utils.initialize_obs_utils_with_config(config)
    shape_meta = file_utils.get_shape_metadata_from_dataset(dataset_path=dataset, all_obs_keys=config.all_obs_keys)
    torch.manual_seed(config.train.seed)
    model = algo_factory(
        algo_name=config.algo_name,
        config=config,
        obs_key_shapes=shape_meta["all_shapes"],
        ac_dim=shape_meta["ac_dim"],
        device=torch.device(device),
    )
    trainset, _ = train_utils.load_data_for_training(config, obs_keys=shape_meta["all_obs_keys"])
    loader = DataLoader(trainset, batch_size=config.train.batch_size, shuffle=True, drop_last=True)
    autocast = torch.autocast(torch.device(device).type, dtype=torch.bfloat16, enabled=precision == "bf16")
    with autocast:
        train_utils.run_epoch(model=model, data_loader=loader, epoch=1, num_steps=2)
    sync = torch.cuda.synchronize if device.startswith("cuda") else lambda: None
    sync()
    with stopwatch() as timed, autocast:
        log = train_utils.run_epoch(model=model, data_loader=loader, epoch=1, num_steps=steps)
        sync()
    elapsed, cpu = timed.wall_s, timed.cpu_s
    # a sample's steps: the sequence and the frames stacked before it (Diffusion Policy's observation history)
    batch, seq = config.train.batch_size, config.train.frame_stack - 1 + config.train.seq_length
    # robomimic's own timers (minutes summed over the epoch): where an epoch's time goes
    parts = {part: log[f"Time_{part}"] * 60.0 for part in EPOCH_PARTS}
    return dict(
        config=name,
        precision=precision,
        batch=batch,
        seq=seq,
        steps_per_s=steps / elapsed,
        steps_per_cpu_s=steps / cpu,
        samples_per_s=steps * batch / elapsed,
        frames_per_s=steps * batch * seq / elapsed,
        shares={part: seconds / elapsed for part, seconds in parts.items()},
    )


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_training.py", description=__doc__)
    parser.add_argument(
        "--algos",
        type=cli.ListOf(cli.Choice("config", lambda: sorted(p.stem for p in CONFIG_DIR.glob("*.json")))),
        default=["bc", "bc_rnn", "bcq", "bc_image", "diffusion_policy"],
        help="configs/json names",
    )
    parser.add_argument(
        "--dataset", type=cli.robomimic_dataset, help="robomimic HDF5 with the configs' observation keys"
    )
    parser.add_argument("--steps", type=cli.count, default=30, help="timed gradient steps, low-dim configs")
    parser.add_argument("--image-steps", type=cli.count, default=3, help="timed gradient steps, image configs")
    parser.add_argument(
        "--diffusion-steps",
        type=cli.count,
        default=3,
        help="timed gradient steps, Diffusion Policy (a 66M-weight U-Net)",
    )
    parser.add_argument(
        "--threads",
        type=cli.ListOf(cli.count),
        default=[1, 2],
        help="torch thread counts (robomimic's train.py uses 2)",
    )
    parser.add_argument(
        "--device",
        type=cli.Choice("torch device", TORCH_DEVICES),
        default="cpu",
        help="torch device the networks train on",
    )
    parser.add_argument(
        "--precision",
        type=cli.ListOf(cli.Choice("precision", PRECISIONS)),
        default=["fp32"],
        help="fp32 (robomimic's) and/or bf16 (torch's autocast: AMX or AVX512-BF16 CPUs, GPUs)",
    )
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Each config with each thread count, and the table of their rates."""
    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()
    import torch  # heavy: torch, after robomimic_compat.install()

    if args.device == "cuda" and not torch.cuda.is_available():
        raise cli.UsageError(f"--device cuda: torch finds no CUDA device here (accepted: {', '.join(TORCH_DEVICES)})")

    dataset = args.dataset
    if dataset is None:
        sys.path.insert(0, str(ROOT / "tests"))
        from helpers.tiny_dataset import record_tiny_dataset  # tests/ is put on the path just above

        dataset = os.path.join(tempfile.mkdtemp(prefix="bench_training_"), "scoop.hdf5")
        started = time.perf_counter()
        record_tiny_dataset(dataset, episodes=6, steps=40, camera_names=("overhead",), camera_depths=True)
        print(f"recorded 6 x 40 ScoopGranular steps with RGB-D in {time.perf_counter() - started:.0f} s: {dataset}")

    # OpenMP threads stall when other processes hold the cores: the load average tells whether figures are clean
    load_before = os.getloadavg()[0]
    rows = []
    for name in args.algos:
        steps = args.image_steps if "image" in name or "rgbd" in name else args.steps
        steps = args.diffusion_steps if name.startswith("diffusion_policy") else steps
        for threads in args.threads:
            torch.set_num_threads(threads)
            for precision in args.precision:
                rows.append(dict(bench_algo(name, dataset, steps, args.device, precision), threads=threads))
                r = rows[-1]
                rate = f"{r['steps_per_s']:.2f} steps/s, {r['samples_per_s']:.0f} samples/s"
                print(f"{name}, {threads} threads, {precision}: {rate}", flush=True)

    print(
        f"\ntraining throughput, {_device_name(args.device)} ({os.cpu_count()} cores, "
        f"load average {load_before:.1f} -> "
        f"{os.getloadavg()[0]:.1f}), robomimic {_version('robomimic')}"
    )
    parts = " | ".join(f"% {p.lower().replace('_', ' ')}" for p in EPOCH_PARTS)
    print(
        "| config | torch threads | precision | batch | seq | gradient steps/s | per CPU second | samples/s | "
        f"frames/s | {parts} |"
    )
    print("|---|---|---|---|---|---|---|---|---|" + "---|" * len(EPOCH_PARTS))
    for r in rows:
        shares = " | ".join(f"{100 * r['shares'][p]:.0f}" for p in EPOCH_PARTS)
        print(
            f"| {r['config']} | {r['threads']} | {r['precision']} | {r['batch']} | {r['seq']} | "
            f"{r['steps_per_s']:.2f} | {r['steps_per_cpu_s']:.2f} | "
            f"{r['samples_per_s']:.0f} | {r['frames_per_s']:.0f} | {shares} |"
        )
    return 0


def _device_name(device: str) -> str:
    """The device the networks trained on, as a reader names it."""
    import torch  # heavy: torch, after robomimic_compat.install()

    return torch.cuda.get_device_name(torch.device(device)) if device.startswith("cuda") else "CPU"


def _version(package: str) -> str:
    """The installed version; a package put on the path without metadata (a copied folder) gives its __version__."""
    from importlib.metadata import PackageNotFoundError, version  # only where a version is printed

    try:
        return version(package)
    except PackageNotFoundError:
        return getattr(__import__(package), "__version__", "unknown")


if __name__ == "__main__":
    sys.exit(main())
