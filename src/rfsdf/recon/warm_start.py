"""Where the fit starts: f pre-fitted to the signed distance of the thresholded MF image.

The rendering kernel delta_sigma(f) has no gradient where |f| >> sigma, so a surface that
starts far from an object never finds it; a sphere start only works for objects it
touches. The matched-filter image already says roughly where things are: voxels whose
view-mean MF amplitude exceeds ``threshold`` of its peak are taken as inside, the signed
Euclidean distance to that set's boundary is the target, and f is regressed onto it (L1,
clipped, plus the Eikonal term) before the GeRaF loss takes over.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy import ndimage

from ..geometry import Grid
from .losses import eikonal_loss

__all__ = ["image_signed_distance", "fit_to_distance"]

_CLIP_M = 0.03  # residuals beyond 3 cm count as 3 cm: far-field values need not be exact


def image_signed_distance(power: np.ndarray, grid: Grid, threshold: float) -> np.ndarray:
    """(nx, ny, nz) float32 signed distance [m] to the set where sqrt(power) >= threshold * max.

    Negative inside. Distances run between voxel centres, so the boundary sits half a voxel
    outside the last inside voxel. Raises ValueError when the set is empty or the whole box.
    """
    amplitude = np.sqrt(np.maximum(np.asarray(power, float), 0))
    inside = amplitude >= threshold * amplitude.max() if amplitude.max() > 0 else np.zeros(amplitude.shape, bool)
    if not inside.any() or inside.all():
        raise ValueError(f"MF threshold {threshold:g} of the peak amplitude selects "
                         f"{'no' if not inside.any() else 'every'} voxel; choose another init.threshold")
    voxel = tuple(float(v) for v in grid.voxel_m)
    half = 0.5 * float(np.mean(voxel))
    outside_distance = ndimage.distance_transform_edt(~inside, sampling=voxel) - half
    inside_distance = ndimage.distance_transform_edt(inside, sampling=voxel) - half
    return np.where(inside, -inside_distance, outside_distance).astype(np.float32)


def fit_to_distance(sdf, parameters, points_m: torch.Tensor, target_m: torch.Tensor, *, steps: int, lr: float,
                    batch: int, eikonal_weight: float, generator: torch.Generator) -> float:
    """Regress ``sdf`` (points (N, 3) -> (N,)) onto ``target_m`` (N,) at ``points_m`` by Adam.

    Each step draws ``batch`` of the points; the Eikonal term is taken on a quarter of them.
    Returns the last clipped L1 residual [m].
    """
    optimizer = torch.optim.Adam(parameters, lr=lr)
    residual = float("nan")
    for _ in range(steps):
        index = torch.randint(len(points_m), (batch,), generator=generator).to(points_m.device)
        points = points_m[index]
        misfit = (sdf(points) - target_m[index]).abs().clamp(max=_CLIP_M).mean()
        loss = misfit + eikonal_weight * eikonal_loss(sdf, points[: max(1, batch // 4)])
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        residual = float(misfit.detach())
    return residual
