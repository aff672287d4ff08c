"""Positional encoding gamma(p) on coordinates normalised to the scene bounds.

gamma(p) = [x, sin(2^l pi x), cos(2^l pi x)] for l = 0..L-1, with x = (p - centre) / h, where
h is half the longest edge of the bounds, so the scene maps into [-1, 1]^3 with one scale on
every axis (spheres stay spheres). Level l has period 2 / 2^l in x, that is S / 2^l metres
for a scene of longest edge S.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

__all__ = ["PositionalEncoding", "levels_for"]


def levels_for(scene_size_m: float, feature_size_m: float) -> int:
    """Number of levels L whose finest half-period S / 2^L is at most ``feature_size_m``.

    Convention: a feature of size s (e.g. a wavelength or a voxel) is represented when the
    finest sinusoid has a half-period no longer than s, so L = ceil(log2(S / s)), at least 0.
    """
    if not (scene_size_m > 0 and feature_size_m > 0):
        raise ValueError(f"sizes must be positive [m], got scene {scene_size_m}, feature {feature_size_m}")
    return max(0, math.ceil(math.log2(scene_size_m / feature_size_m) - 1e-9))


class PositionalEncoding(nn.Module):
    """gamma : (N, 3) points [m] -> (N, 3 + 6 L) features."""

    def __init__(self, lower_m, upper_m, levels: int):
        super().__init__()
        lower, upper = np.asarray(lower_m, float), np.asarray(upper_m, float)
        if levels < 0:
            raise ValueError(f"levels must be >= 0, got {levels}")
        self.levels = int(levels)
        self.register_buffer("centre", torch.tensor((lower + upper) / 2, dtype=torch.float32))
        self.half_extent_m = float((upper - lower).max() / 2)
        self.register_buffer("frequencies", math.pi * 2.0 ** torch.arange(self.levels, dtype=torch.float32))

    @property
    def out_dim(self) -> int:
        return 3 + 6 * self.levels

    def normalise(self, points: torch.Tensor) -> torch.Tensor:
        """(N, 3) [m] -> (N, 3) in [-1, 1] inside the bounds."""
        return (points - self.centre) / self.half_extent_m

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        x = self.normalise(points)
        if self.levels == 0:
            return x
        angles = (x[:, None, :] * self.frequencies[None, :, None]).flatten(1)  # (N, 3 L)
        return torch.cat([x, torch.sin(angles), torch.cos(angles)], dim=1)
