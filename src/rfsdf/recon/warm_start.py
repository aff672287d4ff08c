"""Where the fit starts: f pre-fitted to the signed distance of the thresholded MF image.

The rendering kernel delta_sigma(f) has no gradient where |f| >> sigma, so a surface that
starts far from an object never finds it; a sphere start only works for objects it
touches. The matched-filter image already says roughly where things are: voxels whose
view-mean MF amplitude exceeds ``threshold`` of its peak are taken as inside, the signed
Euclidean distance to that set's boundary is the target, and f is regressed onto it (L1,
clipped, plus the Eikonal term) before the GeRaF loss takes over. The reflectivity is
regressed at the same time onto the local peak of the MF amplitude (a max filter over the
PSF's cross-range width), so weak reflectors (wood, drywall) start dim instead of being
explained away by moving their surfaces.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy import ndimage
from tqdm.auto import tqdm

from ..geometry import Grid
from .losses import eikonal_loss

__all__ = ["image_signed_distance", "local_peak_amplitude", "fit_to_image"]

_CLIP_M = 0.03  # residuals beyond 3 cm count as 3 cm: far-field values need not be exact


def _amplitude(power: np.ndarray) -> np.ndarray:
    """sqrt(power) in float64; negative values (round-off) count as 0."""
    return np.sqrt(np.maximum(np.asarray(power, float), 0))


def image_signed_distance(power: np.ndarray, grid: Grid, threshold: float) -> np.ndarray:
    """(nx, ny, nz) float32 signed distance [m] to the set where sqrt(power) >= threshold * max.

    Negative inside. Distances run between voxel centres, so the boundary sits half a voxel
    outside the last inside voxel. Raises ValueError when the set is empty or the whole box.
    """
    amplitude = _amplitude(power)
    inside = amplitude >= threshold * amplitude.max() if amplitude.max() > 0 else np.zeros(amplitude.shape, bool)
    if not inside.any() or inside.all():
        raise ValueError(f"MF threshold {threshold:g} of the peak amplitude selects "
                         f"{'no' if not inside.any() else 'every'} voxel; choose another init.threshold")
    voxel = tuple(float(v) for v in grid.voxel_m)
    half = 0.5 * float(np.mean(voxel))
    outside_distance = ndimage.distance_transform_edt(~inside, sampling=voxel) - half
    inside_distance = ndimage.distance_transform_edt(inside, sampling=voxel) - half
    return np.where(inside, -inside_distance, outside_distance).astype(np.float32)


def local_peak_amplitude(power: np.ndarray, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) float32 max of sqrt(power) over a cube of ``window_voxels``, peak 1."""
    amplitude = _amplitude(power)
    peak = ndimage.maximum_filter(amplitude, size=max(1, int(window_voxels)))
    return (peak / max(float(peak.max()), 1e-30)).astype(np.float32)


def fit_to_image(field, points_m: torch.Tensor, sdf_target_m: torch.Tensor, reflectivity_target: torch.Tensor, *,
                 steps: int, lr: float, batch: int, eikonal_weight: float, generator: torch.Generator,
                 progress: bool = False) -> float:
    """Regress ``field`` (a RadarField) onto targets (N,) at ``points_m`` (N, 3) by Adam.

    f by clipped L1 against ``sdf_target_m`` plus the Eikonal term (on a quarter of the
    batch); Gamma by L1 against ``reflectivity_target`` (None: f only). Each step draws
    ``batch`` points. Returns the last clipped L1 residual of f [m].
    """
    optimizer = torch.optim.Adam(field.parameters(), lr=lr)
    residual = float("nan")
    for _ in tqdm(range(steps), desc="warm start", disable=not progress, leave=False):
        index = torch.randint(len(points_m), (batch,), generator=generator).to(points_m.device)
        points = points_m[index]
        f, gamma = field.sdf_and_reflectivity(points)
        misfit = (f - sdf_target_m[index]).abs().clamp(max=_CLIP_M).mean()
        loss = misfit + eikonal_weight * eikonal_loss(field.sdf, points[: max(1, batch // 4)])
        if reflectivity_target is not None:
            loss = loss + (gamma - reflectivity_target[index]).abs().mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        residual = float(misfit.detach())
    return residual
