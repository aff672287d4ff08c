"""CLEAN: remove the array's sidelobes from matched-filter images, view by view.

Högbom's CLEAN (1974) with the Cotton-Schwab split into minor and major cycles, using the
exact, shift-variant point spread function of a near-field MIMO view (the sensing operator
knows it). Minor cycle: take the brightest voxel q of the residual image r, record a
component a = gain * r(q), subtract a * h_q, where h_q(x) = A(x)^H A(q) / ||A(x)||^2 is the
column-normalised image of a unit point at q (h_q(q) = 1), evaluated in a window around q.
Major cycle (every ``major_every`` components): the residual image is recomputed over the
whole grid from the residual *data* y - A c, so the far sidelobes outside the windows are
removed exactly too. Stops when the residual peak falls below ``stop_fraction`` of the dirty
peak, or after ``max_components``.

A view that is a planar scan (``Acquisition.scans``) on a grid on its raster's lattice
(``rfsdf.radar.scan_imaging.lattice_grid``) takes the same loop with every image by FFT on
the lattice, the kernels' spectra kept (:class:`~rfsdf.radar.scan_imaging.ScanLattice`): a
component's point response is the image of its point's data on the window's depth planes,
exact. On a scan of preset ``sar-77g`` (1089 frames, 43^3 voxels) the first five
components took 2.5 s against the general path's 140 s, the same components; its four scans
at 300 components 101 s, where they had not ended after 20 minutes (2 cores,
``benchmarks/scan_clean.py``).

The cleaned view image is the components restored with a Gaussian beam of one voxel
(power), plus the residual power; the incoherent mean over views is what a radar engineer
would threshold. Weak objects under a strong one's sidelobes survive it, where the raw MF
image buries them (``benchmarks/object_contrast.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage

from ..errors import RfsdfError
from ..geometry import Grid
from ..progress import progress_bar
from .acquisition import Measurements
from .fast_imaging import fast_adjoint
from .imaging import imaging_method
from .operator import SensingOperator
from .scan_imaging import ScanLattice

__all__ = ["FLOOR_QUANTILE", "MAX_COMPONENTS", "CleanResult", "clean_view", "clean_image"]

# The residual floor is read at the 99th percentile of the voxels, a 1 % false-alarm rate of a
# CFAR detector: on the default demo it is 0.063 of the peak amplitude, on the 36-view radar
# 0.125, the thresholds a sweep against the truth picks on each (docs/results/demo-quality.md).
FLOOR_QUANTILE = 0.99
MAX_COMPONENTS = 300  # per view, unless the residual falls below stop_fraction of its peak first


@dataclass(frozen=True)
class CleanResult:
    """CLEAN of every view of a measurement set on a grid.

    component_index : list of V (C_v,) int64 voxel indices; component_amplitude : list of V
    (C_v,) complex64 [image units]; residual : (V, nx, ny, nz) complex64 residual image;
    per_view_power : (V, nx, ny, nz) float32 restored power of each view (components on a
    one-voxel Gaussian beam + residual power).
    """

    grid: Grid
    component_index: list
    component_amplitude: list
    residual: torch.Tensor
    per_view_power: torch.Tensor

    @property
    def power(self) -> torch.Tensor:
        """(nx, ny, nz) float32 mean over views of the restored power."""
        return self.per_view_power.mean(0)

    def residual_floor(self, quantile: float = FLOOR_QUANTILE) -> float:
        """What CLEAN left unexplained, as a fraction of the peak amplitude: the ``quantile``
        over voxels of the view-mean residual amplitude sqrt(mean_v |r_v|^2), over the
        restored image's peak amplitude. Residual sidelobes and noise reach this level, so a
        detection threshold below it admits them. It grows with the number of views: a glint
        is bright in a few views and is averaged down by the rest, while every view leaves
        a residual up to ``stop_fraction`` of its own peak."""
        floor = (self.residual.abs() ** 2).mean(0).sqrt().numpy()
        peak = float(self.power.max().sqrt())
        return float(np.quantile(floor, quantile)) / max(peak, 1e-30)


def _window(grid: Grid, centre: int, radius: int) -> torch.Tensor:
    """Flat indices (W,) of the voxels within ``radius`` voxels (cube) of voxel ``centre``."""
    nx, ny, nz = grid.shape
    i, j, k = centre // (ny * nz), (centre // nz) % ny, centre % nz
    ranges = [torch.arange(max(0, c - radius), min(n, c + radius + 1)) for c, n in zip((i, j, k), (nx, ny, nz))]
    ii, jj, kk = torch.meshgrid(*ranges, indexing="ij")
    return ((ii * ny + jj) * nz + kk).flatten()


def clean_view(measurements: Measurements, view: int, grid: Grid, *, gain: float = 0.3,
               stop_fraction: float = 0.05, max_components: int = MAX_COMPONENTS, window_m: float = 0.03,
               major_every: int = 50, method: str = "auto", device=None):
    """CLEAN one view: (component indices (C,), amplitudes (C,) complex, residual image (N,) complex).

    The images are column-normalised MF images c_hat = A^H y / ||A||^2 on the voxel centres
    of ``grid``; ``window_m`` is the half-width of the minor cycle's PSF window [m]. The
    whole-grid images (dirty and major cycles) use the imaging ``method`` (see
    :func:`~rfsdf.radar.imaging.matched_filter`); the windowed PSFs are exact
    (:meth:`~rfsdf.radar.operator.SensingOperator.point_response`, factorised over Tx and Rx).
    A scan on ``grid``'s lattice is imaged by :class:`~rfsdf.radar.scan_imaging.ScanLattice`
    throughout, exactly, whatever ``method``.
    The images live on ``device`` (None: CPU); what is returned is on the CPU.
    """
    if not 0 < gain <= 1:
        raise ValueError(f"CLEAN loop gain must be in (0, 1], got {gain}")
    measured = measurements.coherent_view(view)
    acquisition = measured.acquisition
    op = SensingOperator(acquisition)
    fast = imaging_method(acquisition, method, device) == "fast"
    lattice = _scan_lattice(measurements, view, grid, device)
    radius = max(1, int(round(window_m / float(np.max(grid.voxel_m)))))
    y = measured.data.to(device)
    voxels = grid.points(device=device)
    norms = op.column_norms_sq(voxels) if lattice is None else lattice.column_norms_sq.to(device)
    seen = norms > 0
    safe = torch.where(seen, norms, torch.ones_like(norms))

    def normalised(back_projected, index=slice(None)):  # c_hat = A^H y / ||A||^2, 0 where unseen
        return torch.where(seen[index], back_projected / safe[index], 0.0)

    def back_projected(data, planes=slice(None)):  # A^H y on every voxel (of a scan: on its depth planes)
        if lattice is not None:
            return lattice.adjoint(data, planes).to(voxels.device)
        if fast:
            return fast_adjoint(acquisition, data.cpu(), voxels.cpu(), summed=True)[0].to(voxels.device)
        return op.adjoint(data, voxels)

    def image(data):
        return normalised(back_projected(data))

    def point_response(q, window):  # A^H A e_q on the window's voxels
        if lattice is None:  # factorised over Tx and Rx
            return op.point_response(voxels[q], voxels[window])
        depth = np.unravel_index(q, grid.shape)[lattice.depth_axis]
        planes = slice(max(0, depth - radius), depth + radius + 1)  # the window's
        unit = torch.ones(1, dtype=torch.complex64, device=voxels.device)
        return back_projected(op.forward(voxels[q:q + 1], unit), planes)[window]

    residual = image(y)
    stop = stop_fraction * float(residual.abs().max())
    indices: list[int] = []
    amplitudes: list[complex] = []
    with torch.no_grad():
        while len(indices) < max_components:
            q = int(residual.abs().argmax())
            if float(residual[q].abs()) <= stop:
                break
            amplitude = gain * residual[q]
            window = _window(grid, q, radius).to(voxels.device)
            residual[window] -= amplitude * normalised(point_response(q, window), window)
            indices.append(q)
            amplitudes.append(complex(amplitude))
            if len(indices) % major_every == 0:
                # Exact residual from the residual data. A point of reflectivity a at q images
                # to a at q (column normalisation), so a component's data are a * A_q.
                c = torch.tensor(amplitudes, dtype=torch.complex64, device=voxels.device)
                residual = image(y - op.forward(voxels[torch.tensor(indices, device=voxels.device)], c))
    return torch.tensor(indices, dtype=torch.long), torch.tensor(amplitudes, dtype=torch.complex64), residual.cpu()


def _scan_lattice(measurements: Measurements, view: int, grid: Grid, device) -> ScanLattice | None:
    """The lattice imaging of view ``view`` when it is a planar scan (``Acquisition.scans``)
    whose lattice ``grid``'s voxels lie on, else None (a MIMO frame; a scan on another grid).
    Kernels' spectra beyond the memory stop CLEAN with that error (RfsdfError): the general
    path would take hours on such a scan."""
    if measurements.acquisition.scans is None:
        return None
    try:
        return ScanLattice(measurements.acquisition.coherent_view(view), grid, device=device)
    except RfsdfError:
        raise
    except ValueError:  # no raster, or not on this grid
        return None


def clean_image(measurements: Measurements, grid: Grid, *, progress: bool = False, **options) -> CleanResult:
    """CLEAN every view (options as :func:`clean_view`) and restore the incoherent power image."""
    views = measurements.acquisition.num_views
    indices, amplitudes, residuals, restored = [], [], [], []
    for v in progress_bar(range(views), desc="CLEAN", enabled=progress):
        index, amplitude, residual = clean_view(measurements, v, grid, **options)
        indices.append(index)
        amplitudes.append(amplitude)
        residuals.append(residual.reshape(grid.shape))
        components = np.zeros(grid.size, dtype=complex)
        np.add.at(components, index.numpy(), amplitude.numpy())
        beam = ndimage.gaussian_filter(components.real.reshape(grid.shape), 1.0) ** 2 + \
            ndimage.gaussian_filter(components.imag.reshape(grid.shape), 1.0) ** 2
        restored.append(torch.from_numpy(beam / _beam_peak() + residual.abs().reshape(grid.shape).numpy() ** 2).float())
    return CleanResult(grid, indices, amplitudes, torch.stack(residuals), torch.stack(restored))


def _beam_peak() -> float:
    """Peak of a unit component filtered by the one-voxel Gaussian, squared (restored peaks = |a|^2)."""
    impulse = np.zeros((9, 9, 9))
    impulse[4, 4, 4] = 1.0
    return float(ndimage.gaussian_filter(impulse, 1.0).max() ** 2)
