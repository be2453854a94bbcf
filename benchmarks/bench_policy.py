"""
Rollout cost of Diffusion Policy: control steps per second of the policy alone, and the time of a step that predicts.

A policy of configs/json/diffusion_policy.json's size (its U-Net and horizons; a checkpoint's weights with
--checkpoint, else untrained ones, which cost the same) acts on the sample data's observations, one per control step
as veragmil-evaluate feeds them. Each case changes one thing the algorithm leaves free: the denoising steps per
prediction (DDIM's, or the template's DDPM with 100), the actions executed per prediction (action chunking: the
config's action horizon, or 1 to predict every step) and the torch threads. ScoopGranular's own step (20-70 steps/s
here, veragmil-bench) comes on top in a rollout.

Wall-clock rates hold only on an otherwise idle machine; the CPU-time rates (this process's CPU seconds, all its
threads) stand for an idle core with 1 thread even when other jobs load the machine.

    python benchmarks/bench_policy.py                              # DDIM 10 and 5, DDPM 100; chunks of 8 and 1
    python benchmarks/bench_policy.py --checkpoint runs/x/models/model_epoch_100.pth --threads 1 2
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_DATA = ROOT / "demos" / "scoop.hdf5"

# OSMesa whatever the display (veragmil_suite.utils.rendering's forced choice), set before robosuite is imported
os.environ["MUJOCO_GL"] = os.environ["PYOPENGL_PLATFORM"] = "osmesa"
os.environ.setdefault("PYNPUT_BACKEND", "dummy")

# the package imports robosuite: after MUJOCO_GL
from veragmil_suite.utils import cli  # noqa: E402
from veragmil_suite.utils.timing import stopwatch  # noqa: E402

# (scheduler, denoising steps, actions executed per prediction): the config's case first
CASES = (("ddim", 10, 8), ("ddim", 5, 8), ("ddpm", 100, 8), ("ddim", 10, 1))


def _config(checkpoint: str | None):
    """The config of the checkpoint, or of configs/json/diffusion_policy.json on the sample data."""
    from robomimic.config import config_factory  # robomimic: after robomimic_compat.install()

    if checkpoint is not None:
        import robomimic.utils.file_utils as FileUtils  # robomimic: after robomimic_compat.install()

        ckpt = FileUtils.load_dict_from_checkpoint(checkpoint)
        config, _ = FileUtils.config_from_checkpoint(ckpt_dict=ckpt)
        return config, ckpt
    config = config_factory("diffusion_policy")
    with config.values_unlocked():
        config.update(json.loads((ROOT / "configs" / "json" / "diffusion_policy.json").read_text()))
        config.train.data = str(SAMPLE_DATA)
    return config, None


def bench_case(config, ckpt, scheduler: str, denoising_steps: int, chunk: int, steps: int) -> dict:
    """Times ``steps`` control steps (after one warm-up prediction) of one case; returns its rates."""
    import h5py  # with robomimic, after robomimic_compat.install()
    import numpy as np  # with robomimic, after robomimic_compat.install()
    import robomimic.utils.file_utils as FileUtils  # robomimic: after robomimic_compat.install()
    import robomimic.utils.obs_utils as ObsUtils  # robomimic: after robomimic_compat.install()
    from robomimic.algo import RolloutPolicy, algo_factory  # robomimic: after robomimic_compat.install()

    config = type(config)(dict_to_load=json.loads(config.dump()))
    with config.values_unlocked():
        config.algo.ddpm.enabled = scheduler == "ddpm"
        config.algo.ddim.enabled = scheduler == "ddim"
        config.algo[scheduler].num_inference_timesteps = denoising_steps
        config.algo.horizon.action_horizon = chunk
    ObsUtils.initialize_obs_utils_with_config(config)
    if ckpt is not None:
        shape_meta = ckpt["shape_metadata"]
    else:
        shape_meta = FileUtils.get_shape_metadata_from_dataset(str(SAMPLE_DATA), all_obs_keys=config.all_obs_keys)
    model = algo_factory(config.algo_name, config, shape_meta["all_shapes"], shape_meta["ac_dim"], device="cpu")
    if ckpt is not None:
        model.deserialize(ckpt["model"])
    policy = RolloutPolicy(model)
    with h5py.File(SAMPLE_DATA, "r") as f:
        demo = f["data/demo_0/obs"]
        observations = [{k: demo[k][t] for k in shape_meta["all_obs_keys"]} for t in range(steps + 1)]
    policy.start_episode()
    policy(ob=observations[0])  # warm-up: the EMA weights copied in, the first prediction
    wall, cpu = [], []
    for ob in observations[1:]:
        with stopwatch() as elapsed:
            policy(ob=ob)
        wall.append(elapsed.wall_s)
        cpu.append(elapsed.cpu_s)
    wall, cpu = np.array(wall), np.array(cpu)
    predicting = np.argsort(cpu)[-max(1, steps // chunk) :]  # the costliest steps are those that predict
    return dict(
        scheduler=scheduler,
        denoising_steps=denoising_steps,
        chunk=chunk,
        steps_per_s=steps / wall.sum(),
        cpu_steps_per_s=steps / cpu.sum(),
        predict_ms=1000 * float(np.median(wall[predicting])),
        predict_cpu_ms=1000 * float(np.median(cpu[predicting])),
    )


def build_parser() -> cli.Parser:
    parser = cli.Parser("bench_policy.py", description=__doc__)
    parser.add_argument("--checkpoint", type=cli.checkpoint, help="a diffusion_policy checkpoint (default: untrained)")
    parser.add_argument(
        "--steps", type=cli.count, default=48, help="timed control steps per case (a multiple of every case's chunk)"
    )
    parser.add_argument("--threads", type=cli.ListOf(cli.count), default=[1, 2], help="torch thread counts")
    return parser


@cli.command(build_parser)
def main(args: argparse.Namespace) -> int:
    """Each case of CASES with each thread count, and the table of their rates."""
    chunks = sorted({chunk for _, _, chunk in CASES})
    if any(args.steps % chunk for chunk in chunks):
        raise cli.UsageError(f"--steps {args.steps}: must be a multiple of every case's chunk ({chunks})")

    from veragmil_suite.learning import robomimic_compat

    robomimic_compat.install()
    import h5py  # with robomimic, after robomimic_compat.install()
    import torch  # heavy: torch, after robomimic_compat.install()

    config, ckpt = _config(args.checkpoint)
    if ckpt is not None and config.algo_name != "diffusion_policy":
        raise cli.UsageError(
            f"--checkpoint {args.checkpoint}: a {config.algo_name} checkpoint; give a diffusion_policy one"
        )
    with h5py.File(SAMPLE_DATA, "r") as f:
        length = len(f["data/demo_0/actions"])
    if args.steps >= length:
        raise cli.UsageError(f"--steps {args.steps}: the sample data's first demo has {length} steps; give fewer")
    load_before = os.getloadavg()[0]
    rows = []
    for threads in args.threads:
        torch.set_num_threads(threads)
        for scheduler, denoising_steps, chunk in CASES:
            rows.append(dict(bench_case(config, ckpt, scheduler, denoising_steps, chunk, args.steps), threads=threads))
            r = rows[-1]
            print(f"{scheduler} {denoising_steps}, chunk {chunk}, {threads} threads: {r['steps_per_s']:.1f} steps/s")
    print(
        f"\nDiffusion Policy rollout cost, CPU ({os.cpu_count()} cores, load average {load_before:.1f} -> "
        f"{os.getloadavg()[0]:.1f}), {'checkpoint ' + args.checkpoint if ckpt else 'untrained weights'}"
    )
    print(
        "| scheduler | denoising steps | actions per prediction | torch threads | control steps/s | "
        "per CPU second | predicting step (ms) | its CPU ms |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['scheduler'].upper()} | {r['denoising_steps']} | {r['chunk']} | {r['threads']} | "
            f"{r['steps_per_s']:.1f} | {r['cpu_steps_per_s']:.1f} | {r['predict_ms']:.0f} | {r['predict_cpu_ms']:.0f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
