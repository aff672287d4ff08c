"""What a view's glints explain: their sidelobes, found by the view's own point-spread function.

A bright glint shows in its view's matched filter far beyond itself: its range sidelobes along
the line of sight (-13 dB at 1.43 range resolutions for a uniform band) and the array's
lateral sidelobes across it. A detection or a range peak there is no surface, and a surface
fitted through it grows where there is none: on the demo a metal ball's first range
sidelobe, 1.43 range resolutions behind its glint, lies 4 mm outside its far side, where the
peaks held a lump that put out the opposite view's glint, and its lateral sidelobes left
floaters 3-4 cm off it (docs/results/demo-quality.md, "Peaks on sidelobes").

The rule. In view v its glints G are its range peaks of at least ``GLINT_LEVEL`` of its
strongest, taken as point targets with the data's own normalised image there, c = A_G^H y /
||A_G||^2. Their response at any point p, A_p^H A_G c / ||A_p||^2 (the view's exact
point-spread function, every glint's sidelobes summed coherently), is compared with the
data's image there: a point farther than half a range resolution from every glint (within it,
it is a glint's own main lobe) where that response reaches ``EXPLAINED`` of the data's
amplitude is a sidelobe in v, the glints account for what v shows there. A face beside a
bright one keeps what returns more than the glints' sidelobes do. The range-sidelobe rule
of :func:`~rfsdf.radar.detection.on_range_sidelobes` looks along the line of sight for a
brighter voxel; this one predicts the sidelobes, lateral ones included.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree

from .acquisition import Measurements
from .detection import own_detection, window_voxels
from .operator import SensingOperator
from .range_peaks import RangePeaks
from .waveform import range_sidelobes

__all__ = ["GLINT_LEVEL", "EXPLAINED", "sidelobe_peaks", "sidelobe_voxels"]

GLINT_LEVEL = 0.5  # a view's glints: its range peaks of at least this amplitude (of its strongest)
EXPLAINED = 0.7  # a point is their sidelobe where their response reaches this fraction of the data's image


def sidelobe_peaks(measurements: Measurements, peaks: RangePeaks) -> np.ndarray:
    """(N,) bool: the range ``peaks`` that are sidelobes of their own view's glints (module
    docstring). On the demo 160 of 930 peaks, 155 of them more than 2 mm off the surface, 2
    within 1 mm of it."""
    marked = np.zeros(len(peaks.points), bool)
    reach_m = _main_lobe_m(measurements)
    for view in np.unique(peaks.view):
        mine = np.flatnonzero(peaks.view == view)
        marked[mine] = _explained(measurements, int(view), _glints(peaks, view), peaks.points[mine], reach_m)
    return marked


def sidelobe_voxels(measurements: Measurements, peaks: RangePeaks, per_view_power: np.ndarray, grid, *,
                    threshold: float, local_threshold: float, window_m: float) -> np.ndarray:
    """(nx, ny, nz) bool: the voxels of the views' own detections in ``per_view_power`` (V,
    nx, ny, nz; each view's at :func:`~rfsdf.radar.detection.detection_level`) that are a
    sidelobe of the glints (of ``peaks``) in every view that detects them: marked in some
    view and genuine in none, as :func:`~rfsdf.radar.detection.on_range_sidelobes` marks."""
    points = grid.points().double().numpy()
    sidelobe, genuine = np.zeros(grid.size, bool), np.zeros(grid.size, bool)
    window, reach_m = window_voxels(window_m, grid), _main_lobe_m(measurements)
    for view, power in enumerate(per_view_power):
        own = np.flatnonzero(own_detection(power, threshold=threshold, local_threshold=local_threshold,
                                           window_voxels=window))
        lobe = _explained(measurements, view, _glints(peaks, view), points[own], reach_m)
        sidelobe[own[lobe]] = True
        genuine[own[~lobe]] = True
    return (sidelobe & ~genuine).reshape(grid.shape)


def _glints(peaks: RangePeaks, view) -> np.ndarray:
    """(G, 3) [m] the glints of view ``view``: its peaks of amplitude >= GLINT_LEVEL."""
    return peaks.points[(peaks.view == view) & (peaks.amplitude >= GLINT_LEVEL)]


def _main_lobe_m(measurements: Measurements) -> float:
    """Half the first range null of the data's frequencies [m]: within it a point is a glint's
    own main lobe (inf for a single frequency: nothing is tested)."""
    return 0.5 * range_sidelobes(measurements.acquisition.frequencies_hz.cpu().numpy())[0]


def _explained(measurements: Measurements, view: int, glints: np.ndarray, points: np.ndarray,
               reach_m: float) -> np.ndarray:
    """(N,) bool: which ``points`` (N, 3) [m] the ``glints`` (G, 3) [m] of view ``view``
    explain as their sidelobes, testing those more than ``reach_m`` from every glint (module
    docstring)."""
    acquisition = measurements.acquisition
    marked = np.zeros(len(points), bool)
    if not len(glints) or not len(points) or not np.isfinite(reach_m):
        return marked
    tested = np.flatnonzero(cKDTree(glints).query(points)[0] > reach_m)
    if not len(tested):  # all within a glint's main lobe
        return marked
    operator = SensingOperator(acquisition.coherent_view(view))
    data = measurements.data[acquisition.frames(view)]
    targets = torch.from_numpy(np.concatenate([glints, points[tested]])).float()
    with torch.no_grad():
        image = operator.adjoint(data, targets) / operator.column_norms_sq(targets)
        response = operator.adjoint(operator.forward(targets[:len(glints)], image[:len(glints)]), targets[len(glints):])
    response = response / operator.column_norms_sq(targets[len(glints):])
    marked[tested] = (response.abs() >= EXPLAINED * image[len(glints):].abs()).numpy()
    return marked
