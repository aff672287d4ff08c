"""Deciding where an image shows something: a global and a local (CFAR-like) threshold.

A voxel is a detection where its amplitude exceeds both ``threshold`` of the image's peak
and ``local_threshold`` of the local peak, the maximum over a window of about a PSF. The
local rule cuts every object at its own fraction of its peak, so a strong reflector is
not bloated by its blur and a weak one is not lost below a global level set by the
strongest: the idea of a cell-averaging CFAR detector, with the local maximum as the
reference level.

Per view, two rules take voxels out of a detection set: ``in_front_of_ridges`` (the half of
a glint's range blob that stands before the surface) and ``on_range_sidelobes`` (the weak
copies a bright glint leaves a range resolution before and behind it on the same line of
sight, below the waveform's sidelobe level: range-sidelobe blanking).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .waveform import range_sidelobes

__all__ = ["amplitude_of", "window_voxels", "detection_mask", "detection_level", "own_detection", "in_front_of_ridges",
           "range_ridges", "on_range_sidelobes"]

SIDELOBE_REACH = 4.0  # on_range_sidelobes' default: this many range resolutions along each line of sight
SIDELOBE_TUBE_VOXELS = 3  # ... within a tube of this many voxels across it


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


def own_detection(power: np.ndarray, *, threshold: float, local_threshold: float, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) bool: one view's own detection, where its amplitude reaches
    :func:`detection_level` of its power (and is not 0); empty or full without complaint,
    unlike :func:`detection_mask`."""
    amplitude = amplitude_of(power)
    level = detection_level(power, threshold=threshold, local_threshold=local_threshold, window_voxels=window_voxels)
    return (amplitude >= level) & (amplitude > 0)


def detection_mask(power: np.ndarray, *, threshold: float, local_threshold: float, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) bool: sqrt(power) >= max(local_threshold * local peak, threshold * peak).

    The local peak is the maximum amplitude over a cube of ``window_voxels``; a
    ``local_threshold`` of 0 gives a plain global threshold. Raises ValueError when the set
    is empty or the whole box.
    """
    inside = own_detection(power, threshold=threshold, local_threshold=local_threshold, window_voxels=window_voxels)
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
    front = np.zeros(grid.shape, bool)
    for _, in_front, _ in _ridge_split(per_view_power, view_centres_m, grid, threshold=threshold,
                                         local_threshold=local_threshold, window_m=window_m):
        front |= in_front
    return front


def range_ridges(per_view_power: np.ndarray, view_centres_m: np.ndarray, grid, *, threshold: float,
                 local_threshold: float, window_m: float):
    """Per view, its range ridges: (flat indices (n,) of the voxels of its own detection that
    are not in front of a brighter voxel, as :func:`in_front_of_ridges` decides; unit vectors
    (n, 3) from them towards the view's array centre). Where the view's seen surface lies, to
    a voxel."""
    for own, in_front, towards in _ridge_split(per_view_power, view_centres_m, grid, threshold=threshold,
                                               local_threshold=local_threshold, window_m=window_m):
        index = np.flatnonzero(own & ~in_front)
        yield index, towards[index]


def _ridge_split(per_view_power, view_centres_m, grid, *, threshold, local_threshold, window_m):
    """Per view: its own detection, the part of it in front of a brighter voxel one voxel
    further from the view (both bool, grid.shape), and the unit vectors (N, 3) towards the view."""
    behind = float(np.max(grid.voxel_m))
    points = grid.points().double().numpy()
    for amplitude, own, towards in _view_detections(per_view_power, view_centres_m, grid, points, threshold=threshold,
                                                    local_threshold=local_threshold, window_m=window_m):
        further = _sampled(amplitude, grid, points - behind * towards)
        yield own, own & (further.reshape(grid.shape) > amplitude), towards


def on_range_sidelobes(per_view_power: np.ndarray, view_centres_m: np.ndarray, frequencies_hz, grid, *,
                       threshold: float, local_threshold: float, window_m: float,
                       reach: float = SIDELOBE_REACH, level: float | None = None) -> np.ndarray:
    """(nx, ny, nz) bool: detected voxels that no view shows as more than a range sidelobe.

    A bright glint leaves, in the view that sees it, weak copies along that view's line of
    sight about a range resolution before and behind it (the waveform's range sidelobes, and
    what CLEAN's on-grid point model leaves of them): small detections a few centimetres off
    the objects. A voxel of view v's own detection (as in :func:`in_front_of_ridges`) is a
    sidelobe in v when a voxel on its line of sight to v's array, between half a range
    resolution and ``reach`` of them away (within a tube of ``SIDELOBE_TUBE_VOXELS``),
    is brighter than it by more than 1 / ``level`` (None: the waveform's peak range sidelobe,
    :func:`~rfsdf.radar.waveform.range_sidelobes`, 0.22 for 16 uniform frequencies, the
    level a point's sidelobes reach; an extended glint's far artifacts are stronger, and
    an opaque surface cannot be lit by a view on the same line of sight as a brighter one,
    which a level up to 1 states). Marked are the voxels that are a sidelobe in some view
    and genuine in none, so a weak surface behind a bright one survives if any other view
    sees it.

    per_view_power : (V, nx, ny, nz); view_centres_m : (V, 3) [m]; frequencies_hz : (K,).
    """
    null_m, peak_sidelobe = range_sidelobes(frequencies_hz)
    level = peak_sidelobe if level is None else level
    if not np.isfinite(null_m):
        return np.zeros(grid.shape, bool)
    points = grid.points().double().numpy()
    offsets = np.arange(0.5 * null_m, reach * null_m, 0.5 * float(np.max(grid.voxel_m)))
    sidelobe, genuine = np.zeros(grid.size, bool), np.zeros(grid.size, bool)
    for amplitude, own, towards in _view_detections(per_view_power, view_centres_m, grid, points, threshold=threshold,
                                                    local_threshold=local_threshold, window_m=window_m):
        index = np.flatnonzero(own)
        tube = ndimage.maximum_filter(amplitude, size=SIDELOBE_TUBE_VOXELS)
        brightest = np.zeros(len(index))
        for offset in np.concatenate([offsets, -offsets]):
            ray = points[index] + offset * towards[index]
            brightest = np.maximum(brightest, _sampled(tube, grid, ray, outside=0.0))
        lobe = amplitude.ravel()[index] < level * brightest
        sidelobe[index[lobe]] = True
        genuine[index[~lobe]] = True
    return (sidelobe & ~genuine).reshape(grid.shape)


def _view_detections(per_view_power, view_centres_m, grid, points, *, threshold, local_threshold, window_m):
    """Per view: its amplitude (grid.shape), its own detection (bool, grid.shape: amplitude at or
    above :func:`detection_level` of that view's power) and the unit vectors (N, 3) from each
    voxel centre (``points`` (N, 3) [m], the grid's) towards the view's array centre."""
    window = window_voxels(window_m, grid)
    for power, centre in zip(per_view_power, np.asarray(view_centres_m, float)):
        amplitude = amplitude_of(power)
        own = own_detection(power, threshold=threshold, local_threshold=local_threshold, window_voxels=window)
        towards = centre - points
        towards /= np.linalg.norm(towards, axis=1, keepdims=True)
        yield amplitude, own, towards


def _sampled(volume: np.ndarray, grid, points: np.ndarray, outside: float | None = None) -> np.ndarray:
    """(N,) trilinear samples of a voxel-centre volume at points (N, 3) [m]: the nearest face
    value beyond the grid, or ``outside`` when given."""
    index = ((points - np.asarray(grid.lower_m, float)) / np.asarray(grid.voxel_m, float) - 0.5).T
    if outside is None:
        return ndimage.map_coordinates(volume, index, order=1, mode="nearest")
    return ndimage.map_coordinates(volume, index, order=1, mode="constant", cval=outside)
