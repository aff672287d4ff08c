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

__all__ = ["amplitude_of", "detection_mask", "detection_level"]


def amplitude_of(power: np.ndarray) -> np.ndarray:
    """sqrt(power) in float64; negative values (round-off) count as 0."""
    return np.sqrt(np.maximum(np.asarray(power, float), 0))


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

