"""
Diffusion Policy for the grid on the calibrated physics, trained on a GPU machine.

``prepare`` (here, with the study's own arguments) writes the study's training config where ``veragmil-study`` looks
for it (so the study skips the training and evaluates the checkpoint put beside it), the same config for the GPU
machine (training on CUDA with 4 loader workers, a checkpoint every 4 epochs, no TensorBoard: tensorboardX is not
there) and a copy of the dataset without simulator states (``slim_dataset.py``: the machine takes 64 MiB of files).

``train`` (there) trains until its time budget, then writes the newest checkpoint's EMA weights, the weights
Diffusion Policy acts with, as float16 in 8 pieces of under 16 MiB: the machine returns at most 8 files and 64 MiB a
call, so pieces 0-3 come back with the training call and ``ship`` sends pieces 4-7 in the next.

``rebuild`` (here) joins the pieces into a robomimic checkpoint: float32 EMA weights as both the nets and the EMA
(the raw training weights, which no rollout uses, stay on the machine).

    python results/grid_calibrated_diffusion/device_run.py prepare -- <veragmil-study arguments>
    # run(command="bash results/grid_calibrated_diffusion/device_run.sh", carry=[".gpu"], timeout_s=590)
    # run(command="python3 results/grid_calibrated_diffusion/device_run.py ship --out $OUT", timeout_s=60)
    python results/grid_calibrated_diffusion/device_run.py rebuild <files_at 1> <files_at 2> [--early-dir DIR]
"""

from __future__ import annotations

import argparse
import copy
import glob
import io
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

GPU_DIR = Path(".gpu")
PIECES = 8
FIRST_CALL = 4  # pieces back with the training call
SAVE_EVERY = 4  # epochs between checkpoints on the machine
WORK = Path("/tmp/dp")
STUDY_CONFIG = "study_config.json"  # the study's own training config, kept here by prepare


def prepare(study_args: list[str]) -> None:
    from slim_dataset import slim  # beside this script

    from veragmil_suite.scripts.study import build_parser, settings_from_args
    from veragmil_suite.study.pipeline import training_runs

    settings = settings_from_args(build_parser().parse_args(study_args))
    (run,) = [r for r in training_runs(settings) if r["algo"] == "diffusion_policy"]
    config = run["config"]
    name = config["experiment"]["name"]
    runs = Path(config["train"]["output_dir"])
    runs.mkdir(parents=True, exist_ok=True)
    (runs / f"{name}.json").write_text(json.dumps(config, indent=4))
    device = copy.deepcopy(config)
    device["train"].update(data=str(GPU_DIR / "dataset.hdf5"), output_dir=str(WORK / "runs"), cuda=True)
    device["train"]["num_data_workers"] = 4
    device["experiment"]["save"]["every_n_epochs"] = SAVE_EVERY
    device["experiment"]["logging"]["log_tb"] = False
    GPU_DIR.mkdir(exist_ok=True)
    (GPU_DIR / "config.json").write_text(json.dumps(device, indent=4))
    (GPU_DIR / STUDY_CONFIG).write_text(json.dumps(config, indent=4))  # for rebuild: where the study looks
    demos = slim(config["train"]["data"], str(GPU_DIR / "dataset.hdf5"), config)
    steps = config["experiment"]["epoch_every_n_steps"]
    print(f"{name}: {demos} demos, {config['train']['num_epochs']} x {steps} steps")


def train(out: Path, until: float) -> None:
    import torch

    config = json.loads((GPU_DIR / "config.json").read_text())
    command = [sys.executable, "-c", "from veragmil_suite.scripts.robomimic_entry import train_main; train_main()"]
    t0 = time.time()
    WORK.mkdir(parents=True, exist_ok=True)
    with open(WORK / "train.log", "w") as log:
        try:
            subprocess.run(
                command + ["--config", str(GPU_DIR / "config.json")],
                stdout=log,
                stderr=log,
                timeout=max(60.0, until - time.time()),
                check=False,
            )
        except subprocess.TimeoutExpired:
            pass
    trained = time.time() - t0
    # robomimic's epoch summaries without the progress bars, at most 256 KiB: the pieces leave little of the 64 MiB
    lines = [line for line in (WORK / "train.log").read_text(errors="replace").splitlines() if "%|" not in line]
    (out / "train.txt").write_text("\n".join(lines)[-(2**18) :] + "\n")
    saved = {int(Path(p).stem.rsplit("_", 1)[1]): p for p in glob.glob(str(WORK / "runs/*/*/models/*.pth"))}
    if not saved:
        sys.exit(f"no checkpoint after {trained:.0f} s of training; see train.txt")
    epoch, first = max(saved), min(saved)
    span_s = os.path.getmtime(saved[epoch]) - os.path.getmtime(saved[first])
    steps_per_epoch = config["experiment"]["epoch_every_n_steps"]
    ckpt = torch.load(saved[epoch], map_location="cpu", weights_only=False)
    nets, ema = ckpt["model"]["nets"], dict(ckpt["model"]["ema"])
    shadow = ema.pop("shadow_params")
    if [tuple(v.shape) for v in nets.values()] != [tuple(v.shape) for v in shadow]:
        sys.exit("the EMA's weights do not line up with the nets' state dict")
    ckpt["model"] = dict(nets={k: v.half() for k, v in zip(nets, shadow)}, ema=ema)
    ckpt["epoch"] = epoch
    buffer = io.BytesIO()
    torch.save(ckpt, buffer)
    blob = buffer.getvalue()
    size = math.ceil(len(blob) / PIECES)
    parts = WORK / "parts"
    parts.mkdir(parents=True, exist_ok=True)
    for i in range(PIECES):
        target = out if i < FIRST_CALL else parts
        (target / f"ckpt.part{i}").write_bytes(blob[i * size : (i + 1) * size])
    summary = dict(
        gpu=torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        train_s=round(trained, 1),
        epochs=epoch,
        epochs_asked=config["train"]["num_epochs"],
        gradient_steps=epoch * steps_per_epoch,
        steps_per_s_between_checkpoints=round((epoch - first) * steps_per_epoch / span_s, 2) if epoch > first else None,
        checkpoint_bytes_fp16=len(blob),
        piece_bytes=size,
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary), flush=True)


def ship(out: Path) -> None:
    for i in range(FIRST_CALL, PIECES):
        (out / f"ckpt.part{i}").write_bytes((WORK / "parts" / f"ckpt.part{i}").read_bytes())


def rebuild(folders: list[str], early_dir: Path | None) -> None:
    import torch

    pieces = {}
    for folder in folders:
        for p in Path(folder).glob("ckpt.part*"):
            pieces[int(p.name.removeprefix("ckpt.part"))] = p
    if sorted(pieces) != list(range(PIECES)):
        sys.exit(f"pieces {sorted(pieces)} of {PIECES}")
    blob = b"".join(pieces[i].read_bytes() for i in range(PIECES))
    ckpt = torch.load(io.BytesIO(blob), map_location="cpu", weights_only=False)
    nets = {k: v.float() for k, v in ckpt["model"]["nets"].items()}
    ckpt["model"] = dict(nets=nets, ema=dict(ckpt["model"]["ema"], shadow_params=[v.clone() for v in nets.values()]))
    study = json.loads((GPU_DIR / STUDY_CONFIG).read_text())
    name = study["experiment"]["name"]
    if json.loads(ckpt["config"])["experiment"]["name"] != name:
        sys.exit(f"the pieces are not of {name}, the run prepare made")
    ckpt["config"] = json.dumps(study, indent=4)  # the study's paths; the training is the same
    epoch, reached = study["train"]["num_epochs"], ckpt.pop("epoch")
    models = Path(study["train"]["output_dir"]) / name / "device" / "models"
    # a run its time budget stopped early keeps its own epoch's name: the study evaluates only its last epoch
    target = models / f"model_epoch_{reached}.pth"
    if reached != epoch and early_dir is not None:
        target = early_dir / f"{name}_epoch_{reached}.pth"
    target.parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, target)
    print(f"wrote {target}")


def main() -> None:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="verb", required=True)
    sub.add_parser("prepare").add_argument("study_args", nargs=argparse.REMAINDER)
    t = sub.add_parser("train")
    t.add_argument("--out", type=Path, required=True)
    t.add_argument("--until", type=float, required=True, help="when training stops (Unix time)")
    sub.add_parser("ship").add_argument("--out", type=Path, required=True)
    r = sub.add_parser("rebuild")
    r.add_argument("folders", nargs="+")
    r.add_argument("--early-dir", type=Path, help="where a run stopped before its last epoch goes (default: beside it)")
    args = p.parse_args()
    if args.verb == "prepare":
        prepare([a for a in args.study_args if a != "--"])
    elif args.verb == "train":
        train(args.out, args.until)
    elif args.verb == "ship":
        ship(args.out)
    else:
        rebuild(args.folders, args.early_dir)


if __name__ == "__main__":
    main()
