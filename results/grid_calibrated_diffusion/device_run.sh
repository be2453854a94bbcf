#!/usr/bin/env bash
# The GPU machine's training call, from the repository root (image_rgbd/bundle.sh made .gpu/ and .gl/ here, and
# device_run.py prepare the config and dataset in .gpu/):
#   run(command="bash results/grid_calibrated_diffusion/device_run.sh", carry=[".gpu", ".gl"], timeout_s=590)
# Training stops TRAIN_END seconds after the start at the latest.
set -uo pipefail
start=$(date +%s)
TRAIN_END=${TRAIN_END:-500}
source results/image_rgbd/device_setup.sh
nvidia-smi -L; nproc; python3 -c "import numpy, torch, diffusers; print(numpy.__version__, torch.__version__, diffusers.__version__)"
echo "setup: $(( $(date +%s) - start )) s"
python3 results/grid_calibrated_diffusion/device_run.py train --out "$OUT" --until $(( start + TRAIN_END ))
grep -E "^Train Epoch|\"Loss\"|Epoch [0-9]+ Memory" "$OUT/train.txt" | tail -n 60
tail -n 3 "$OUT/train.txt"
echo "done: $(( $(date +%s) - start )) s"
