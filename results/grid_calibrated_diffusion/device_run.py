"""
Diffusion Policy for the grid on the calibrated physics, trained on a GPU machine.

``prepare`` (here, with the study's own arguments) writes each Diffusion Policy run's training config where
``veragmil-study`` looks for it (so the study skips the training and evaluates the checkpoint put beside it), the same
config for the GPU machine (training on CUDA with 4 loader workers, a checkpoint every 4 epochs, no TensorBoard:
tensorboardX is not there) and a copy of each data profile's dataset without simulator states (``slim_dataset.py``:
the machine takes 64 MiB of files). Several training seeds and data profiles make several runs; ``--only`` keeps
those whose experiment name matches.

``train`` (there) trains every run side by side until its time budget, then turns each run's newest checkpoint into
the one the rollouts use (``--keep``, at the path ``rebuild`` writes here) and writes the first run's EMA weights as
float16 in 8 pieces of under 16 MiB: the machine returns at most 8 files and 64 MiB a call, so pieces 0-3 come back
with the training call and ``ship`` sends the rest, for any run, in the calls after it.

``evaluate`` (there) scores the kept checkpoints with ``veragmil-evaluate`` on the GPU until its time budget; its
journal comes back, and ``veragmil-evaluate --resume`` here runs the episodes it did not reach.

``rebuild`` (here) joins the pieces into a robomimic checkpoint: float32 EMA weights as both the nets and the EMA
(the raw training weights, which no rollout uses, stay on the machine).

    python results/grid_calibrated_diffusion/device_run.py prepare -- <veragmil-study arguments>
    # run(command="bash results/grid_calibrated_diffusion/device_run.sh", carry=[".gpu", ".gl"], timeout_s=590)
    # run(command="python3 results/grid_calibrated_diffusion/device_run.py ship --out $OUT [--run N]", timeout_s=60)
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
import re
import shutil
import subprocess
import sys
import tarfile
import time
from pathlib import Path

GPU_DIR = Path(".gpu")
DEVICE_CONFIGS = GPU_DIR / "configs"  # each run's config for the machine, by run number
STUDY_CONFIGS = GPU_DIR / "study"  # each run's own config (the study's paths), for rebuild here and --keep there
PIECES = 8
PER_CALL = 4  # pieces back in a call: 4 x 16 MiB of the machine's 64 MiB
SAVE_EVERY = 4  # epochs between checkpoints on the machine
WORKERS = 4  # data loader workers of each run on the machine
WORK = Path("/tmp/dp")
KEPT = WORK / "kept.json"  # run number -> the checkpoint train --keep wrote and its figures
LOG_TAIL = 2**17  # bytes of each run's training log that come back


def _configs(folder: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(folder.glob("*.json"), key=lambda p: int(p.stem))]


def prepare(
    study_args: list[str], only: str | None = None, save_every: int = SAVE_EVERY, workers: int = WORKERS
) -> None:
    from slim_dataset import slim  # beside this script

    from veragmil_suite.scripts.study import build_parser, settings_from_args
    from veragmil_suite.study.pipeline import training_runs

    settings = settings_from_args(build_parser().parse_args(study_args))
    runs = [r for r in training_runs(settings) if r["algo"] == "diffusion_policy"]
    if only is not None:
        runs = [r for r in runs if re.fullmatch(only, r["config"]["experiment"]["name"])]
    if not runs:
        sys.exit("these study arguments make no diffusion_policy run" + (f" named {only}" if only else ""))
    for folder in (DEVICE_CONFIGS, STUDY_CONFIGS):
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
    datasets = {}  # the study's dataset -> its slim copy for the machine, one per data profile
    for i, run in enumerate(runs):
        config = run["config"]
        name = config["experiment"]["name"]
        Path(config["train"]["output_dir"]).mkdir(parents=True, exist_ok=True)
        (Path(config["train"]["output_dir"]) / f"{name}.json").write_text(json.dumps(config, indent=4))
        data = config["train"]["data"]
        if data not in datasets:
            datasets[data] = GPU_DIR / Path(data).name
            print(f"{data}: {slim(data, str(datasets[data]), config)} demos")
        device = copy.deepcopy(config)
        device["train"].update(data=str(datasets[data]), output_dir=str(WORK / "runs"), cuda=True)
        device["train"]["num_data_workers"] = workers
        device["experiment"]["save"]["every_n_epochs"] = save_every
        device["experiment"]["logging"]["log_tb"] = False
        (DEVICE_CONFIGS / f"{i}.json").write_text(json.dumps(device, indent=4))
        (STUDY_CONFIGS / f"{i}.json").write_text(json.dumps(config, indent=4))
        steps = config["experiment"]["epoch_every_n_steps"]
        print(f"run {i}: {name}, {config['train']['num_epochs']} x {steps} steps")


def _ema_blob(checkpoint: str) -> bytes:
    """A checkpoint with only its EMA weights, as float16 in the nets' state dict: what the rollouts use."""
    import torch

    ckpt = torch.load(checkpoint, map_location="cpu", weights_only=False)
    nets, ema = ckpt["model"]["nets"], dict(ckpt["model"]["ema"])
    shadow = ema.pop("shadow_params")
    if [tuple(v.shape) for v in nets.values()] != [tuple(v.shape) for v in shadow]:
        sys.exit("the EMA's weights do not line up with the nets' state dict")
    ckpt["model"] = dict(nets={k: v.half() for k, v in zip(nets, shadow)}, ema=ema)
    ckpt["epoch"] = int(Path(checkpoint).stem.rsplit("_", 1)[1])
    buffer = io.BytesIO()
    torch.save(ckpt, buffer)
    return buffer.getvalue()


def _checkpoint(blob: bytes, study: dict, early_dir: Path | None) -> tuple[Path, dict]:
    """The robomimic checkpoint of an EMA blob, with the study's config, and where it goes."""
    import torch

    ckpt = torch.load(io.BytesIO(blob), map_location="cpu", weights_only=False)
    nets = {k: v.float() for k, v in ckpt["model"]["nets"].items()}
    ckpt["model"] = dict(nets=nets, ema=dict(ckpt["model"]["ema"], shadow_params=[v.clone() for v in nets.values()]))
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
    return target, ckpt


def _pieces(blob: bytes, first: int, out: Path) -> None:
    size = math.ceil(len(blob) / PIECES)
    for i in range(first, min(first + PER_CALL, PIECES)):
        (out / f"ckpt.part{i}").write_bytes(blob[i * size : (i + 1) * size])


def train(out: Path, until: float, keep: bool, early_dir: Path | None) -> None:
    import torch

    configs, studies = _configs(DEVICE_CONFIGS), _configs(STUDY_CONFIGS)
    command = [sys.executable, "-c", "from veragmil_suite.scripts.robomimic_entry import train_main; train_main()"]
    t0 = time.time()
    WORK.mkdir(parents=True, exist_ok=True)
    logs = [open(WORK / f"train{i}.log", "w") for i in range(len(configs))]
    runs = [
        subprocess.Popen(command + ["--config", str(DEVICE_CONFIGS / f"{i}.json")], stdout=log, stderr=log)
        for i, log in enumerate(logs)
    ]
    for run in runs:  # side by side until the budget
        try:
            run.wait(timeout=max(1.0, until - time.time()))
        except subprocess.TimeoutExpired:
            run.kill()
            run.wait()
    trained = time.time() - t0
    for log in logs:
        log.close()
    summary, kept, text = [], {}, []
    for i, config in enumerate(configs):
        name = config["experiment"]["name"]
        # robomimic's epoch summaries without the progress bars
        lines = [line for line in (WORK / f"train{i}.log").read_text(errors="replace").splitlines() if "%|" not in line]
        text.append(f"==> run {i}: {name}\n" + "\n".join(lines)[-LOG_TAIL:] + "\n")
        saved = {int(Path(p).stem.rsplit("_", 1)[1]): p for p in glob.glob(str(WORK / f"runs/{name}/*/models/*.pth"))}
        if not saved:
            summary.append(dict(run=i, name=name, error=f"no checkpoint after {trained:.0f} s"))
            continue
        epoch, first = max(saved), min(saved)
        span_s = os.path.getmtime(saved[epoch]) - os.path.getmtime(saved[first])
        steps_per_epoch = config["experiment"]["epoch_every_n_steps"]
        blob = _ema_blob(saved[epoch])
        (WORK / f"blob{i}").write_bytes(blob)
        if i == 0:
            _pieces(blob, 0, out)
        if keep:
            target, ckpt = _checkpoint(blob, studies[i], early_dir)
            target.parent.mkdir(parents=True, exist_ok=True)
            torch.save(ckpt, target)
            kept[i] = dict(path=str(target), epoch=epoch, steps=epoch * steps_per_epoch, seed=config["train"]["seed"])
        summary.append(
            dict(
                run=i,
                name=name,
                epochs=epoch,
                epochs_asked=config["train"]["num_epochs"],
                gradient_steps=epoch * steps_per_epoch,
                steps_per_s_between_checkpoints=round((epoch - first) * steps_per_epoch / span_s, 2)
                if epoch > first
                else None,
                checkpoint_bytes_fp16=len(blob),
            )
        )
    (out / "train.txt").write_text("".join(text))
    KEPT.write_text(json.dumps(kept))
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    (out / "summary.json").write_text(json.dumps(dict(gpu=gpu, train_s=round(trained, 1), runs=summary), indent=2))
    print(json.dumps(summary), flush=True)


def evaluate(out: Path, until: float, name: str, evaluate_args: list[str]) -> None:
    """veragmil-evaluate on the kept checkpoints until ``until``; its output folder comes back."""
    kept = json.loads(KEPT.read_text())
    agents = []
    for run in kept.values():
        label = name.format(steps=f"{run['steps'] // 1000}k", seed=run["seed"])
        agents += ["--agent", f"{label}={run['path']}"]
    output = WORK / "eval"
    # the module, not the console script: the package is on PYTHONPATH there, not installed
    command = [sys.executable, "-m", "veragmil_suite.scripts.evaluate", *agents, "--output-dir", str(output), "--quiet"]
    t0 = time.time()
    try:
        subprocess.run(command + evaluate_args, timeout=max(1.0, until - time.time()), check=False)
    except subprocess.TimeoutExpired:
        pass
    print(f"evaluated for {time.time() - t0:.0f} s", flush=True)
    with tarfile.open(out / "eval.tar.gz", "w:gz") as tar:
        tar.add(output, arcname="eval")


def ship(out: Path, run: int, first: int) -> None:
    _pieces((WORK / f"blob{run}").read_bytes(), first, out)


def rebuild(folders: list[str], run: int, early_dir: Path | None) -> None:
    import torch

    pieces = {}
    for folder in folders:
        for p in Path(folder).glob("ckpt.part*"):
            pieces[int(p.name.removeprefix("ckpt.part"))] = p
    if sorted(pieces) != list(range(PIECES)):
        sys.exit(f"pieces {sorted(pieces)} of {PIECES}")
    blob = b"".join(pieces[i].read_bytes() for i in range(PIECES))
    target, ckpt = _checkpoint(blob, _configs(STUDY_CONFIGS)[run], early_dir)
    target.parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, target)
    print(f"wrote {target}")


def main() -> None:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="verb", required=True)
    q = sub.add_parser("prepare")
    q.add_argument("--only", help="the runs whose experiment name matches this regular expression")
    q.add_argument("--save-every", type=int, default=SAVE_EVERY, help="epochs between checkpoints on the machine")
    q.add_argument("--workers", type=int, default=WORKERS, help="data loader workers of each run on the machine")
    q.add_argument("study_args", nargs=argparse.REMAINDER, help="-- then veragmil-study's arguments")
    t = sub.add_parser("train")
    t.add_argument("--out", type=Path, required=True)
    t.add_argument("--until", type=float, required=True, help="when training stops (Unix time)")
    t.add_argument("--keep", action="store_true", help="write each run's rollout checkpoint there, for evaluate")
    e = sub.add_parser("evaluate")
    e.add_argument("--out", type=Path, required=True)
    e.add_argument("--until", type=float, required=True, help="when evaluation stops (Unix time)")
    e.add_argument("--name", required=True, help="agent name, with {steps} and {seed}")
    e.add_argument("evaluate_args", nargs=argparse.REMAINDER, help="-- then veragmil-evaluate's arguments")
    s = sub.add_parser("ship")
    s.add_argument("--out", type=Path, required=True)
    s.add_argument("--run", type=int, default=0, help="run number (prepare's order)")
    s.add_argument("--first", type=int, default=PER_CALL, help="first piece")
    r = sub.add_parser("rebuild")
    r.add_argument("folders", nargs="+")
    r.add_argument("--run", type=int, default=0, help="run number (prepare's order)")
    for q in (t, r):
        q.add_argument("--early-dir", type=Path, help="where a run stopped before its last epoch goes")
    args = p.parse_args()
    if args.verb == "prepare":
        prepare([a for a in args.study_args if a != "--"], args.only, args.save_every, args.workers)
    elif args.verb == "train":
        train(args.out, args.until, args.keep, args.early_dir)
    elif args.verb == "evaluate":
        evaluate(args.out, args.until, args.name, [a for a in args.evaluate_args if a != "--"])
    elif args.verb == "ship":
        ship(args.out, args.run, args.first)
    else:
        rebuild(args.folders, args.run, args.early_dir)


if __name__ == "__main__":
    main()
