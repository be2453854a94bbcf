"""
Diffusion Policy's U-Net alone (the config's sizes, batch 100, 16 actions, 2 observations of 40 features) in float32
and under torch's autocast to bfloat16: a training step (forward, backward, AdamW) and one denoising step for one
observation, on 2 torch threads. Run from the repository root:

    python results/training_precision/unet_probe.py > results/training_precision/unet_probe.txt
"""

import time

import torch
from torch.nn import functional as F

from veragmil_suite.learning.algos.conditional_unet1d import ConditionalUnet1D

torch.set_num_threads(2)
torch.manual_seed(0)
net = ConditionalUnet1D(
    input_dim=6,
    global_cond_dim=2 * 40,
    diffusion_step_embed_dim=256,
    down_dims=(256, 512, 1024),
    kernel_size=5,
    n_groups=8,
)
optimizer = torch.optim.AdamW(net.parameters(), lr=1e-4)
actions, cond, steps = torch.randn(100, 16, 6), torch.randn(100, 80), torch.randint(0, 100, (100,))


def autocast(bf16: bool) -> torch.autocast:
    return torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16)


def train_step(bf16: bool) -> None:
    optimizer.zero_grad()
    with autocast(bf16):
        prediction = net(actions, steps, global_cond=cond)
    F.mse_loss(prediction.float(), actions).backward()
    optimizer.step()


for bf16 in (False, True, False, True):  # twice each, alternating: the host's load drifts
    train_step(bf16)
    train_step(bf16)
    started = time.perf_counter()
    for _ in range(4):
        train_step(bf16)
    print(f"training step, {'bf16' if bf16 else 'fp32'}: {(time.perf_counter() - started) / 4:.2f} s", flush=True)

one_action, one_cond, one_step = torch.randn(1, 16, 6), torch.randn(1, 80), torch.tensor([5])
with torch.no_grad():
    for bf16 in (False, True):
        for _ in range(3):
            with autocast(bf16):
                net(one_action, one_step, global_cond=one_cond)
        started = time.perf_counter()
        for _ in range(20):
            with autocast(bf16):
                net(one_action, one_step, global_cond=one_cond)
        elapsed_ms = (time.perf_counter() - started) / 20 * 1000
        print(f"denoising step, one observation, {'bf16' if bf16 else 'fp32'}: {elapsed_ms:.0f} ms")
