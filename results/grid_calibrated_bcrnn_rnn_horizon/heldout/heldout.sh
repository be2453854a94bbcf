#!/bin/bash
# Sessions 56-57: the spacemouse cut-data BC-RNN seeds at reset periods 10 and 30, the expert BC-RNN 50k seeds at 10
# and 20, on other bowls (eval seed 200000 + i, 10 a food)
cd "$(dirname "$0")/../../.."  # the repository root
export MUJOCO_GL=osmesa PYOPENGL_PLATFORM=osmesa
S1=runs/grid_sm_noops_s1/runs/spacemouse_bc_rnn_30demos_20000steps_obs-no-load_no-noops/20261130193310/models/model_epoch_40.pth
S2=runs/grid_sm_noops_s23/runs/spacemouse_bc_rnn_30demos_20000steps_obs-no-load_no-noops_seed2/20261130212857/models/model_epoch_40.pth
S3=runs/grid_sm_noops_s23/runs/spacemouse_bc_rnn_30demos_20000steps_obs-no-load_no-noops_seed3/20261130221626/models/model_epoch_40.pth
C="--foods rice buckwheat barley pasta peas beans flakes --episodes 10 --seed 200000 --env-kwargs {\"physics\":\"calibrated\"} --processes 2 --quiet --resume"
for s in 3 1 2; do
  eval ck=\$S$s
  .venv/bin/veragmil-evaluate --agent "seed $s rnn.horizon 10=$ck" $C --output-dir runs/rnnh56/heldout_seed${s}_h10
  .venv/bin/veragmil-evaluate --agent "seed $s rnn.horizon 30=$ck" --rnn-horizon 30 $C --output-dir runs/rnnh56/heldout_seed${s}_h30
done
E2=runs/grid_bcrnn_50k_s2/runs/expert_bc_rnn_30demos_50000steps_obs-no-load_seed2/20261130095153/models/model_epoch_100.pth
E3=runs/grid_bcrnn_50k_s3/runs/expert_bc_rnn_30demos_50000steps_obs-no-load_seed3/20261130124301/models/model_epoch_100.pth
for s in 2 3; do
  eval ck=\$E$s
  .venv/bin/veragmil-evaluate --agent "seed $s rnn.horizon 10=$ck" $C --output-dir runs/rnnh57/heldout_expert_seed${s}_h10
  .venv/bin/veragmil-evaluate --agent "seed $s rnn.horizon 20=$ck" --rnn-horizon 20 $C --output-dir runs/rnnh57/heldout_expert_seed${s}_h20
done
echo "exit $?"
