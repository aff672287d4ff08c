"""A coarse displacement of a surface: offsets on knots a few wavelengths apart, read
trilinearly. Subtracted from an SDF f it moves f's zero set by d along the normal (where
|grad f| = 1), smoothly, with a few thousand degrees of freedom: a change a descent can make
only over the knots' spacing, the multiscale remedy full-waveform inversion uses against
minima that finer changes of the surface would find."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..geometry import Grid, trilinear

__all__ = ["KnotDisplacement"]


class KnotDisplacement(nn.Module):
    """d : (N, 3) points [m] -> (N,) [m], trilinear between offsets on knots ``knot_m`` [m]
    apart spanning the bounds (one knot beyond them on each side); zero at the start."""

    def __init__(self, lower_m, upper_m, knot_m: float):
        super().__init__()
        if not knot_m > 0:
            raise ValueError(f"knot spacing must be positive [m], got {knot_m}")
        lower, upper = np.asarray(lower_m, float) - knot_m, np.asarray(upper_m, float) + knot_m
        counts = np.ceil((upper - lower) / knot_m).astype(int) + 1  # knots at the voxel centres
        centre, half = (lower + upper) / 2, counts * knot_m / 2  # each voxel knot_m wide, its centre a knot
        self.grid = Grid(tuple(centre - half), tuple(centre + half), tuple(int(n) for n in counts))
        self.offsets_m = nn.Parameter(torch.zeros(self.grid.shape))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return trilinear(self.offsets_m, self.grid)(points)
