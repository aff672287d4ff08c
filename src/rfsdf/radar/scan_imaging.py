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
operator's adjoint (spreading included, an isotropic pattern), not a stationary-phase
approximation as the range-migration (omega-k) algorithm is; it costs O(P K Z L log L) for L
lateral samples against O(P K Z L N) for back-projection over N positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import fft as scipy_fft

from .acquisition import SPEED_OF_LIGHT

__all__ = ["PlanarScan", "scan_image", "scan_voxels"]

_KERNEL_BYTES = 1 << 27  # kernels built at once, per chunk of frequencies


@dataclass(frozen=True)
class PlanarScan:
    """A rigid board over a raster: position (a, b) at ``origin_m + a dx e_x + b dy e_y``.

    origin_m, axis_x, axis_y : (3,) [m], orthonormal axes. steps_m : (dx, dy) [m].
    shape : (nx, ny) positions. tx_offsets_m, rx_offsets_m : (P, 3) [m], each pair's Tx and
    Rx relative to the position. frequencies_hz : (K,).
    """

    origin_m: np.ndarray
    axis_x: np.ndarray
    axis_y: np.ndarray
    steps_m: tuple[float, float]
    shape: tuple[int, int]
    tx_offsets_m: np.ndarray
    rx_offsets_m: np.ndarray
    frequencies_hz: np.ndarray

    def __post_init__(self):
        ex, ey = np.asarray(self.axis_x, float), np.asarray(self.axis_y, float)
        if abs(np.linalg.norm(ex) - 1) > 1e-9 or abs(np.linalg.norm(ey) - 1) > 1e-9 or abs(ex @ ey) > 1e-9:
            raise ValueError("axis_x and axis_y must be orthonormal")
        if np.shape(self.tx_offsets_m) != np.shape(self.rx_offsets_m) or np.shape(self.tx_offsets_m)[1:] != (3,):
            raise ValueError("tx_offsets_m and rx_offsets_m must both be (P, 3)")
        if min(self.shape) < 1 or min(self.steps_m) <= 0:
            raise ValueError(f"shape must be >= 1 and steps_m > 0, got {self.shape}, {self.steps_m}")

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


def scan_image(scan: PlanarScan, data: torch.Tensor, first: tuple[int, int], count: tuple[int, int],
               depths_m: np.ndarray, *, device=None) -> torch.Tensor:
    """A^H y of the whole scan on :func:`scan_voxels` (``first``, ``count``, ``depths_m``):
    (nxi, nyi, Z) complex128 on the CPU. ``data`` (nx, ny, P, K) complex, the positions'
    samples; the FFTs run on ``device`` (None: the CPU)."""
    nx, ny = scan.shape
    p_total, k_total = len(scan.tx_offsets_m), len(scan.frequencies_hz)
    if tuple(data.shape) != (nx, ny, p_total, k_total):
        raise ValueError(f"data must be (nx, ny, P, K) = {(nx, ny, p_total, k_total)}, got {tuple(data.shape)}")
    lx, ly = (scipy_fft.next_fast_len(n + c - 1) for n, c in zip(scan.shape, count))
    device = torch.device(device or "cpu")
    y = torch.zeros(p_total, k_total, lx, ly, dtype=torch.complex128, device=device)
    y[:, :, :nx, :ny] = data.to(device, torch.complex128).permute(2, 3, 0, 1)
    spectra = torch.fft.fft2(y)  # (P, K, lx, ly)
    # the kernel's lateral offsets m = i - a, from first - (n - 1), laid out so that the
    # circular convolution's samples n - 1 .. n + count - 2 are the linear one's
    m = first[0] - (nx - 1) + np.arange(lx)
    n = first[1] - (ny - 1) + np.arange(ly)
    lateral = (m[:, None, None] * scan.steps_m[0] * np.asarray(scan.axis_x, float)
               + n[None, :, None] * scan.steps_m[1] * np.asarray(scan.axis_y, float))  # (lx, ly, 3)
    wavenumbers = torch.from_numpy(2 * np.pi * np.asarray(scan.frequencies_hz, float) / SPEED_OF_LIGHT).to(device)
    chunk = max(1, _KERNEL_BYTES // (16 * lx * ly))
    image = torch.zeros(count[0], count[1], len(depths_m), dtype=torch.complex128, device=device)
    for z_index, depth in enumerate(np.asarray(depths_m, float)):
        w = torch.from_numpy(lateral + depth * scan.axis_z).to(device)
        total = torch.zeros(lx, ly, dtype=torch.complex128, device=device)
        for p in range(p_total):
            d_tx, d_rx = (torch.linalg.vector_norm(w - torch.as_tensor(np.asarray(offsets[p], float), device=device),
                                                   dim=-1) for offsets in (scan.tx_offsets_m, scan.rx_offsets_m))
            path, spread = d_tx + d_rx, 1.0 / (d_tx * d_rx)
            for start in range(0, k_total, chunk):
                k = wavenumbers[start:start + chunk, None, None]
                kernel = torch.polar(spread.expand(len(k), -1, -1), k * path)
                total += (spectra[p, start:start + chunk] * torch.fft.fft2(kernel)).sum(0)
        image[:, :, z_index] = torch.fft.ifft2(total)[nx - 1:nx - 1 + count[0], ny - 1:ny - 1 + count[1]]
    return image.cpu()
