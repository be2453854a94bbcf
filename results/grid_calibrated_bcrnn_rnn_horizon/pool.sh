#!/bin/bash
# Session 56: BC-RNN's LSTM reset every 10 (stock), 20 or 30 rollout steps, pooled
cd "$(dirname "$0")/../.."  # the repository root
N=results/grid_calibrated_spacemouse_noops_seeds/results.json
X=results/grid_calibrated_bcrnn_50k_seeds/results.json
R=runs/rnnh56
rm -rf runs/grid_calibrated_bcrnn_rnn_horizon
.venv/bin/veragmil-pool-results runs/grid_calibrated_bcrnn_rnn_horizon/eval \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 10 seed 1=$N:spacemouse BC-RNN no-load obs no-noops seed 1" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 10 seed 2=$N:spacemouse BC-RNN no-load obs no-noops seed 2" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 10 seed 3=$N:spacemouse BC-RNN no-load obs no-noops seed 3" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 20 seed 1=$R/eval_seed1/results.json:seed 1 rnn.horizon 20" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 20 seed 2=$R/eval_seed2/results.json:seed 2 rnn.horizon 20" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 20 seed 3=$R/eval_seed3/results.json:seed 3 rnn.horizon 20" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 30 seed 1=$R/eval_seed1_h30/results.json:seed 1 rnn.horizon 30" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 30 seed 2=$R/eval_seed2_h30/results.json:seed 2 rnn.horizon 30" \
 --agent "spacemouse no-noops BC-RNN 20k rnn.horizon 30 seed 3=$R/eval_seed3_h30/results.json:seed 3 rnn.horizon 30" \
 --agent "expert BC-RNN 50k rnn.horizon 10 seed 2=$X:expert BC-RNN no-load obs seed 2" \
 --agent "expert BC-RNN 50k rnn.horizon 10 seed 3=$X:expert BC-RNN no-load obs seed 3" \
 --agent "expert BC-RNN 50k rnn.horizon 20 seed 2=$R/eval_expert50k_s2/results.json:expert BC-RNN 50k seed 2 rnn.horizon 20" \
 --agent "expert BC-RNN 50k rnn.horizon 20 seed 3=$R/eval_expert50k_s3/results.json:expert BC-RNN 50k seed 3 rnn.horizon 20" \
 --agent "expert BC-RNN 50k rnn.horizon 30 seed 2=$R/eval_expert50k_s2_h30/results.json:expert BC-RNN 50k seed 2 rnn.horizon 30" \
 --agent "expert BC-RNN 50k rnn.horizon 30 seed 3=$R/eval_expert50k_s3_h30/results.json:expert BC-RNN 50k seed 3 rnn.horizon 30"
echo "exit $?"
