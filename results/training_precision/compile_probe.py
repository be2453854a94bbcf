"""
Diffusion Policy's U-Net (configs/json/diffusion_policy.json's sizes and batch, 16 actions of 6 dimensions,
conditioned on the 2 x 22 features of two `no-load-size` observations): a training step (forward, backward, AdamW)
eager and through torch.compile (inductor, CPU), on 2 torch threads. Run from the repository root:

    python results/training_precision/compile_probe.py > results/training_precision/compile_probe.txt
"""

import time
from functools import partial

import torch
from torch.nn import functional as F
from unet_batch import unet_and_batch

from veragmil_suite.utils.timing import per_call

net, optimizer, actions, cond, steps = unet_and_batch(cond_dim=44)


def train_step(model: torch.nn.Module) -> None:
    optimizer.zero_grad()
    F.mse_loss(model(actions, steps, global_cond=cond), actions).backward()
    optimizer.step()


compiled = torch.compile(net)
start = time.perf_counter()
train_step(compiled)
print(f"torch.compile and its first step: {time.perf_counter() - start:.0f} s", flush=True)
for name, model in (("eager", net), ("compiled", compiled), ("eager", net), ("compiled", compiled)):
    print(f"training step, {name}: {per_call(partial(train_step, model), calls=4, warmup=1).wall_s:.2f} s", flush=True)
