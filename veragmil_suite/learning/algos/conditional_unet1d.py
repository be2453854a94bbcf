"""
Diffusion Policy's noise prediction network (Chi et al., RSS 2023): a 1D temporal U-Net over a sequence of actions,
conditioned by FiLM on the diffusion step and the observations.

The noisy action sequence (batch, time, action) is convolved along time. Each level of the U-Net holds two residual
blocks of (Conv1d, GroupNorm, Mish) layers; the time resolution halves between levels on the way down and doubles on
the way up, where each level also takes the features of the level of equal resolution on the way down (skip
connections). Every residual block is conditioned on one vector, the sinusoidal embedding of the diffusion step
(through a small MLP) concatenated with the flattened observation features: a linear map of it gives a scale and a
bias per channel (FiLM), applied after the block's first layer.
"""

from __future__ import annotations

import functools
import math

import torch
from torch import nn


class SinusoidalStepEmbedding(nn.Module):
    """The Transformer's sinusoidal position embedding, of the diffusion step."""

    def __init__(self, dim: int):
        super().__init__()
        if dim % 2 or dim < 4:
            raise ValueError(f"the diffusion step embedding needs an even width of at least 4, got {dim}")
        self.dim = dim

    def forward(self, steps: torch.Tensor) -> torch.Tensor:
        half = self.dim // 2
        frequencies = torch.exp(
            torch.arange(half, device=steps.device, dtype=torch.float32) * (-math.log(10000.0) / (half - 1))
        )
        angles = steps.float()[:, None] * frequencies[None, :]
        return torch.cat([angles.sin(), angles.cos()], dim=-1)


class ConvNormMish(nn.Sequential):
    """Conv1d along time (same length), GroupNorm, Mish."""

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, n_groups: int):
        super().__init__(
            nn.Conv1d(in_channels, out_channels, kernel_size, padding=kernel_size // 2),
            nn.GroupNorm(n_groups, out_channels),
            nn.Mish(),
        )


class FiLMResidualBlock(nn.Module):
    """Two ConvNormMish layers with a residual connection; the conditioning scales and shifts the first's output."""

    def __init__(self, in_channels: int, out_channels: int, cond_dim: int, kernel_size: int, n_groups: int):
        super().__init__()
        self.first = ConvNormMish(in_channels, out_channels, kernel_size, n_groups)
        self.second = ConvNormMish(out_channels, out_channels, kernel_size, n_groups)
        self.film = nn.Sequential(nn.Mish(), nn.Linear(cond_dim, 2 * out_channels))
        self.residual = nn.Conv1d(in_channels, out_channels, 1) if in_channels != out_channels else nn.Identity()

    def forward(self, x: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        scale, bias = self.film(cond).unsqueeze(-1).chunk(2, dim=1)
        return self.second(scale * self.first(x) + bias) + self.residual(x)


class ConditionalUnet1D(nn.Module):
    """
    Predicts the noise (or the clean sequence) of a noisy action sequence from its diffusion step and a global
    conditioning vector (the observation features).

    Args:
        input_dim: action dimension
        global_cond_dim: width of the conditioning vector (observation features x observation horizon)
        diffusion_step_embed_dim: width of the diffusion step's embedding
        down_dims: channels of the levels, finest first; the sequence length must be a multiple of
            2 ** (len(down_dims) - 1)
        kernel_size: temporal convolution kernel (odd)
        n_groups: GroupNorm groups (dividing every level's channels)
    """

    def __init__(
        self,
        input_dim: int,
        global_cond_dim: int,
        diffusion_step_embed_dim: int = 256,
        down_dims: tuple[int, ...] = (256, 512, 1024),
        kernel_size: int = 5,
        n_groups: int = 8,
    ):
        super().__init__()
        down_dims = [int(d) for d in down_dims]
        if not down_dims or kernel_size % 2 == 0 or any(d % n_groups for d in down_dims):
            raise ValueError(
                f"the U-Net needs at least one level, an odd kernel and channels divisible by n_groups ({n_groups}); "
                f"got down_dims {down_dims} and kernel_size {kernel_size}"
            )
        width = diffusion_step_embed_dim
        self.step_encoder = nn.Sequential(
            SinusoidalStepEmbedding(width), nn.Linear(width, 4 * width), nn.Mish(), nn.Linear(4 * width, width)
        )
        block = functools.partial(
            FiLMResidualBlock, cond_dim=width + global_cond_dim, kernel_size=kernel_size, n_groups=n_groups
        )
        widths = [input_dim, *down_dims]
        self.down = nn.ModuleList()
        for level, (w_in, w_out) in enumerate(zip(widths[:-1], widths[1:])):
            coarsest = level == len(down_dims) - 1
            downsample = nn.Identity() if coarsest else nn.Conv1d(w_out, w_out, 3, stride=2, padding=1)
            self.down.append(nn.ModuleList([block(w_in, w_out), block(w_out, w_out), downsample]))
        self.mid = nn.ModuleList([block(down_dims[-1], down_dims[-1]), block(down_dims[-1], down_dims[-1])])
        # each level on the way up takes the coarser level's output beside its skip connection, of the same width
        self.up = nn.ModuleList()
        for w_out, w_coarse in reversed(list(zip(down_dims[:-1], down_dims[1:]))):
            upsample = nn.ConvTranspose1d(w_out, w_out, 4, stride=2, padding=1)
            self.up.append(nn.ModuleList([block(2 * w_coarse, w_out), block(w_out, w_out), upsample]))
        self.head = nn.Sequential(
            ConvNormMish(down_dims[0], down_dims[0], kernel_size, n_groups), nn.Conv1d(down_dims[0], input_dim, 1)
        )

    def forward(self, sample: torch.Tensor, steps: torch.Tensor | int, global_cond: torch.Tensor) -> torch.Tensor:
        """
        Args:
            sample: noisy action sequences (batch, time, action)
            steps: diffusion steps, one per sequence (batch,) or one for all
            global_cond: conditioning vectors (batch, global_cond_dim)

        Returns:
            the prediction, of the sample's shape
        """
        resolution = 2 ** (len(self.down) - 1)
        if sample.shape[1] % resolution:
            raise ValueError(f"sequence length {sample.shape[1]} is not a multiple of the U-Net's {resolution}")
        steps = torch.as_tensor(steps, device=sample.device).reshape(-1).expand(sample.shape[0])
        cond = torch.cat([self.step_encoder(steps), global_cond], dim=-1)
        x = sample.transpose(1, 2)
        skips = []
        for first, second, downsample in self.down:
            x = second(first(x, cond), cond)
            skips.append(x)
            x = downsample(x)
        for block in self.mid:
            x = block(x, cond)
        for first, second, upsample in self.up:
            x = torch.cat([x, skips.pop()], dim=1)
            x = upsample(second(first(x, cond), cond))
        return self.head(x).transpose(1, 2)
