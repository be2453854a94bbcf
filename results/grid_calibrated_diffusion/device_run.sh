#!/usr/bin/env bash
# The GPU machine's call, from the repository root (image_rgbd/bundle.sh made .gpu/ and .gl/ here, and
# device_run.py prepare the configs and dataset in .gpu/):
#   run(command="bash results/grid_calibrated_diffusion/device_run.sh", carry=[".gpu", ".gl"], timeout_s=590)
# Training stops TRAIN_END seconds after the start at the latest. With EVAL_END, the runs' checkpoints are then scored
# on the GPU (veragmil-evaluate EVAL_ARGS, agents named EVAL_NAME) until EVAL_END seconds after the start, on the
# settled piles carried in .gpu/piles; EARLY_DIR is where a checkpoint short of its last epoch goes (as rebuild's).
set -uo pipefail
start=$(date +%s)
TRAIN_END=${TRAIN_END:-500}
source results/image_rgbd/device_setup.sh
nvidia-smi -L; nproc; python3 -c "import numpy, torch, diffusers; print(numpy.__version__, torch.__version__, diffusers.__version__)"
echo "setup: $(( $(date +%s) - start )) s"
keep=()
[ -n "${EVAL_END:-}" ] && keep=(--keep --early-dir "${EARLY_DIR:-runs}")
python3 results/grid_calibrated_diffusion/device_run.py train --out "$OUT" --until $(( start + TRAIN_END )) "${keep[@]}"
grep -E "^==> run|^Train Epoch|\"Loss\"|Epoch [0-9]+ Memory" "$OUT/train.txt" | tail -n 80
echo "trained: $(( $(date +%s) - start )) s"
if [ -n "${EVAL_END:-}" ]; then
    mkdir -p /tmp/piles && cp .gpu/piles/* /tmp/piles/ 2>/dev/null
    export VERAGMIL_CACHE_DIR=/tmp/piles
    python3 results/grid_calibrated_diffusion/device_run.py evaluate --out "$OUT" --until $(( start + EVAL_END )) \
        --name "$EVAL_NAME" -- $EVAL_ARGS
    tar xzf "$OUT/eval.tar.gz" -O eval/table.md 2>/dev/null | head -n 12
    echo "piles settled there: $(( $(ls /tmp/piles | wc -l) - $(ls .gpu/piles | wc -l) ))"
fi
echo "done: $(( $(date +%s) - start )) s"
