"""Coherent imaging of a planar scan by FFT convolution: the exact matched filter, fast.

A board (its Tx/Rx pairs at fixed offsets) translated over a planar raster sees every voxel
of a grid laid on the raster's own lattice through the same kernel, shifted: the operator's
column for position (a, b) and voxel (i, j, z) depends on (i - a, j - b, z) alone. So the
matched filter A^H y of the whole scan, summed coherently over positions, pairs and
frequencies, is a 2-D convolution per depth, done by FFT:

    image(i, j, z) = sum_{p, k} IFFT2[ FFT2(y_pk) FFT2(h_pkz) ],
    h_pkz(m, n) = exp(+j 2 pi f_k (|T_p - w| + |R_p - w|) / c) / (|T_p - w| |R_p - w|),
    w = m dx e_x + n dy e_y + z e_z,

with T_p, R_p the pair's offsets from the position and e_z = e_x x e_y. It is the exact
operator's adjoint (spreading and the antenna pattern included), not a stationary-phase
approximation as the range-migration (omega-k) algorithm is; it costs O(P K Z L log L) for L
lateral samples against O(P K Z L N) for back-projection over N positions.

Measurements whose frames are the positions of one board (as ``rfsdf import`` makes them)
are such a scan when the positions fill a planar raster: :func:`planar_scan` finds it, and
:func:`scan_matched_filter` images the whole scan as one coherent view on the raster's
lattice; :func:`scan_views_matched_filter` images each scan of ``Acquisition.scans`` (one a
turntable angle, as preset ``sar-77g``) so, on a grid that lies on every scan's lattice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import fft as scipy_fft

from ..geometry import Grid
from ..limits import require_memory
from .acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from .imaging import Image, safe_divide

__all__ = ["PlanarScan", "ScanLattice", "planar_scan", "scan_image", "scan_column_norms", "scan_voxels",
           "scan_matched_filter", "scan_views_matched_filter", "lattice_grid"]

_KERNEL_BYTES = 1 << 27  # kernels built at once, per chunk of frequencies


@dataclass(frozen=True)
class PlanarScan:
    """A rigid board over a raster: position (a, b) at ``origin_m + a dx e_x + b dy e_y``.

    origin_m, axis_x, axis_y : (3,) [m], orthonormal axes. steps_m : (dx, dy) [m].
    shape : (nx, ny) positions. tx_offsets_m, rx_offsets_m : (P, 3) [m], each pair's Tx and
    Rx relative to the position. frequencies_hz : (K,). boresight : (3,) unit vector of the
    antennas' cos^n pattern, ``pattern_exponent`` n (0: isotropic); ``spreading``: the
    1 / (d_tx d_rx) factor, as :class:`~rfsdf.radar.Acquisition`'s.
    """

    origin_m: np.ndarray
    axis_x: np.ndarray
    axis_y: np.ndarray
    steps_m: tuple[float, float]
    shape: tuple[int, int]
    tx_offsets_m: np.ndarray
    rx_offsets_m: np.ndarray
    frequencies_hz: np.ndarray
    boresight: np.ndarray | None = None
    pattern_exponent: float = 0.0
    spreading: bool = True

    def __post_init__(self):
        ex, ey = np.asarray(self.axis_x, float), np.asarray(self.axis_y, float)
        if abs(np.linalg.norm(ex) - 1) > 1e-9 or abs(np.linalg.norm(ey) - 1) > 1e-9 or abs(ex @ ey) > 1e-9:
            raise ValueError("axis_x and axis_y must be orthonormal")
        if np.shape(self.tx_offsets_m) != np.shape(self.rx_offsets_m) or np.shape(self.tx_offsets_m)[1:] != (3,):
            raise ValueError("tx_offsets_m and rx_offsets_m must both be (P, 3)")
        if min(self.shape) < 1 or min(self.steps_m) <= 0:
            raise ValueError(f"shape must be >= 1 and steps_m > 0, got {self.shape}, {self.steps_m}")
        if self.pattern_exponent > 0 and self.boresight is None:
            raise ValueError("a pattern_exponent > 0 needs the boresight")

    @property
    def axis_z(self) -> np.ndarray:
        """e_x x e_y: the raster's normal, into the scene."""
        return np.cross(self.axis_x, self.axis_y)

    def positions_m(self) -> np.ndarray:
        """(nx, ny, 3) [m] the raster positions."""
        a, b = np.meshgrid(np.arange(self.shape[0]), np.arange(self.shape[1]), indexing="ij")
        return (np.asarray(self.origin_m, float) + a[..., None] * self.steps_m[0] * np.asarray(self.axis_x, float)
                + b[..., None] * self.steps_m[1] * np.asarray(self.axis_y, float))


def scan_voxels(scan: PlanarScan, first: tuple[int, int], count: tuple[int, int], depths_m: np.ndarray) -> np.ndarray:
    """(nxi, nyi, Z, 3) [m] the voxels :func:`scan_image` images: lateral indices ``first`` +
    0..``count`` - 1 on the raster's lattice, at ``depths_m`` (Z,) along e_z from it."""
    i = np.arange(first[0], first[0] + count[0])
    j = np.arange(first[1], first[1] + count[1])
    ii, jj, zz = np.meshgrid(i, j, np.asarray(depths_m, float), indexing="ij")
    return (np.asarray(scan.origin_m, float) + ii[..., None] * scan.steps_m[0] * np.asarray(scan.axis_x, float)
            + jj[..., None] * scan.steps_m[1] * np.asarray(scan.axis_y, float) + zz[..., None] * scan.axis_z)


def _fft_shape(scan: PlanarScan, count: tuple[int, int]) -> tuple[int, int]:
    """(lx, ly): the FFT size at which the circular convolution of the scan's positions with
    ``count`` voxels' kernel offsets is the linear one."""
    return tuple(scipy_fft.next_fast_len(n + c - 1) for n, c in zip(scan.shape, count))


def _lateral_offsets(scan: PlanarScan, first: tuple[int, int], count: tuple[int, int]) -> np.ndarray:
    """(lx, ly, 3) [m] the kernel offsets on the lattice, laid out so that the circular
    convolution over the (lx, ly) FFT of the scan's (nx, ny) positions is the linear one for
    the voxels ``first`` .. ``first + count``."""
    nx, ny = scan.shape
    lx, ly = _fft_shape(scan, count)
    m = first[0] - (nx - 1) + np.arange(lx)
    n = first[1] - (ny - 1) + np.arange(ly)
    return (m[:, None, None] * scan.steps_m[0] * np.asarray(scan.axis_x, float)
            + n[None, :, None] * scan.steps_m[1] * np.asarray(scan.axis_y, float))


def _pair_kernels(scan: PlanarScan, lateral: np.ndarray, depth: float, device: torch.device):
    """Each pair's kernel at one depth: (p, amplitude, path) with amplitude and path (lx, ly)
    float64 [m] at the offsets ``lateral`` (:func:`_lateral_offsets`) ``depth`` along e_z."""
    boresight = None if scan.boresight is None else torch.as_tensor(np.asarray(scan.boresight, float), device=device)
    w = torch.from_numpy(lateral + depth * scan.axis_z).to(device)
    for p in range(len(scan.tx_offsets_m)):
        rel = [w - torch.as_tensor(np.asarray(offsets[p], float), device=device)
               for offsets in (scan.tx_offsets_m, scan.rx_offsets_m)]
        d_tx, d_rx = (torch.linalg.vector_norm(r, dim=-1) for r in rel)
        amplitude = 1.0 / (d_tx * d_rx) if scan.spreading else torch.ones_like(d_tx)
        if scan.pattern_exponent > 0:
            cos = [((r @ boresight) / d).clamp(min=0) for r, d in zip(rel, (d_tx, d_rx))]
            amplitude = amplitude * (cos[0] * cos[1]) ** scan.pattern_exponent
        yield p, amplitude, d_tx + d_rx


def _convolved(scan: PlanarScan, first: tuple[int, int], count: tuple[int, int], depths_m: np.ndarray,
               device: torch.device, spectrum) -> torch.Tensor:
    """(nxi, nyi, Z) complex128: sum over pairs p of IFFT2[``spectrum``(p, amplitude, path)] at each
    depth, cropped to the linear convolution's samples of the voxels ``first`` .. ``first + count``.
    ``spectrum`` gets the pair's kernel amplitude and path length (lx, ly) [m]
    (:func:`_pair_kernels`)."""
    nx, ny = scan.shape
    lx, ly = _fft_shape(scan, count)
    lateral = _lateral_offsets(scan, first, count)
    image = torch.zeros(count[0], count[1], len(depths_m), dtype=torch.complex128, device=device)
    for z_index, depth in enumerate(np.asarray(depths_m, float)):
        total = torch.zeros(lx, ly, dtype=torch.complex128, device=device)
        for p, amplitude, path in _pair_kernels(scan, lateral, depth, device):
            total += spectrum(p, amplitude, path)
        image[:, :, z_index] = torch.fft.ifft2(total)[nx - 1:nx - 1 + count[0], ny - 1:ny - 1 + count[1]]
    return image


def scan_image(scan: PlanarScan, data: torch.Tensor, first: tuple[int, int], count: tuple[int, int],
               depths_m: np.ndarray, *, device=None) -> torch.Tensor:
    """A^H y of the whole scan on :func:`scan_voxels` (``first``, ``count``, ``depths_m``):
    (nxi, nyi, Z) complex128 on the CPU. ``data`` (nx, ny, P, K) complex, the positions'
    samples; the FFTs run on ``device`` (None: the CPU)."""
    nx, ny = scan.shape
    p_total, k_total = len(scan.tx_offsets_m), len(scan.frequencies_hz)
    if tuple(data.shape) != (nx, ny, p_total, k_total):
        raise ValueError(f"data must be (nx, ny, P, K) = {(nx, ny, p_total, k_total)}, got {tuple(data.shape)}")
    lx, ly = _fft_shape(scan, count)
    device = torch.device(device or "cpu")
    y = torch.zeros(p_total, k_total, lx, ly, dtype=torch.complex128, device=device)
    y[:, :, :nx, :ny] = data.to(device, torch.complex128).permute(2, 3, 0, 1)
    spectra = torch.fft.fft2(y)  # (P, K, lx, ly)
    wavenumbers = torch.from_numpy(2 * np.pi * np.asarray(scan.frequencies_hz, float) / SPEED_OF_LIGHT).to(device)
    chunk = max(1, _KERNEL_BYTES // (16 * lx * ly))

    def spectrum(p, amplitude, path):
        total = torch.zeros(lx, ly, dtype=torch.complex128, device=device)
        for start in range(0, k_total, chunk):
            kernel = torch.polar(amplitude.expand(len(wavenumbers[start:start + chunk]), -1, -1),
                                 wavenumbers[start:start + chunk, None, None] * path)
            total += (spectra[p, start:start + chunk] * torch.fft.fft2(kernel)).sum(0)
        return total

    return _convolved(scan, first, count, depths_m, device, spectrum).cpu()


def scan_column_norms(scan: PlanarScan, first: tuple[int, int], count: tuple[int, int], depths_m: np.ndarray, *,
                      device=None) -> torch.Tensor:
    """||A_q||^2 of the whole scan at :func:`scan_voxels`: (nxi, nyi, Z) float64 on the CPU, the
    sum over positions, pairs and frequencies of the kernel's squared amplitude (a convolution
    of the raster's indicator with it)."""
    device = torch.device(device or "cpu")
    lx, ly = _fft_shape(scan, count)
    indicator = torch.zeros(lx, ly, dtype=torch.complex128, device=device)
    indicator[:scan.shape[0], :scan.shape[1]] = len(scan.frequencies_hz)
    raster = torch.fft.fft2(indicator)
    norms = _convolved(scan, first, count, depths_m, device,
                       lambda p, amplitude, path: raster * torch.fft.fft2(amplitude.to(torch.complex128) ** 2))
    return norms.real.clamp(min=0).cpu()


def _clusters(values: np.ndarray, tolerance: float) -> np.ndarray:
    """Sorted centres of the groups of ``values`` (N,) that lie within ``tolerance`` of a neighbour."""
    ordered = np.sort(values)
    breaks = np.flatnonzero(np.diff(ordered) > tolerance) + 1
    return np.array([group.mean() for group in np.split(ordered, breaks)])


def _lattice(coordinates: np.ndarray, tolerance: float, axis: str) -> tuple[np.ndarray, float]:
    """Integer indices (N,) of ``coordinates`` (N,) [m] on a regular lattice, and its step [m]."""
    centres = _clusters(coordinates, tolerance)
    if len(centres) == 1:
        return np.zeros(len(coordinates), int), 1.0
    step = float(np.median(np.diff(centres)))
    index = np.round((coordinates - centres[0]) / step).astype(int)
    off = np.abs(coordinates - centres[0] - index * step).max()
    if off > tolerance:
        raise ValueError(f"the positions along the raster's {axis} axis are not {step * 1e3:.3g} mm apart: "
                         f"one is {off * 1e3:.3g} mm off the lattice")
    return index, step


def planar_scan(acquisition: Acquisition, *, tolerance: float = 0.1) -> tuple[PlanarScan, np.ndarray]:
    """The planar raster whose positions are the views of ``acquisition``, and each view's
    position index (V, 2) on it.

    Every view must be the same board (Tx and Rx at the same offsets from its first Tx, the
    same boresight) at a position of a full raster: a lattice of two orthogonal axes in a
    plane, each position once, in any order (raster, serpentine), within ``tolerance`` of a
    step of the lattice. e_x is the direction to the nearest neighbour of the first view's
    position, e_z = e_x x e_y faces the boresight. ValueError, naming what is not a scan,
    otherwise.
    """
    tx, rx = acquisition.tx_m.numpy(), acquisition.rx_m.numpy()
    positions = tx[:, 0]
    if len(positions) < 2:
        raise ValueError("a scan needs at least two views (positions)")
    tx_offsets, rx_offsets = tx - positions[:, None], rx - positions[:, None]
    spread = max(np.abs(tx_offsets - tx_offsets[0]).max(), np.abs(rx_offsets - rx_offsets[0]).max())
    if spread > 1e-6:
        raise ValueError(f"the views are not one board moved: its antennas' offsets differ by up to {spread * 1e3:.3g} mm")
    boresight = acquisition.boresight.numpy()
    if np.abs(boresight - boresight[0]).max() > 1e-6:
        raise ValueError("the views are not one board moved: their boresights differ")
    relative = positions - positions[0]
    distance = np.linalg.norm(relative, axis=1)
    distance[0] = np.inf
    nearest = float(distance.min())
    if nearest < 1e-9:
        raise ValueError("two views share a position; a scan has each position once")
    axis_x = relative[int(np.argmin(distance))] / nearest
    centred = positions - positions.mean(0)
    vt = np.linalg.svd(centred, full_matrices=False)[2]
    across = centred - np.outer(centred @ axis_x, axis_x)
    normal = vt[2] if np.linalg.norm(across, axis=1).max() > tolerance * nearest else boresight[0]
    axis_y = np.cross(normal, axis_x)
    if np.linalg.norm(axis_y) < 1e-6:
        raise ValueError("the scan's line runs along the boresight; a raster lies across it")
    axis_y /= np.linalg.norm(axis_y)
    if np.cross(axis_x, axis_y) @ boresight[0] < 0:
        axis_y = -axis_y
    out_of_plane = np.abs(relative @ np.cross(axis_x, axis_y)).max()
    if out_of_plane > tolerance * nearest:
        raise ValueError(f"the positions are not in one plane: one is {out_of_plane * 1e3:.3g} mm off it")
    ix, step_x = _lattice(relative @ axis_x, tolerance * nearest, "x")
    iy, step_y = _lattice(relative @ axis_y, tolerance * nearest, "y")
    ix, iy = ix - ix.min(), iy - iy.min()
    shape = (int(ix.max()) + 1, int(iy.max()) + 1)
    filled = np.zeros(shape, int)
    np.add.at(filled, (ix, iy), 1)
    if (filled != 1).any():
        raise ValueError(f"the positions do not fill a {shape[0]} x {shape[1]} raster: {int((filled == 0).sum())} "
                         f"missing, {int((filled > 1).sum())} taken twice")
    origin = positions[0] + (ix.min() - ix[0]) * step_x * axis_x + (iy.min() - iy[0]) * step_y * axis_y
    t, r = tx.shape[1], rx.shape[1]
    scan = PlanarScan(origin, axis_x, axis_y, (step_x, step_y), shape, np.repeat(tx_offsets[0], r, 0),
                      np.tile(rx_offsets[0], (t, 1)), acquisition.frequencies_hz.numpy(), boresight[0],
                      acquisition.pattern_exponent, acquisition.spreading)
    return scan, np.stack([ix, iy], 1)


def _scene_axis(direction: np.ndarray, name: str) -> int:
    """The scene axis (0, 1, 2) that ``direction`` (3,) runs along (either way)."""
    axis = int(np.argmax(np.abs(direction)))
    if abs(direction[axis]) < 1 - 1e-6:
        raise ValueError(f"the raster's {name} axis {np.round(direction, 4).tolist()} is not along a scene axis; "
                         "scan imaging images on the raster's lattice in the scene frame")
    return axis


@dataclass(frozen=True)
class _Placement:
    """Where a grid's box meets a scan's lattice: the voxels ``first`` .. ``first + count``
    across the raster at ``depths_m`` along its normal (:func:`scan_voxels`); ``order`` and
    ``backwards`` turn the lattice's (x, y, normal) dimensions into the scene's; ``grid`` the
    lattice's voxels of the box in the scene frame."""

    first: tuple[int, int]
    count: tuple[int, int]
    depths_m: np.ndarray
    order: tuple[int, int, int]
    backwards: list
    grid: Grid

    def to_scene(self, lattice_image: torch.Tensor) -> torch.Tensor:
        """(nxi, nyi, Z, ...) on the lattice -> the same values on ``grid``'s (nx, ny, nz, ...)."""
        return lattice_image.permute(*self.order, *range(3, lattice_image.dim())).flip(self.backwards)


def _placement(scan: PlanarScan, grid: Grid) -> _Placement:
    """The lattice voxels of ``grid``'s box: at the raster's steps across it and at ``grid``'s
    voxels along its normal. The raster's axes must run along scene axes (ValueError)."""
    axes = [_scene_axis(scan.axis_x, "x"), _scene_axis(scan.axis_y, "y"), _scene_axis(scan.axis_z, "normal")]
    lower, upper = np.asarray(grid.lower_m, float), np.asarray(grid.upper_m, float)
    first, count, lattice = [], [], []
    for direction, step, axis in zip((scan.axis_x, scan.axis_y), scan.steps_m, axes):
        sign = np.sign(direction[axis])
        ends = sorted(((lower[axis] - scan.origin_m[axis]) * sign / step, (upper[axis] - scan.origin_m[axis]) * sign / step))
        start, stop = int(np.ceil(ends[0])), int(np.floor(ends[1]))
        if stop < start:
            raise ValueError(f"the box holds no lattice point of the raster along scene axis {'xyz'[axis]}")
        first.append(start), count.append(stop - start + 1)
        lattice.append(scan.origin_m[axis] + sign * step * np.arange(start, stop + 1))
    depth_axis = axes[2]
    depths = (grid.axes()[depth_axis] - scan.origin_m[depth_axis]) / scan.axis_z[depth_axis]
    order = tuple(int(d) for d in np.argsort(axes))  # the lattice's (x, y, normal) dimensions in scene order
    backwards = [axis for direction, axis in zip((scan.axis_x, scan.axis_y), axes) if direction[axis] < 0]
    out_lower, out_upper, shape = lower.copy(), upper.copy(), list(grid.shape)
    for values, step, axis in zip(lattice, scan.steps_m, axes):
        out_lower[axis], out_upper[axis], shape[axis] = values.min() - step / 2, values.max() + step / 2, len(values)
    return _Placement(tuple(first), tuple(count), depths, order, backwards,
                      Grid(tuple(out_lower), tuple(out_upper), tuple(shape)))


def _positions_data(frames_data: torch.Tensor, scan: PlanarScan, index: np.ndarray,
                    dtype=torch.complex128) -> torch.Tensor:
    """(nx, ny, P, K): the frames' samples ``frames_data`` (F, T, R, K) at their raster positions
    ``index`` (F, 2)."""
    data = torch.zeros(*scan.shape, len(scan.tx_offsets_m), len(scan.frequencies_hz), dtype=dtype)
    data[index[:, 0], index[:, 1]] = frames_data.reshape(len(index), -1, data.shape[-1]).to(dtype)
    return data


def scan_matched_filter(measurements: Measurements, grid: Grid, *, raster=None, device=None) -> Image:
    """The matched filter of a scan (:func:`planar_scan`) as one coherent view, on the raster's
    lattice: the voxels of ``grid``'s box at the raster's steps across it and at ``grid``'s
    voxels along its normal. The raster's axes must run along scene axes. ``raster``:
    :func:`planar_scan`'s answer for these measurements, when the caller has it. Returns an
    :class:`~rfsdf.radar.imaging.Image` with one view on that lattice grid."""
    scan, index = raster or planar_scan(measurements.acquisition)
    placement = _placement(scan, grid)
    pairs, frequencies = len(scan.tx_offsets_m), len(scan.frequencies_hz)
    padded = int(np.prod(_fft_shape(scan, placement.count)))
    require_memory(16 * pairs * frequencies * (int(np.prod(scan.shape)) + 2 * padded),
                   f"the spectra of a {scan.shape[0]} x {scan.shape[1]} scan ({pairs} pairs, {frequencies} frequencies)")
    data = _positions_data(measurements.data, scan, index)
    numerator = scan_image(scan, data, placement.first, placement.count, placement.depths_m, device=device)
    norms = scan_column_norms(scan, placement.first, placement.count, placement.depths_m, device=device)
    numerator, norms = placement.to_scene(numerator), placement.to_scene(norms)
    return Image(placement.grid, safe_divide(numerator, norms).to(torch.complex64)[None], norms.to(torch.float32)[None])


def _require_lattice(scan: PlanarScan, grid: Grid, name: str) -> _Placement:
    """The scan's placement on ``grid``, whose voxels must be the lattice's (ValueError, naming
    ``name``, otherwise)."""
    placement = _placement(scan, grid)
    if placement.grid.shape != grid.shape or not np.allclose(placement.grid.lower_m, grid.lower_m, atol=1e-6):
        raise ValueError(f"{name}'s raster ({scan.steps_m[0] * 1e3:.3g} x {scan.steps_m[1] * 1e3:.3g} mm "
                         f"steps) does not put its lattice on the grid's {np.round(np.asarray(grid.voxel_m) * 1e3, 3).tolist()} "
                         "mm voxels; a voxel of the scan's step, aligned with its positions, does")
    return placement


class ScanLattice:
    """The matched filter of one planar scan (``acquisition``'s frames, :func:`planar_scan`)
    on ``grid``, whose voxels lie on its lattice, with the kernels' spectra kept: Z P K FFTs of
    the padded lattice, complex64 (0.5 GB for a scan of preset ``sar-77g`` over scene
    ``handheld`` at 3 mm). Each further image then costs P K FFTs and Z P K products instead of
    every kernel built again: CLEAN's image of each component on a scan."""

    def __init__(self, acquisition: Acquisition, grid: Grid, *, device=None):
        self.scan, self._index = planar_scan(acquisition)
        self._placement = _require_lattice(self.scan, grid, "the scan")
        self._device = torch.device(device or "cpu")
        first, count, depths = self._placement.first, self._placement.count, self._placement.depths_m
        lx, ly = _fft_shape(self.scan, count)
        pairs, frequencies = len(self.scan.tx_offsets_m), len(self.scan.frequencies_hz)
        require_memory(8 * len(depths) * pairs * frequencies * lx * ly,
                       f"the kernels' spectra of a {self.scan.shape[0]} x {self.scan.shape[1]} scan on {len(depths)} depths")
        wavenumbers = torch.from_numpy(2 * np.pi * self.scan.frequencies_hz / SPEED_OF_LIGHT).to(self._device)
        self._spectra = torch.empty(len(depths), pairs, frequencies, lx, ly, dtype=torch.complex64, device=self._device)
        lateral = _lateral_offsets(self.scan, first, count)
        chunk = max(1, _KERNEL_BYTES // (16 * lx * ly))
        for z, depth in enumerate(depths):
            for p, amplitude, path in _pair_kernels(self.scan, lateral, depth, self._device):
                for start in range(0, frequencies, chunk):
                    k = wavenumbers[start:start + chunk, None, None]
                    kernel = torch.polar(amplitude.expand(len(k), -1, -1), k * path)
                    self._spectra[z, p, start:start + chunk] = torch.fft.fft2(kernel)
        norms = scan_column_norms(self.scan, first, count, depths, device=self._device)
        self.column_norms_sq = self._placement.to_scene(norms).reshape(-1).float()  # (N,) in grid order

    @property
    def depth_axis(self) -> int:
        """The scene axis (0, 1, 2) along the raster's normal: the grid's depth planes."""
        return self._placement.order.index(2)

    def adjoint(self, data: torch.Tensor, planes: slice = slice(None)) -> torch.Tensor:
        """A^H y on the grid's voxels: (N,) complex64 on the CPU, from ``data`` (F, T, R, K), the
        scan's frames in the acquisition's order; only on the depth ``planes`` (indices along
        :attr:`depth_axis`), 0 elsewhere."""
        (nx, ny), count = self.scan.shape, self._placement.count
        lx, ly = self._spectra.shape[-2:]
        y = torch.zeros(*self._spectra.shape[1:3], lx, ly, dtype=torch.complex64, device=self._device)
        positions = _positions_data(data, self.scan, self._index, torch.complex64).to(self._device)
        y[..., :nx, :ny] = positions.permute(2, 3, 0, 1)
        spectra = torch.fft.fft2(y)
        image = torch.zeros(*count, len(self._spectra), dtype=torch.complex64, device=self._device)
        for z in range(len(self._spectra))[planes]:
            total = (spectra * self._spectra[z]).sum((0, 1))
            image[:, :, z] = torch.fft.ifft2(total)[nx - 1:nx - 1 + count[0], ny - 1:ny - 1 + count[1]]
        return self._placement.to_scene(image).reshape(-1).cpu()


def scan_views_matched_filter(measurements: Measurements, grid: Grid, *, device=None) -> Image:
    """The matched filter of every scan of ``measurements`` (``Acquisition.scans``; none: its
    frames are one scan) as one view each, by :func:`scan_matched_filter`, on ``grid``, whose
    voxels must lie on every raster's lattice (voxel and step alike, centres on the lattice's
    points; otherwise ValueError saying so). An :class:`~rfsdf.radar.imaging.Image`, a view a scan."""
    acq = measurements.acquisition
    views = [measurements.coherent_view(v) for v in range(acq.num_views)] if acq.scans is not None else [measurements]
    images = []
    for v, view in enumerate(views):
        raster = planar_scan(view.acquisition)
        _require_lattice(raster[0], grid, f"scan {v}")
        images.append(scan_matched_filter(view, grid, raster=raster, device=device))
    return Image(grid, torch.cat([i.per_view for i in images]), torch.cat([i.column_norms_sq for i in images]))


def lattice_grid(acquisition: Acquisition, lower_m, upper_m) -> Grid:
    """The grid of the box [lower_m, upper_m] whose cubic voxels are the scans' step and whose
    voxel centres lie on every scan's raster lattice: the grid :func:`scan_views_matched_filter`
    images on, where the scans share one (rasters along scene axes, one step, as the views of
    preset ``sar-77g``, a turntable's quarter turns apart). Along an axis no raster runs, the
    first scan's origin anchors the voxels."""
    views = [acquisition] if acquisition.scans is None else [acquisition.coherent_view(v)
                                                             for v in range(acquisition.num_views)]
    scans = [planar_scan(view)[0] for view in views]
    step = min(min(scan.steps_m) for scan in scans)
    anchor = np.array(scans[0].origin_m, float)
    anchored = [False] * 3
    for scan in scans:
        for direction in (scan.axis_x, scan.axis_y):
            axis = int(np.argmax(np.abs(direction)))
            if not anchored[axis]:
                anchor[axis], anchored[axis] = scan.origin_m[axis], True
    lower = anchor + np.floor((np.asarray(lower_m, float) - anchor) / step - 1e-9) * step - step / 2
    upper = anchor + np.ceil((np.asarray(upper_m, float) - anchor) / step + 1e-9) * step + step / 2
    return Grid(tuple(lower), tuple(upper), tuple(int(n) for n in np.round((upper - lower) / step)))
