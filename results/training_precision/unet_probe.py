"""
Diffusion Policy's U-Net alone (configs/json/diffusion_policy.json's sizes and batch, 16 actions of 6 dimensions,
conditioned on 80 features: wider than the 2 x 22 of two `no-load-size` observations, a small share of the U-Net's
cost) in float32 and under torch's autocast to bfloat16: a training step (forward, backward, AdamW) and one denoising
step for one observation, on 2 torch threads. Run from the repository root:

    python results/training_precision/unet_probe.py > results/training_precision/unet_probe.txt
"""

from functools import partial

import torch
from torch.nn import functional as F
from unet_batch import HORIZON, unet_and_batch

from veragmil_suite.utils.timing import per_call

net, optimizer, actions, cond, steps = unet_and_batch(cond_dim=80)


def autocast(bf16: bool) -> torch.autocast:
    return torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16)


def train_step(bf16: bool) -> None:
    optimizer.zero_grad()
    with autocast(bf16):
        prediction = net(actions, steps, global_cond=cond)
    F.mse_loss(prediction.float(), actions).backward()
    optimizer.step()


def denoise_step(bf16: bool) -> None:
    with torch.no_grad(), autocast(bf16):
        net(one_action, one_step, global_cond=one_cond)


for bf16 in (False, True, False, True):  # twice each, alternating: the host's load drifts
    seconds = per_call(partial(train_step, bf16), calls=4, warmup=2).wall_s
    print(f"training step, {'bf16' if bf16 else 'fp32'}: {seconds:.2f} s", flush=True)

one_action, one_cond, one_step = torch.randn(1, HORIZON, 6), torch.randn(1, cond.shape[1]), torch.tensor([5])
for bf16 in (False, True):
    elapsed_ms = per_call(partial(denoise_step, bf16), calls=20, warmup=3).wall_s * 1000
    print(f"denoising step, one observation, {'bf16' if bf16 else 'fp32'}: {elapsed_ms:.0f} ms")
