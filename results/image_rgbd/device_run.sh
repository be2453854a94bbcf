#!/usr/bin/env bash
# The GPU machine's whole job, from the repository root (bundle.sh made .gpu/ and .gl/ here first):
#   run(command="bash results/image_rgbd/device_run.sh", carry=[".gpu", ".gl"], timeout_s=580)
# Training stops TRAIN_END seconds after the start; the training benchmark on the recorded data follows.
set -uo pipefail
start=$(date +%s)
TRAIN_END=${TRAIN_END:-430}
source results/image_rgbd/device_setup.sh
export VERAGMIL_CACHE_DIR=/tmp/piles
nvidia-smi -L; nproc; python3 -c "import numpy, torch; print(numpy.__version__, torch.__version__)"
python3 - <<'PY' || exit 1
import time, robosuite, veragmil_suite
t = time.time()
env = robosuite.make("ScoopGranular", use_camera_obs=True, has_offscreen_renderer=True, camera_names="overhead",
                     camera_depths=True, camera_heights=84, camera_widths=84, food="rice")
obs = env.reset()
print("smoke: overhead", obs["overhead_image"].shape, obs["overhead_depth"].shape, f"{time.time() - t:.1f} s")
PY
echo "setup and smoke test: $(( $(date +%s) - start )) s"
python3 results/image_rgbd/device_run.py --out "$OUT" --train-until $(( start + TRAIN_END ))
echo "trained: $(( $(date +%s) - start )) s"
left=$(( 560 - ($(date +%s) - start) ))
[ -f /tmp/rgbd/expert.hdf5 ] && [ $left -gt 40 ] && timeout $(( left - 10 )) python3 benchmarks/bench_training.py \
    --device cuda --dataset /tmp/rgbd/expert.hdf5 --algos diffusion_policy bc bc_rnn bcq bc_rnn_rgbd \
    --steps 100 --image-steps 20 --diffusion-steps 30 --threads 16 2>&1 | grep -E "steps/s|^\||throughput|Error" > "$OUT/bench.txt"
cat "$OUT/bench.txt" 2>/dev/null
echo "done: $(( $(date +%s) - start )) s"
