"""Occupancy from an SDF: the soft indicator whose 0.5 level set is the surface."""

from __future__ import annotations

import torch

from .differential import SDFCallable

__all__ = ["occupancy"]


def occupancy(sdf: SDFCallable, points: torch.Tensor, alpha: float) -> torch.Tensor:
    """sigmoid(-alpha f(points)) : (N,) in (0, 1); 1 inside, 0 outside, 0.5 on the surface.

    ``alpha`` [1/m] sets the sharpness: the transition is about 4/alpha metres wide.
    """
    if not alpha > 0:
        raise ValueError(f"alpha must be positive [1/m], got {alpha}")
    return torch.sigmoid(-alpha * sdf(points))
