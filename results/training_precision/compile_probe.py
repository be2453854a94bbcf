"""
Diffusion Policy's U-Net (configs/json/diffusion_policy.json's sizes and batch, 16 actions of 6 dimensions,
conditioned on the 2 x 22 features of two `no-load-size` observations): a training step (forward, backward, AdamW)
eager and through torch.compile (inductor, CPU), on 2 torch threads. Run from the repository root:

    python results/training_precision/compile_probe.py > results/training_precision/compile_probe.txt
"""

import json
import time
from functools import partial
from pathlib import Path

import torch
from torch.nn import functional as F

from veragmil_suite.learning.algos.conditional_unet1d import ConditionalUnet1D
from veragmil_suite.utils.timing import per_call

config = json.loads((Path(__file__).resolve().parents[2] / "configs" / "json" / "diffusion_policy.json").read_text())
unet, batch = config["algo"]["unet"], config["train"]["batch_size"]
horizon = config["algo"]["horizon"]["prediction_horizon"]
torch.set_num_threads(2)
torch.manual_seed(0)
net = ConditionalUnet1D(
    input_dim=6,
    global_cond_dim=44,
    diffusion_step_embed_dim=unet["diffusion_step_embed_dim"],
    down_dims=tuple(unet["down_dims"]),
    kernel_size=unet["kernel_size"],
    n_groups=unet["n_groups"],
)
optimizer = torch.optim.AdamW(net.parameters(), lr=1e-4)
actions, cond = torch.randn(batch, horizon, 6), torch.randn(batch, 44)
steps = torch.randint(0, 100, (batch,))


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
