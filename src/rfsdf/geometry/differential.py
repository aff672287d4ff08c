"""Gradients of SDFs by autograd: normals and the Eikonal residual."""

from __future__ import annotations

from typing import Callable

import torch

from .base import as_points

__all__ = ["gradient", "normals", "eikonal_residual"]

SDFCallable = Callable[[torch.Tensor], torch.Tensor]


def gradient(sdf: SDFCallable, points: torch.Tensor, *, create_graph: bool = False) -> torch.Tensor:
    """grad f at ``points`` : (N, 3) [m]; returns (N, 3), unitless.

    With ``create_graph=True`` the result is itself differentiable (for Eikonal losses
    on networks); otherwise it is detached from any graph of ``points``.
    """
    points = as_points(points)
    with torch.enable_grad():
        p = points if (create_graph and points.requires_grad) else points.detach().requires_grad_(True)
        values = sdf(p)
        (grad,) = torch.autograd.grad(values.sum(), p, create_graph=create_graph)
    return grad


def normals(sdf: SDFCallable, points: torch.Tensor) -> torch.Tensor:
    """Outward unit normals grad f / |grad f| at ``points`` : (N, 3); returns (N, 3)."""
    return torch.nn.functional.normalize(gradient(sdf, points), dim=1)


def eikonal_residual(sdf: SDFCallable, points: torch.Tensor, *, create_graph: bool = False) -> torch.Tensor:
    """| |grad f| - 1 | at ``points`` : (N, 3); returns (N,). Zero for an exact SDF."""
    return (torch.linalg.norm(gradient(sdf, points, create_graph=create_graph), dim=1) - 1.0).abs()
