"""Where each view's seen surface lies within a voxel: its range ridges refined along the line of sight.

A detection on a voxel grid places a surface to half a voxel at best (3 mm on the demo's 6 mm
grid), and a boundary drawn from voxel sets adds its own half voxel. Yet each view's
matched-filter image of a glint peaks on the surface along that view's line of sight, and
the image can be evaluated anywhere, not only at voxel centres. So every ridge voxel of a
view's detection (:func:`~rfsdf.radar.detection.range_ridges`) is moved to the peak of the
view's own matched filter (normalised as a correlation, :func:`~rfsdf.radar.imaging.
view_correlation`, which a point target's peaks at the point) sampled every ``step_m`` along
its line of sight within ``span_m``, refined
by a parabola through the three samples at the peak. A peak at either end of the span is not
this voxel's surface and is dropped.

On the demo's data (50^3 voxels of 6 mm, 12 views), the ridge voxels of the CLEAN image lie
4.0 mm from the true surface (median), the refined points 1.2 mm (amplitude-weighted mean
3.8 -> 1.5 mm): docs/results/demo-quality.md, "Range peaks".

Seen ``through`` a known scene (a box the objects are packed in), each line's return comes
later by the two-way excess path of the slabs it crosses (:mod:`~rfsdf.radar.transmission`),
the same for every element of the view, as the simulator and the fit's renderer model it.
Moving the peak back by the one-way excess is not the same: the envelope moves by it, the
carrier's focus (the array's wavefront curvature) does not, and the peak lies between (0.93
of the way for a point 11 cm before a 4 cm array). So each line is correlated with the data
with its delay taken out first, which puts a point's peak back on it; a line that meets metal
is dropped (no return reaches the view from there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..scene import Scene
from .acquisition import Measurements
from .detection import range_ridges
from .imaging import view_correlation
from .transmission import line_of_sight

__all__ = ["RangePeaks", "range_peaks"]

SPAN_M = 0.015  # how far before and behind a ridge voxel its peak is looked for [m]
STEP_M = 0.0005  # sampling along the line of sight [m]
EXCESS_STEP_M = 2e-5  # lines seen through slabs are grouped by their excess path to this [m]: within 0.02 rad at 79 GHz


@dataclass(frozen=True)
class RangePeaks:
    """Surface points seen by the views: points (N, 3) [m], amplitude (N,) (each view's
    correlation at its peak over that view's largest), view (N,) int, towards (N, 3) unit vectors to the
    view's array centre."""

    points: np.ndarray
    amplitude: np.ndarray
    view: np.ndarray
    towards: np.ndarray


def range_peaks(measurements: Measurements, per_view_power: np.ndarray, grid, *, threshold: float,
                local_threshold: float, window_m: float, keep: np.ndarray | None = None,
                span_m: float = SPAN_M, step_m: float = STEP_M, through: Scene | None = None) -> RangePeaks:
    """The range ridges of each view's detection in ``per_view_power`` (V, nx, ny, nz; the
    detection rule as in :func:`~rfsdf.radar.detection.range_ridges`), only those in ``keep``
    (bool, grid.shape; None: all), each moved to the peak of the view's matched filter of
    ``measurements`` along its line of sight, the delay of ``through``'s slabs on it taken out
    first (None: nothing in the way)."""
    acquisition = measurements.acquisition
    centres = acquisition.view_centres()[0].cpu().numpy()
    points = grid.points().double().numpy()
    offsets = np.arange(-span_m, span_m + 0.5 * step_m, step_m)  # positive: away from the view
    parts = []
    for view, (index, towards) in enumerate(range_ridges(per_view_power, centres, grid, threshold=threshold,
                                                          local_threshold=local_threshold, window_m=window_m)):
        if keep is not None:
            kept = keep.ravel()[index]
            towards, index = towards[kept], index[kept]
        if not len(index):
            continue
        excess = None
        if through is not None:
            sight = line_of_sight(through, torch.from_numpy(points[index]), torch.from_numpy(towards),
                                  torch.from_numpy(centres[view]), float(acquisition.frequencies_hz.mean()))
            clear = (sight.factor != 0).numpy()
            index, towards, excess = index[clear], towards[clear], 2 * sight.excess_m.numpy()[clear]
        line = points[index, None, :] - offsets[None, :, None] * towards[:, None, :]
        amplitude = _line_correlation(measurements, view, line, excess)
        peak, shift = _parabolic_peak(amplitude)
        inner = (peak > 0) & (peak < len(offsets) - 1)
        along = (offsets[peak] + shift * step_m)[inner]
        found = points[index[inner]] - along[:, None] * towards[inner]
        parts.append((found, amplitude[inner, peak[inner]], np.full(len(found), view), towards[inner]))
    if not parts:
        return RangePeaks(np.zeros((0, 3)), np.zeros(0), np.zeros(0, int), np.zeros((0, 3)))
    found, amplitude, view, towards = (np.concatenate(p) for p in zip(*parts))
    for v in np.unique(view):  # each view's peaks over its largest: views of other brightness weigh alike
        amplitude[view == v] /= amplitude[view == v].max()
    return RangePeaks(found, amplitude, view, towards)


def _line_correlation(measurements: Measurements, view: int, lines: np.ndarray,
                      excess_m: np.ndarray | None) -> np.ndarray:
    """(N, S) float64: the view's correlation (:func:`~rfsdf.radar.imaging.view_correlation`)
    at the points ``lines`` (N, S, 3) [m]; with ``excess_m`` (N,) [m], each line's with the
    view's data advanced by its two-way excess path (grouped to EXCESS_STEP_M, one correlation a group)."""
    n, s = lines.shape[:2]
    if excess_m is None:
        groups, members = np.zeros(1), np.zeros(n, int)
    else:
        groups, members = np.unique(np.round(excess_m / EXCESS_STEP_M), return_inverse=True)
        groups = groups * EXCESS_STEP_M
    amplitude = np.zeros((n, s))
    for group, excess in enumerate(groups):
        rows = members == group
        samples = torch.from_numpy(lines[rows].reshape(-1, 3)).float()
        with torch.no_grad():
            correlation = view_correlation(measurements, view, samples, advance_m=float(excess))
        amplitude[rows] = correlation.reshape(rows.sum(), s).double().numpy()
    return amplitude


def _parabolic_peak(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``samples`` (N, S): the index of its maximum and the parabola's vertex offset
    from it [samples, within +-0.5] through the maximum and its two neighbours (0 at the ends)."""
    peak = samples.argmax(1)
    inner = np.clip(peak, 1, samples.shape[1] - 2)
    rows = np.arange(len(samples))
    before, at, after = samples[rows, inner - 1], samples[rows, inner], samples[rows, inner + 1]
    curvature = before - 2 * at + after
    shift = np.where(curvature < 0, 0.5 * (before - after) / np.where(curvature < 0, curvature, -1.0), 0.0)
    shift = np.where((peak > 0) & (peak < samples.shape[1] - 1), np.clip(shift, -0.5, 0.5), 0.0)
    return peak, shift
