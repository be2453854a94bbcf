"""
The probes' shared setup: Diffusion Policy's U-Net with configs/json/diffusion_policy.json's sizes, its AdamW, and one
training batch of the config's size (16 actions of 6 dimensions, noise steps drawn from 100), on 2 torch threads.
"""

import json
from pathlib import Path

import torch

from veragmil_suite.learning.algos.conditional_unet1d import ConditionalUnet1D

CONFIG = json.loads((Path(__file__).resolve().parents[2] / "configs" / "json" / "diffusion_policy.json").read_text())
HORIZON = CONFIG["algo"]["horizon"]["prediction_horizon"]


def unet_and_batch(
    cond_dim: int, down_dims: tuple[int, ...] | None = None
) -> tuple[ConditionalUnet1D, torch.optim.AdamW, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The U-Net conditioned on ``cond_dim`` features (its widths ``down_dims``, else the config's), its optimizer and a
    batch: actions, conditioning, noise steps."""
    unet, batch = CONFIG["algo"]["unet"], CONFIG["train"]["batch_size"]
    torch.set_num_threads(2)
    torch.manual_seed(0)
    net = ConditionalUnet1D(
        input_dim=6,
        global_cond_dim=cond_dim,
        diffusion_step_embed_dim=unet["diffusion_step_embed_dim"],
        down_dims=tuple(down_dims or unet["down_dims"]),
        kernel_size=unet["kernel_size"],
        n_groups=unet["n_groups"],
    )
    optimizer = torch.optim.AdamW(net.parameters(), lr=1e-4)
    actions, cond = torch.randn(batch, HORIZON, 6), torch.randn(batch, cond_dim)
    return net, optimizer, actions, cond, torch.randint(0, 100, (batch,))
