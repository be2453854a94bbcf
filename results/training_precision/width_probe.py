"""
Diffusion Policy's U-Net at three widths: configs/json/diffusion_policy.json's (256-512-1024), diffusion_policy_small's
(128-256-512) and half that again (64-128-256), each a training step (forward, backward, AdamW) on the config's batch
conditioned on the 2 x 22 `no-load-size` features, and one denoising step for one observation, on 2 torch threads.
Run from the repository root:

    python results/training_precision/width_probe.py > results/training_precision/width_probe.txt
"""

import json
from pathlib import Path

import torch
from torch.nn import functional as F
from unet_batch import HORIZON, unet_and_batch

from veragmil_suite.utils.timing import per_call

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "json"
SMALL = json.loads((CONFIGS / "diffusion_policy_small.json").read_text())
WIDTHS = [(256, 512, 1024), tuple(SMALL["algo"]["unet"]["down_dims"]), (64, 128, 256)]


def probe(down_dims: tuple[int, ...]) -> str:
    """One line: the U-Net's weights, its training step and one denoising step."""
    net, optimizer, actions, cond, steps = unet_and_batch(cond_dim=44, down_dims=down_dims)

    def train_step() -> None:
        optimizer.zero_grad()
        F.mse_loss(net(actions, steps, global_cond=cond), actions).backward()
        optimizer.step()

    noisy, step = torch.randn(1, HORIZON, 6), torch.tensor([5])  # drawn once: the timed call is the network's

    def denoise_step() -> None:
        with torch.no_grad():
            net(noisy, step, global_cond=cond[:1])

    weights = sum(p.numel() for p in net.parameters()) / 1e6
    step_s = per_call(train_step, calls=6, warmup=2).wall_s
    denoise_ms = per_call(denoise_step, calls=20, warmup=3).wall_s * 1000
    return (
        f"U-Net {'-'.join(map(str, down_dims))}: {weights:.1f}M weights, training step {step_s:.2f} s, "
        f"denoising step {denoise_ms:.0f} ms"
    )


for widths in WIDTHS:
    print(probe(widths), flush=True)
