"""Deciding where an image shows something: a global and a local (CFAR-like) threshold.

A voxel is a detection where its amplitude exceeds both ``threshold`` of the image's peak
and ``local_threshold`` of the local peak, the maximum over a window of about a PSF. The
local rule cuts every object at its own fraction of its peak, so a strong reflector is
not bloated by its blur and a weak one is not lost below a global level set by the
strongest: the idea of a cell-averaging CFAR detector, with the local maximum as the
reference level.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["amplitude_of", "window_voxels", "detection_mask", "detection_level", "in_front_of_ridges"]


def amplitude_of(power: np.ndarray) -> np.ndarray:
    """sqrt(power) in float64; negative values (round-off) count as 0."""
    return np.sqrt(np.maximum(np.asarray(power, float), 0))


def window_voxels(window_m: float, grid) -> int:
    """Edge [voxels, >= 1] of the local-peak window of edge ``window_m`` [m] on ``grid``."""
    return max(1, round(window_m / float(np.max(grid.voxel_m))))


def detection_level(power: np.ndarray, *, threshold: float, local_threshold: float, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) float64: the amplitude each voxel must reach, max(local_threshold *
    local peak, threshold * peak); the detections are where amplitude >= level."""
    amplitude = amplitude_of(power)
    local = ndimage.maximum_filter(amplitude, size=max(1, int(window_voxels)))
    return np.maximum(local_threshold * local, threshold * float(amplitude.max()))


def detection_mask(power: np.ndarray, *, threshold: float, local_threshold: float, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) bool: sqrt(power) >= max(local_threshold * local peak, threshold * peak).

    The local peak is the maximum amplitude over a cube of ``window_voxels``; a
    ``local_threshold`` of 0 gives a plain global threshold. Raises ValueError when the set
    is empty or the whole box.
    """
    amplitude = amplitude_of(power)
    level = detection_level(power, threshold=threshold, local_threshold=local_threshold, window_voxels=window_voxels)
    inside = (amplitude >= level) & (amplitude > 0)
    if not inside.any() or inside.all():
        raise ValueError(f"image thresholds (global {threshold:g}, local {local_threshold:g}) select "
                         f"{'no' if not inside.any() else 'every'} voxel; choose other init thresholds")
    return inside


def in_front_of_ridges(per_view_power: np.ndarray, view_centres_m: np.ndarray, grid, *, threshold: float,
                       local_threshold: float, window_m: float) -> np.ndarray:
    """(nx, ny, nz) bool: voxels in front of a range ridge of some view (range blur, not surface).

    A glint images as a blob about a range resolution deep along the view's line of sight,
    centred on the surface. A voxel is marked where, in some view v, it belongs to v's own
    detection (:func:`detection_level` of v's power at ``threshold`` and ``local_threshold``,
    the local window of edge ``window_m`` [m])
    and the amplitude one voxel further from v's array centre (``view_centres_m`` (V, 3) [m])
    is larger: the ridge, where the surface is, still lies behind it. Removing these voxels
    from a detection set cuts the half of each blob that stands in front of the seen face
    (``benchmarks/detection_settings.py`` measures it on the demo).

    per_view_power : (V, nx, ny, nz) per-view image power; grid : the images' Grid.
    """
    points = grid.points().double().numpy()  # (N, 3) voxel centres
    voxel = np.asarray(grid.voxel_m, float)
    front = np.zeros(grid.shape, bool)
    window = window_voxels(window_m, grid)
    for power, centre in zip(per_view_power, np.asarray(view_centres_m, float)):
        amplitude = amplitude_of(power)
        towards = centre - points
        towards /= np.linalg.norm(towards, axis=1, keepdims=True)
        behind = points - float(voxel.max()) * towards
        index = ((behind - np.asarray(grid.lower_m, float)) / voxel - 0.5).T  # fractional voxel indices
        further = ndimage.map_coordinates(amplitude, index, order=1, mode="nearest").reshape(grid.shape)
        own = amplitude >= detection_level(power, threshold=threshold, local_threshold=local_threshold,
                                           window_voxels=window)
        front |= own & (amplitude > 0) & (further > amplitude)
    return front
