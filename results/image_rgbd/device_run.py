"""
Trains the paper's sensor setup, robomimic BC-RNN on overhead RGB-D (configs/json/bc_rnn_rgbd.json), on a GPU
machine that holds no dataset: it records the `expert` demos with the camera on (the four training foods at once,
in worker processes), trains for a wall-clock budget, and writes the newest checkpoint (weights as float16, in
15 MiB pieces: the machine returns files of at most 16 MiB) and the training log to --out.

    python results/image_rgbd/device_run.py --out $OUT --train-until $(( $(date +%s) + 400 ))

Run by results/image_rgbd/device_run.sh; the checkpoint is rebuilt and evaluated on this 2-core machine (RUN.md).
"""

from __future__ import annotations

import argparse
import glob
import io
import json
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

CHUNK = 15 * 2**20


def record(path: str, food: str, demos: int, processes: int) -> None:
    """One training food's demos with the overhead RGB-D camera (the study's seeds), in its own worker processes."""
    from veragmil_suite.data.collection import record_scripted, recording_env_kwargs
    from veragmil_suite.study.record import food_seed

    kwargs = recording_env_kwargs("XArm7", food, cameras=("overhead",), depth=True)
    outcome = record_scripted(path, kwargs, demos, profile="expert", seed=food_seed(0, food), processes=processes)
    print(f"{food}: {outcome.summary()}", flush=True)
    if outcome.kept < demos:
        raise SystemExit(f"{food}: kept {outcome.kept} of {demos} demos")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--work", default="/tmp/rgbd")
    p.add_argument("--demos-per-food", type=int, default=30)
    p.add_argument("--processes", type=int, default=16)
    p.add_argument("--train-until", type=float, required=True, help="when training stops (Unix time)")
    p.add_argument("--steps-per-epoch", type=int, default=250)
    p.add_argument("--loader-workers", type=int, default=6)
    p.add_argument("--config", default="bc_rnn_rgbd")
    args = p.parse_args()
    out, work = Path(args.out), Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    started = time.time()

    from veragmil_suite.models.foods import TRAINING_FOODS
    from veragmil_suite.study.record import merge_profile_dataset

    files = [work / "expert" / f"{food}.hdf5" for food in TRAINING_FOODS]
    files[0].parent.mkdir(parents=True, exist_ok=True)
    per_food = max(1, args.processes // len(TRAINING_FOODS))
    # one (non-daemonic) process per food: record_scripted starts worker processes of its own
    context = multiprocessing.get_context("spawn")
    foods = [
        context.Process(target=record, args=(str(f), food, args.demos_per_food, per_food))
        for f, food in zip(files, TRAINING_FOODS)
    ]
    for process in foods:
        process.start()
    for process in foods:
        process.join()
    if any(process.exitcode != 0 for process in foods):
        sys.exit("recording failed")
    dataset = work / "expert.hdf5"
    merge_profile_dataset(dataset, files, [args.demos_per_food])
    recorded = time.time() - started
    print(f"recorded {len(files)} x {args.demos_per_food} demos with overhead RGB-D in {recorded:.0f} s", flush=True)

    from veragmil_suite.learning.algorithms import StudyAlgorithm, register_algorithm
    from veragmil_suite.study.training import training_config

    register_algorithm(StudyAlgorithm(args.config, args.config, "BC-RNN RGB-D"))
    config = training_config(args.config, dataset, work / "runs", "rgbd", 100000, args.steps_per_epoch)
    config["experiment"]["save"]["every_n_epochs"] = 1
    config["experiment"]["logging"]["log_tb"] = False  # tensorboardX is not on the machine
    config["train"]["num_data_workers"] = args.loader_workers
    config_path = work / "rgbd.json"
    config_path.write_text(json.dumps(config, indent=2))
    train = [sys.executable, "-c", "from veragmil_suite.scripts.robomimic_entry import train_main; train_main()"]
    train += ["--config", str(config_path)]
    log = out / "train.log"
    t0 = time.time()
    with open(log, "w") as f:
        try:
            timeout = max(90.0, args.train_until - time.time())
            subprocess.run(train, stdout=f, stderr=subprocess.STDOUT, timeout=timeout, check=False)
        except subprocess.TimeoutExpired:
            pass
    trained = time.time() - t0

    import torch
    from rebuild_checkpoint import cast_floats  # beside this script

    paths = glob.glob(str(work / "runs/rgbd/*/models/model_epoch_*.pth"))
    saved = {int(Path(c).stem.rsplit("_", 1)[1]): c for c in paths}  # by epoch
    if not saved:
        print(f"no checkpoint after {trained:.0f} s of training; see train.log", flush=True)
        sys.exit(1)
    epoch = max(saved)
    newest = saved[epoch]
    times = sorted(os.path.getmtime(c) for c in saved.values())
    rate = (len(times) - 1) * args.steps_per_epoch / (times[-1] - times[0]) if len(times) > 1 else float("nan")
    ckpt = torch.load(newest, map_location="cpu", weights_only=False)
    ckpt["model"] = cast_floats(ckpt["model"], torch.float16)  # half the bytes to carry back
    buffer = io.BytesIO()
    torch.save(ckpt, buffer)
    blob = buffer.getvalue()
    for i in range(0, len(blob), CHUNK):
        (out / f"ckpt.part{i // CHUNK}").write_bytes(blob[i : i + CHUNK])
    summary = dict(
        gpu=torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        demos_per_food=args.demos_per_food,
        record_s=round(recorded, 1),
        train_s=round(trained, 1),
        epochs=epoch,
        gradient_steps=epoch * args.steps_per_epoch,
        steps_per_s_between_checkpoints=round(rate, 2),
        checkpoint=newest,
        checkpoint_bytes_fp16=len(blob),
        config=config,
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps({k: v for k, v in summary.items() if k != "config"}), flush=True)


if __name__ == "__main__":
    main()
