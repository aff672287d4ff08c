"""Samples of the neural surface f_theta = 0, differentiable in theta, for coherent rendering.

Coherent rendering needs points *on* the surface, at most lambda/3 apart, with area weights
and normals (a shell delta_sigma(f) around it cannot be summed coherently, see
``recon/render.py``). The sampler's positions and areas need no double backward through the
training graph (second derivatives only at the refresh, detached); its normals take one:

1. Candidates (no gradient, refreshed every few steps): every voxel the zero level set can
   cross is split into s^3 cells of edge h <= the requested spacing, one uniformly random
   point p0 per cell; those with |f(p0)| < h/2 are kept, with their gradient g0 = grad f(p0).
2. Projection (every step, differentiable): p* = p0 - f_theta(p0) g0 / |g0|^2, one Newton
   step onto f = 0 along the frozen gradient, so dp*/dtheta = -(df/dtheta) g0 / |g0|^2: the
   normal velocity V of the level set under a change of theta. The area each sample stands
   for follows it too, dA/dtheta = A kappa V with kappa = div(g0 / |g0|) the sum of the
   principal curvatures (frozen at the refresh like g0): the first-order area change of a
   surface moved along its normal. Without it a sphere's glint would *brighten* as it
   shrinks (its samples crowd into the Fresnel zone while each keeps its old area, amplitude
   ~ 1/R instead of ~ R), and a too-dim bright ball was pulled inward until it vanished
   (docs/results/quality-history.md, "The area term").

Area weights follow from the coarea formula: the kept cells fill a slab of thickness
h / |g0| around the surface, so each stands for an area h^2 |g0| (unbiased for any f, not
only an exact SDF; the random point per cell makes the samples a jittered, not a regular,
lattice, like the simulator's random surface samples).

3. Normals (every step, differentiable): n = grad f(p0) / |grad f(p0)| at the anchors, so
   the loss can turn a facet, not only move it. The specular lobe makes a glint's direction
   depend on its normal far more than on its position (a facet tilted by 20 degrees sends its
   mirror direction 40 degrees away), and a fit that could only move the samples along
   frozen normals left the warm start's 40-degree normal errors where they were
   (docs/results/demo-quality.md, "Normals from the views"). It costs one double backward through f at the samples.

Why this sampler: it finds every piece of surface the voxel grid sees, including thin
ones and small components, with no mesh; on an analytic sphere its points lie on the
surface to float precision after the Newton step and its area is within 1 % (tests). The
alternative, marching-cubes triangles subdivided and projected, is cheaper to refresh
but takes its areas from a chordal mesh of the coarse grid (a few % low on curved
objects of a few voxels) and loses sub-voxel components.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import torch

from ..geometry import gradient_and_curvature

__all__ = ["SurfaceCandidates", "surface_candidates", "project_to_surface", "smoothed_velocity", "cells_per_voxel",
           "crossing_voxels"]

_EVAL_CHUNK = 1 << 16  # points per SDF call while searching candidates
_CROSSING_MARGIN = 1.0  # a voxel can hold surface when |f(centre)| < margin * voxel (sqrt(3)/2 exact)


@dataclass(frozen=True)
class SurfaceCandidates:
    """Points next to the zero level set, fixed between refreshes (Q candidates).

    anchors : (Q, 3) [m] the points p0. gradients : (Q, 3) grad f(p0), detached.
    area_m2 : (Q,) area each sample stands for [m^2]. spacing_m : the cell edge h [m].
    curvature : (Q,) [1/m] div(g0 / |g0|), the sum of the principal curvatures, detached.
    values : (Q,) [m] f(p0) when the candidates were drawn (the level set the areas belong to).
    """

    anchors: torch.Tensor
    gradients: torch.Tensor
    area_m2: torch.Tensor
    spacing_m: float
    curvature: torch.Tensor
    values: torch.Tensor

    @property
    def normals(self) -> torch.Tensor:
        """(Q, 3) outward unit normals g0 / |g0|."""
        return torch.nn.functional.normalize(self.gradients, dim=1)

    def projected(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """What :func:`project_to_surface` returns for the f the candidates were drawn from,
        without calling it: points (Q, 3) [m], normals (Q, 3), areas (Q,) [m^2], no graph.
        For steps that hold f fixed (the fit's geometry delay), where f(p0) and its gradient
        are still the ones stored at the refresh."""
        return _newton_step(self.anchors, self.values, self.gradients), self.normals, self.area_m2

    def __len__(self) -> int:
        return len(self.anchors)


def cells_per_voxel(voxel_m: float, spacing_m: float) -> int:
    """s: the fewest cells per voxel edge that make the cell edge at most ``spacing_m``."""
    return max(1, math.ceil(voxel_m / spacing_m - 1e-9))


def crossing_voxels(voxel_centres_m: torch.Tensor, voxel_values_m: torch.Tensor, voxel_m: float) -> torch.Tensor:
    """(M, 3) [m] the voxel centres (N, 3) whose values f (N,) [m] say the zero set may cross
    their voxel of edge ``voxel_m`` [m]."""
    return voxel_centres_m[voxel_values_m.abs() < _CROSSING_MARGIN * voxel_m]


def surface_candidates(sdf: Callable[[torch.Tensor], torch.Tensor], voxel_centres_m: torch.Tensor,
                       voxel_values_m: torch.Tensor, voxel_m: float, spacing_m: float,
                       generator: torch.Generator) -> SurfaceCandidates:
    """Candidates near f = 0 from the voxels (N, 3) [m] whose values f (N,) [m] say the surface
    may cross them; cells of edge h = voxel / s <= ``spacing_m`` (see the module docstring)."""
    device = voxel_centres_m.device
    cells = cells_per_voxel(voxel_m, spacing_m)
    h = voxel_m / cells
    crossing = crossing_voxels(voxel_centres_m, voxel_values_m, voxel_m)
    offsets = torch.stack(torch.meshgrid(*[torch.arange(cells, device=device)] * 3, indexing="ij"), -1).reshape(-1, 3)
    corner = crossing - 0.5 * voxel_m  # (M, 3) lower corners
    kept, values = [], []
    with torch.no_grad():
        for start in range(0, len(corner), max(1, _EVAL_CHUNK // len(offsets))):
            block = corner[start:start + max(1, _EVAL_CHUNK // len(offsets))]
            jitter = torch.rand(len(block), len(offsets), 3, generator=generator).to(device)
            points = (block[:, None] + h * (offsets[None] + jitter)).reshape(-1, 3)
            f = sdf(points)
            near = f.abs() < 0.5 * h
            kept.append(points[near])
            values.append(f[near])
    anchors = torch.cat(kept) if kept else torch.zeros(0, 3, device=device)
    derivatives = [gradient_and_curvature(sdf, chunk) for chunk in anchors.split(_EVAL_CHUNK)]
    grads = torch.cat([g for g, _ in derivatives]) if derivatives else torch.zeros(0, 3, device=device)
    curvature = torch.cat([k for _, k in derivatives]) if derivatives else torch.zeros(0, device=device)
    values = torch.cat(values) if values else torch.zeros(0, device=device)
    return SurfaceCandidates(anchors, grads, h**2 * grads.norm(dim=1), h, curvature, values)


def project_to_surface(sdf: Callable[[torch.Tensor], torch.Tensor], candidates: SurfaceCandidates, *,
                       smoothing_m: float = 0.0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Points p* = p0 - f(p0) g0 / |g0|^2 (Q, 3) [m] on the zero level set, one Newton step
    along the frozen gradient; their outward unit normals grad f(p0) / |grad f(p0)| (Q, 3);
    and the area each stands for (Q,) [m^2], A max(0, 1 + kappa V) with V = -(f(p0) - f(p0)
    at the refresh) / |g0| how far the level set moved since the areas were drawn: all three
    differentiable in the parameters of ``sdf`` when gradients are being recorded (the normals
    by a double backward).

    With ``smoothing_m`` > 0 the gradient reaching f(p0) (the normal velocity the loss asks
    for at each sample) is replaced by its Gaussian-weighted local mean over that radius
    [m], a Sobolev-type gradient as in level-set shape optimisation: the forces one sample
    feels from the speckle of a coherent image are random from sample to sample, those of
    a misplaced surface are not, and only the latter survive the average.
    """
    g = candidates.gradients
    recording = torch.is_grad_enabled()
    with torch.enable_grad():
        anchors = candidates.anchors.detach().requires_grad_(True)
        values = sdf(anchors)
        (grad,) = torch.autograd.grad(values.sum(), anchors, create_graph=recording)
    normals = torch.nn.functional.normalize(grad, dim=1)
    if not recording:
        values, normals = values.detach(), normals.detach()
    values = smoothed_velocity(values, candidates.anchors, smoothing_m)
    moved = -(values - candidates.values) / g.norm(dim=1).clamp(min=1e-6)
    area = candidates.area_m2 * (1 + candidates.curvature * moved).clamp(min=0)
    return _newton_step(candidates.anchors, values, g), normals, area


def smoothed_velocity(values: torch.Tensor, points: torch.Tensor, smoothing_m: float) -> torch.Tensor:
    """``values`` (Q,) f at surface points (Q, 3) [m], whose gradient (the normal velocity the
    loss asks for at each point) is replaced by its Gaussian-weighted local mean over
    ``smoothing_m`` [m] (0: left as it is): a Sobolev-type gradient (:func:`project_to_surface`)."""
    return _SmoothedGradient.apply(values, points, smoothing_m) if smoothing_m > 0 else values


def _newton_step(anchors: torch.Tensor, values: torch.Tensor, gradients: torch.Tensor) -> torch.Tensor:
    """p0 - f(p0) g0 / |g0|^2 (Q, 3) [m]: one Newton step to f = 0 along the frozen gradient."""
    norm_sq = (gradients * gradients).sum(1).clamp(min=1e-12)
    return anchors - (values / norm_sq)[:, None] * gradients


def _local_mean(values: torch.Tensor, points: torch.Tensor, radius_m: float) -> torch.Tensor:
    """(Q,) Gaussian-weighted local mean of ``values`` (Q,) at ``points`` (Q, 3) [m]: binned on
    a grid of cells radius/2, blurred by a separable Gaussian of std ``radius_m``, read back."""
    cell = radius_m / 2
    index = torch.floor((points - points.min(0).values) / cell).long() + 3
    shape = tuple(int(n) + 4 for n in index.max(0).values)
    flat = (index[:, 0] * shape[1] + index[:, 1]) * shape[2] + index[:, 2]
    size = shape[0] * shape[1] * shape[2]
    sums = torch.zeros(size, dtype=values.dtype, device=values.device).index_add_(0, flat, values)
    counts = torch.zeros(size, dtype=values.dtype, device=values.device).index_add_(0, flat, torch.ones_like(values))
    offsets = torch.arange(-3, 4, dtype=values.dtype, device=values.device)
    kernel = torch.exp(-0.5 * (offsets * cell / radius_m) ** 2)
    volume = torch.stack([sums, counts]).reshape(2, 1, *shape)
    for axis in range(3):
        view = [1, 1, 1, 1, 1]
        view[2 + axis] = len(kernel)
        padding = [0, 0, 0]
        padding[axis] = 3
        volume = torch.nn.functional.conv3d(volume, (kernel / kernel.sum()).reshape(view), padding=tuple(padding))
    sums, counts = volume.reshape(2, -1)
    return sums[flat] / counts[flat].clamp(min=torch.finfo(values.dtype).tiny)


class _SmoothedGradient(torch.autograd.Function):
    """Identity forward; the backward passes the local mean of the incoming gradient."""

    @staticmethod
    def forward(ctx, values, points, radius_m):
        ctx.save_for_backward(points)
        ctx.radius_m = radius_m
        return values.view_as(values)

    @staticmethod
    def backward(ctx, grad):
        (points,) = ctx.saved_tensors
        return _local_mean(grad, points.detach(), ctx.radius_m), None, None
