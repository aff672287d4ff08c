"""Derivatives of SDFs by autograd: gradients, normals, curvature and the Eikonal residual."""

from __future__ import annotations

from typing import Callable

import torch

from .base import as_points

__all__ = ["gradient", "gradient_and_curvature", "normals", "eikonal_residual"]

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


def gradient_and_curvature(sdf: SDFCallable, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(grad f (N, 3), div(grad f / |grad f|) (N,) [1/m]) at ``points`` (N, 3) [m], detached.

    The divergence of the unit normal is the sum of the two principal curvatures of the level
    set through each point (2/R on a sphere of radius R, 1/R on a cylinder, 0 on a plane,
    positive where the surface is convex): a surface element moved by V along its normal
    grows by the factor 1 + curvature * V. From the Hessian H as (tr H - n^T H n) / |grad f|;
    0 where f is not twice differentiable and autograd's second derivative is NaN (inside a
    box, whose outside part |max(q, 0)| sits at the norm's kink: there f is the largest of
    the planes' distances, flat on each side).
    """
    points = as_points(points)
    with torch.enable_grad():
        p = points.detach().requires_grad_(True)
        (grad,) = torch.autograd.grad(sdf(p).sum(), p, create_graph=True)
        rows = [torch.autograd.grad(grad[:, i].sum(), p, retain_graph=i < 2, allow_unused=True)[0]
                if grad.requires_grad else None for i in range(3)]  # None where f is linear in p
    hessian = torch.stack([torch.zeros_like(p) if r is None else r for r in rows], dim=1).detach()  # (N, 3, 3)
    hessian = torch.nan_to_num(hessian, nan=0.0)
    grad = grad.detach()
    norm = grad.norm(dim=1).clamp(min=torch.finfo(grad.dtype).tiny)
    along = torch.einsum("ni,nij,nj->n", grad, hessian, grad) / norm**2
    return grad, (hessian.diagonal(dim1=1, dim2=2).sum(1) - along) / norm


def normals(sdf: SDFCallable, points: torch.Tensor) -> torch.Tensor:
    """Outward unit normals grad f / |grad f| at ``points`` : (N, 3); returns (N, 3)."""
    return torch.nn.functional.normalize(gradient(sdf, points), dim=1)


def eikonal_residual(sdf: SDFCallable, points: torch.Tensor, *, create_graph: bool = False) -> torch.Tensor:
    """| |grad f| - 1 | at ``points`` : (N, 3); returns (N,). Zero for an exact SDF."""
    return (torch.linalg.norm(gradient(sdf, points, create_graph=create_graph), dim=1) - 1.0).abs()
