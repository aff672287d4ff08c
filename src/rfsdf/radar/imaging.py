"""Matched-filter (back-projection) images: c_hat_q = A_q^H y / ||A_q||^2, P = |c_hat|^2.

Images are kept per view: ``Image.per_view`` (V, nx, ny, nz) and the per-view column norms,
so that both the coherent image (all views in one A) and the incoherent power sum can be
formed, and so that reconstruction can compare view by view.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch

from ..geometry import Grid
from ..limits import require_memory
from ..progress import progress_bar
from .acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from .fast_imaging import DEFAULT_OVERSAMPLING, fast_adjoint
from .operator import SensingOperator

__all__ = ["IMAGING_METHODS", "FAST_MIN_FREQUENCIES", "imaging_method", "Image", "require_image_memory",
           "matched_filter", "view_correlation", "point_spread", "half_power_width", "safe_divide"]

IMAGING_METHODS = ("auto", "exact", "fast")
# The exact adjoint costs K vectorised complex multiply-adds per pair and voxel (GEMMs), the
# fast one a scalar interpolation: on 2 cores fast is 0.74-1.8x exact at 16 frequencies
# (small grid - demo grid), 3.4-3.9x at 64 and 12-17x at 256 (benchmarks/fast_imaging.py), so
# auto = fast from 32 on.
FAST_MIN_FREQUENCIES = 32


def imaging_method(acquisition: Acquisition, method: str = "auto", device=None) -> str:
    """"exact" or "fast" for ``method`` in IMAGING_METHODS. "auto": fast from
    FAST_MIN_FREQUENCIES on, on the CPU; on a GPU always exact (the fast kernel is a CPU
    kernel, and the exact adjoint is GEMMs that a GPU runs faster than the CPU interpolates)."""
    if method not in IMAGING_METHODS:
        raise ValueError(f"unknown imaging method {method!r}; known: {', '.join(IMAGING_METHODS)}")
    if method == "auto":
        on_cpu = device is None or torch.device(device).type == "cpu"
        return "fast" if on_cpu and acquisition.shape[3] >= FAST_MIN_FREQUENCIES else "exact"
    return method

_IMAGE_BYTES_PER_VOXEL = 8 + 4 + 8  # per view: complex64 image, float32 column norm, the division's temporary


def require_image_memory(views: int, grid: Grid, what: str = "the image") -> None:
    """RfsdfError before imaging when per-view images of ``grid`` cannot fit in memory."""
    require_memory(_IMAGE_BYTES_PER_VOXEL * views * grid.size,
                   f"{what} ({views} views x {grid.shape} voxels; a larger voxel or a smaller box needs less)")


@dataclass(frozen=True)
class Image:
    """Matched-filter image on a grid.

    per_view : (V, nx, ny, nz) complex64, c_hat of each view alone.
    column_norms_sq : (V, nx, ny, nz) float32, ||A_q||^2 of each view.
    """

    grid: Grid
    per_view: torch.Tensor
    column_norms_sq: torch.Tensor

    def coherent(self) -> torch.Tensor:
        """(nx, ny, nz) complex64: the design's c_hat with all views in one A (0 where unseen)."""
        return safe_divide((self.per_view * self.column_norms_sq).sum(0), self.column_norms_sq.sum(0))

    def power(self, *, coherent: bool = False) -> torch.Tensor:
        """(nx, ny, nz) float32: |coherent c_hat|^2, or the mean over views of |c_hat_v|^2."""
        if coherent:
            return self.coherent().abs() ** 2
        return (self.per_view.abs() ** 2).mean(0)


def matched_filter(measurements: Measurements, grid: Grid, *, method: str = "auto",
                   oversampling: int = DEFAULT_OVERSAMPLING, device=None, progress: bool = False) -> Image:
    """Back-project ``measurements`` onto the voxel centres of ``grid``, an image per view (a
    frame, or all frames of a scan summed coherently: ``Acquisition.scans``).

    ``method``: "exact" (the sensing operator's adjoint), "fast" (range-profile
    back-projection, :mod:`rfsdf.radar.fast_imaging`, relative error ~1e-3 at the default
    ``oversampling``; CPU) or "auto" (:func:`imaging_method`; views that are planar raster
    scans whose lattice the grid's voxels lie on by FFT instead,
    :func:`rfsdf.radar.scan_imaging.scan_views_matched_filter`, the exact adjoint to 1e-4 at a
    fraction of its cost). ``device``: where the adjoint runs (None: CPU); the image comes back
    on the CPU.
    """
    acq = measurements.acquisition
    require_image_memory(acq.num_views, grid)
    if method == "auto" and acq.scans is not None:
        from .scan_imaging import scan_views_matched_filter  # that module builds on this one

        try:
            return scan_views_matched_filter(measurements, grid, device=device)
        except ValueError:  # no raster, or the grid is not on its lattice: back-projection
            pass
    points = grid.points(device=device)
    fast = imaging_method(acq, method, device) == "fast"
    if acq.scans is None:
        numerator, norms = _back_projection(acq, measurements.data, points, fast, oversampling, True, progress)
    else:
        parts = [_one_view(measurements, v, points, fast, oversampling)
                 for v in progress_bar(range(acq.num_views), desc="scans", enabled=progress)]
        numerator, norms = (torch.stack(t) for t in zip(*parts))
    shape = (acq.num_views, *grid.shape)
    return Image(grid, safe_divide(numerator, norms).reshape(shape).cpu(), norms.reshape(shape).cpu())


def view_correlation(measurements: Measurements, view: int, points: torch.Tensor, *, method: str = "auto",
                     oversampling: int = DEFAULT_OVERSAMPLING, advance_m: float = 0.0,
                     frames: torch.Tensor | None = None) -> torch.Tensor:
    """(Q,) float: |A_q^H y| / ||A_q|| of view ``view`` alone (a frame, or a scan's frames
    summed coherently) at any ``points`` (Q, 3) [m], not only a grid's voxels; ``method`` as in
    :func:`matched_filter`. The matched filter over the column's norm, not its square as in
    c_hat: by Cauchy-Schwarz a point target's is largest exactly at the point, where |c_hat|
    peaks further from the array (the norm falls with the spreading). ``advance_m`` [m]: the
    view's data advanced by this path first (every element's return made earlier by it, a
    delay taken out). ``frames``: of a scan, only these of its frames (indices (n,) into
    ``acquisition.frames(view)``: a sub-aperture); None: all."""
    fast = imaging_method(measurements.acquisition, method, points.device) == "fast"
    numerator, norms = _one_view(measurements, view, points, fast, oversampling, advance_m, frames)
    return safe_divide(numerator.abs(), norms.sqrt()).reshape(-1)


def _one_view(measurements: Measurements, view: int, points: torch.Tensor, fast: bool,
              oversampling: int, advance_m: float = 0.0,
              subset: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """A_v^H y_v and ||A_v||^2 of view ``view`` at ``points``, each (Q,) or (1, Q), y_v advanced
    by ``advance_m`` [m] of path; of a scan, only its frames ``subset`` (None: all)."""
    acq = measurements.acquisition
    if acq.scans is None:  # a frame, its own view
        frames, view_acq, per_frame = slice(view, view + 1), acq.view(view), True
    else:  # a scan's frames (or those of ``subset``) summed as one view
        frames = acq.frames(view) if subset is None else acq.frames(view)[subset]
        view_acq, per_frame = replace(acq.view(frames), scans=None), False
    data = measurements.data[frames]
    if advance_m:
        phase = 2 * torch.pi * acq.frequencies_hz.double() * advance_m / SPEED_OF_LIGHT
        data = data * torch.polar(torch.ones_like(phase), phase).to(data)
    return _back_projection(view_acq, data, points, fast, oversampling, per_frame, False)


def _back_projection(acq: Acquisition, data: torch.Tensor, points: torch.Tensor, fast: bool, oversampling: int,
                     per_view: bool, progress: bool) -> tuple[torch.Tensor, torch.Tensor]:
    """A^H y and ||A_q||^2 at ``points``, (V, Q) per frame or (Q,) summed over the frames."""
    op = SensingOperator(acq)
    with torch.no_grad():
        if fast:
            numerator = fast_adjoint(acq, data, points.cpu(), oversampling=oversampling, summed=not per_view,
                                     progress=progress).to(points.device)
            numerator = numerator if per_view else numerator[0]
        else:
            numerator = op.adjoint(data.to(points.device), points, per_view=per_view, progress=progress)
        return numerator, op.column_norms_sq(points, per_view=per_view)


def safe_divide(numerator: torch.Tensor, norms: torch.Tensor) -> torch.Tensor:
    """numerator / norms, and 0 for voxels no antenna sees (||A_q|| = 0)."""
    seen = norms > 0
    return torch.where(seen, numerator / torch.where(seen, norms, torch.ones_like(norms)), torch.zeros_like(numerator))


def point_spread(acquisition: Acquisition, point_m, grid: Grid) -> Image:
    """Image of a unit point scatterer at ``point_m`` (3,) [m], noise-free (the PSF)."""
    p = torch.as_tensor(point_m, dtype=torch.float32).reshape(1, 3)
    y = SensingOperator(acquisition).forward(p, torch.ones(1, dtype=torch.complex64))
    return matched_filter(Measurements(acquisition, y), grid, method="exact")


def half_power_width(positions_m: np.ndarray, power: np.ndarray) -> float:
    """-3 dB width [m] of the main lobe of a 1-D power profile (linear interpolation at the edges)."""
    power = np.asarray(power, float) / np.max(power)
    peak = int(np.argmax(power))
    left, right = peak, peak
    while left > 0 and power[left] >= 0.5:
        left -= 1
    while right < len(power) - 1 and power[right] >= 0.5:
        right += 1
    if power[left] >= 0.5 or power[right] >= 0.5:
        raise ValueError("the main lobe is not inside the profile")
    x = np.asarray(positions_m, float)
    cross = lambda a, b: x[a] + (0.5 - power[a]) * (x[b] - x[a]) / (power[b] - power[a])  # noqa: E731
    return float(cross(right - 1, right) - cross(left, left + 1))
