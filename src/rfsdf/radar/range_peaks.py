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

A scan (``Acquisition.scans``: a board moved over a planar raster, one view) is searched
along its raster's normal, and each point's line is correlated with the frames of a
*sub-aperture* only: those within ``sqrt(lambda D / 16)`` of the line (D the point's depth
from the raster; the round-trip quadratic phase of a face across them stays under pi / 8).
Focused by the whole aperture as a point, a face the scan sees specularly is not a point:
it returns to every frame from the frame's own foot on it, a wave that focuses further away,
so the whole scan's correlation along a line peaks 6-14 mm behind the faces of preset
``sar-77g``'s scene ``handheld`` (a ball, the one point-like glint, within 1 mm). A small
sub-aperture sees that face within a fraction of a cycle of a point, and too small a one
cannot tell objects at other depths apart (6 mm: within 1.1 mm on the can, the block and the
ball; 1 cm: 0.4-3.6 mm; docs/guide/radar.md, "Scanned views").

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
from scipy.spatial import cKDTree

from ..scene import Scene
from .acquisition import Measurements
from .detection import range_ridges
from .imaging import view_correlation
from .scan_imaging import planar_scan
from .transmission import line_of_sight

__all__ = ["RangePeaks", "range_peaks"]

SPAN_M = 0.015  # how far before and behind a ridge voxel its peak is looked for [m]
STEP_M = 0.0005  # sampling along the line of sight [m]
EXCESS_STEP_M = 2e-5  # lines seen through slabs are grouped by their excess path to this [m]: within 0.02 rad at 79 GHz
SUBAPERTURE_PHASE_RAD = np.pi / 8  # a scan's sub-aperture: the round-trip quadratic phase of a face across it


@dataclass(frozen=True)
class RangePeaks:
    """Surface points seen by the views: points (N, 3) [m], amplitude (N,) (each view's
    correlation at its peak over that view's largest), view (N,) int, towards (N, 3) unit vectors to the
    view along which each peak was found (to its array centre; a planar scan's: against its
    raster's normal)."""

    points: np.ndarray
    amplitude: np.ndarray
    view: np.ndarray
    towards: np.ndarray

    def select(self, kept: np.ndarray) -> RangePeaks:
        """The peaks ``kept`` (N,) bool (or indices), amplitudes as they were."""
        return RangePeaks(self.points[kept], self.amplitude[kept], self.view[kept], self.towards[kept])

    def apexes(self, radius_m: float) -> np.ndarray:
        """(N,) bool: the peaks that are the strongest of their own view's within ``radius_m``
        [m] (ties kept): each glint's centre, where the surface faces the view. Across a curved
        glint the lines of sight beside its centre peak at the centre's range too (the array's
        main lobe), on the glint's tangent plane, where the surface's normal is not the view's."""
        apex = np.ones(len(self.points), bool)
        for view in np.unique(self.view):
            mine = np.flatnonzero(self.view == view)
            for i, neighbours in zip(mine, cKDTree(self.points[mine]).query_ball_point(self.points[mine], radius_m)):
                apex[i] = self.amplitude[i] >= self.amplitude[mine[neighbours]].max()
        return apex


def range_peaks(measurements: Measurements, per_view_power: np.ndarray, grid, *, threshold: float,
                local_threshold: float, window_m: float, keep: np.ndarray | None = None,
                span_m: float = SPAN_M, step_m: float = STEP_M, through: Scene | None = None) -> RangePeaks:
    """The range ridges of each view's detection in ``per_view_power`` (V, nx, ny, nz; the
    detection rule as in :func:`~rfsdf.radar.detection.range_ridges`), only those in ``keep``
    (bool, grid.shape; None: all), each moved to the peak of the view's matched filter of
    ``measurements`` along its line of sight (of a planar scan, along its normal, on the
    sub-aperture before the point), the delay of ``through``'s slabs on it taken out first
    (None: nothing in the way)."""
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
        apertures = None
        normal = _raster_normal(acquisition, view)
        if normal is not None:  # along the raster's normal, each line on the frames before it
            towards = np.broadcast_to(-normal, towards.shape).copy()
            apertures = _subapertures(acquisition, view, points[index], normal)
        excess = None
        if through is not None:
            sight = line_of_sight(through, torch.from_numpy(points[index]), torch.from_numpy(towards),
                                  torch.from_numpy(centres[view]), float(acquisition.frequencies_hz.mean()))
            clear = (sight.factor != 0).numpy()
            index, towards, excess = index[clear], towards[clear], 2 * sight.excess_m.numpy()[clear]
            apertures = None if apertures is None else (apertures[0][clear], apertures[1])
        line = points[index, None, :] - offsets[None, :, None] * towards[:, None, :]
        amplitude = _line_correlation(measurements, view, line, excess, apertures)
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


def _raster_normal(acquisition, view: int) -> np.ndarray | None:
    """(3,) the raster's normal into the scene when view ``view`` is a planar scan (a board
    over a raster), else None (a MIMO frame, or frames that are no raster)."""
    if acquisition.scans is None:
        return None
    try:
        return planar_scan(acquisition.coherent_view(view))[0].axis_z
    except ValueError:
        return None


def _subapertures(acquisition, view: int, points: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, list]:
    """Each point's (N, 3) [m] sub-aperture of scan ``view`` (raster normal ``normal``): the
    index (N,) into a list of frame subsets (indices into ``acquisition.frames(view)``), the
    frames within sqrt(lambda D / 16) of the frame nearest the point's line, D its depth."""
    frames = acquisition.frames(view)
    centres = 0.5 * (acquisition.tx_m[frames].mean(1) + acquisition.rx_m[frames].mean(1)).numpy()  # (F, 3)
    lateral = centres - np.outer(centres @ normal, normal)  # positions across the raster
    offsets = points - np.outer(points @ normal, normal)
    nearest = np.argmin(np.linalg.norm(offsets[:, None] - lateral[None], axis=2), axis=1)
    depth = np.abs((points - centres[nearest]) @ normal)
    wavenumber = 2 * np.pi / acquisition.wavelength_m
    radius = np.sqrt(SUBAPERTURE_PHASE_RAD * depth / wavenumber)  # k a^2 / D = the phase
    keys = np.stack([nearest, np.round(radius / 1e-4).astype(int)], 1)  # radii grouped to 0.1 mm
    groups, members = np.unique(keys, axis=0, return_inverse=True)
    subsets = [torch.from_numpy(np.flatnonzero(np.linalg.norm(lateral - lateral[frame], axis=1) <= key * 1e-4 + 1e-9))
               for frame, key in groups]
    return members.reshape(-1), subsets


def _line_correlation(measurements: Measurements, view: int, lines: np.ndarray,
                      excess_m: np.ndarray | None, apertures: tuple[np.ndarray, list] | None = None) -> np.ndarray:
    """(N, S) float64: the view's correlation (:func:`~rfsdf.radar.imaging.view_correlation`)
    at the points ``lines`` (N, S, 3) [m]; with ``excess_m`` (N,) [m], each line's with the
    view's data advanced by its two-way excess path (grouped to EXCESS_STEP_M, one correlation
    a group); with ``apertures`` (:func:`_subapertures`), each line's on its own frames only.
    By the exact adjoint: the range-profile one's interpolation ripple (0.5 % at its default
    oversampling, with a period of 3 mm of range at 3 GHz) moved the top of a peak as broad
    as c / 2B by 0.7 mm."""
    n, s = lines.shape[:2]
    excess = np.zeros(n) if excess_m is None else np.round(excess_m / EXCESS_STEP_M) * EXCESS_STEP_M
    aperture = np.zeros(n, int) if apertures is None else apertures[0]
    keys, members = np.unique(np.stack([excess, aperture], 1), axis=0, return_inverse=True)
    members = members.reshape(-1)
    amplitude = np.zeros((n, s))
    for group, (advance, subset) in enumerate(keys):
        rows = members == group
        samples = torch.from_numpy(lines[rows].reshape(-1, 3)).float()
        frames = None if apertures is None else apertures[1][int(subset)]
        with torch.no_grad():
            correlation = view_correlation(measurements, view, samples, method="exact", advance_m=float(advance),
                                           frames=frames)
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
