"""Range-profile back-projection: the matched filter A^H y at O(1) per Tx/Rx pair and voxel.

The exact adjoint sums K frequencies for every (view, Tx i, Rx j, voxel q):

    x_q = sum_ij a_i(q) b_j(q) sum_k y_ijk exp(+j k_k P),   P = d(s_i, q) + d(q, r_j),

with a, b the element amplitudes (pattern / distance) and k_k = 2 pi f_k / c. Taking the
band-centre wavenumber k_c out of the inner sum leaves a smooth function of the bistatic
path length alone, the pair's *range profile*

    s_ij(P) = sum_k y_ijk exp(+j (k_k - k_c) P),

whose spectrum lies within |k_k - k_c| <= pi B / c, so it is sampled on a grid of spacing
h = c / (oversampling B) over the scene's path interval once per pair (one small matrix
product: the zero-padded inverse FFT evaluated only where the scene is) and each voxel
reads it by linear interpolation: x_q = sum_ij a_i b_j exp(j k_c P) s_ij(P). The cost per
pair and voxel drops from K complex multiply-adds to one interpolation. The interpolation
error of a tone of phase step w h = pi / oversampling is at most (w h)^2 / 8, so the image
error falls as 1 / oversampling^2 (``benchmarks/fast_imaging.py`` measures it); the
carrier exp(j k_c d) factorises into a Tx and an Rx phasor, computed in float64 once per
element and voxel.

The voxel loop is a compiled kernel (numba, parallel over voxels): a fused loop reads each
pair's profile from cache, where the same arithmetic as tensor operations would stream
(T, R, voxels) temporaries through memory and be no faster than the exact GEMMs.
Works for any frequency set (uniform or not); the column norms are the exact ones.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import torch

from ..progress import progress_bar
from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["DEFAULT_OVERSAMPLING", "fast_adjoint", "range_profiles"]

DEFAULT_OVERSAMPLING = 16  # profile samples per c / B of path: image error ~1e-3 (benchmarks/fast_imaging.py)


def range_profiles(data: np.ndarray, frequencies_hz: np.ndarray, path_min_m: float, path_max_m: float,
                   oversampling: int) -> tuple[np.ndarray, float]:
    """Profiles s(P) of every pair on P = path_min + n h: ((T, R, N) complex64, h [m]).

    data : (T, R, K) complex samples of one view. h = c / (oversampling B), with B the span
    K * mean step of the frequencies (their bandwidth); one sample of margin either side.
    """
    f = np.asarray(frequencies_hz, float)
    k = 2 * math.pi * f / SPEED_OF_LIGHT
    bandwidth = (f.max() - f.min()) * len(f) / max(len(f) - 1, 1)
    step = SPEED_OF_LIGHT / (oversampling * bandwidth)
    count = int(math.ceil((path_max_m - path_min_m) / step)) + 3
    paths = path_min_m - step + step * np.arange(count)
    basis = np.exp(1j * np.outer(k - k.mean(), paths))  # (K, N)
    return (data.reshape(-1, len(f)) @ basis).reshape(*data.shape[:2], count).astype(np.complex64), step


@numba.njit(cache=True)
def _element_terms(positions, boresight, points, exponent, spreading, k_c, distances, phasors):
    """Fill distances (E, B) float32 [m] and phasors (E, B, 2) float32 (real, imaginary) of
    amplitude * exp(+j k_c d), for every element and a block of points (B, 3); float64 inside."""
    for e in range(positions.shape[0]):
        for b in range(points.shape[0]):
            dx = points[b, 0] - positions[e, 0]
            dy = points[b, 1] - positions[e, 1]
            dz = points[b, 2] - positions[e, 2]
            d = math.sqrt(dx * dx + dy * dy + dz * dz)
            amplitude = 1.0 / d if spreading else 1.0
            if exponent > 0:
                cos = (dx * boresight[0] + dy * boresight[1] + dz * boresight[2]) / d
                amplitude *= max(cos, 0.0) ** exponent
            distances[e, b] = d
            phasors[e, b, 0] = amplitude * math.cos(k_c * d)
            phasors[e, b, 1] = amplitude * math.sin(k_c * d)


_BLOCK = 128  # voxels per block: a block's element terms and partial sums stay in L1/L2


@numba.njit(parallel=True, cache=True, fastmath=True)
def _back_project(profiles, path_min, step, tx, rx, boresight, exponent, spreading, k_c, points, out):
    """out[q] = sum_ij a_i b_j exp(j k_c P) s_ij(P), P = d_i + d_j, s read by linear interpolation.

    profiles : (T, R, N, 2) float32, real and imaginary parts. Blocks of voxels run in
    parallel; within a block the pair loop is outside the voxel loop, so one pair's profile
    is read by every voxel of the block while in cache. Complex arithmetic is written out
    in float32 parts (numba's complex product checks for infinities).
    """
    n_tx, n_rx, n_samples = profiles.shape[:3]
    n_blocks = (points.shape[0] + _BLOCK - 1) // _BLOCK
    scale = np.float32(1.0 / step)
    origin = np.float32(path_min)
    for block in numba.prange(n_blocks):
        lo = block * _BLOCK
        size = min(lo + _BLOCK, points.shape[0]) - lo
        d_tx = np.empty((n_tx, size), np.float32)
        d_rx = np.empty((n_rx, size), np.float32)
        p_tx = np.empty((n_tx, size, 2), np.float32)
        p_rx = np.empty((n_rx, size, 2), np.float32)
        _element_terms(tx, boresight, points[lo:lo + size], exponent, spreading, k_c, d_tx, p_tx)
        _element_terms(rx, boresight, points[lo:lo + size], exponent, spreading, k_c, d_rx, p_rx)
        total = np.zeros((size, 2), np.float64)
        partial = np.empty((size, 2), np.float32)
        for i in range(n_tx):
            partial[:] = 0
            for j in range(n_rx):
                row = profiles[i, j]
                for b in range(size):
                    x = (d_tx[i, b] + d_rx[j, b] - origin) * scale
                    n = min(max(int(x), 0), n_samples - 2)
                    frac = x - np.float32(n)
                    s_re = row[n, 0] + frac * (row[n + 1, 0] - row[n, 0])
                    s_im = row[n, 1] + frac * (row[n + 1, 1] - row[n, 1])
                    partial[b, 0] += p_rx[j, b, 0] * s_re - p_rx[j, b, 1] * s_im
                    partial[b, 1] += p_rx[j, b, 0] * s_im + p_rx[j, b, 1] * s_re
            for b in range(size):
                total[b, 0] += p_tx[i, b, 0] * partial[b, 0] - p_tx[i, b, 1] * partial[b, 1]
                total[b, 1] += p_tx[i, b, 0] * partial[b, 1] + p_tx[i, b, 1] * partial[b, 0]
        for b in range(size):
            out[lo + b] = complex(total[b, 0], total[b, 1])


def fast_adjoint(acquisition: Acquisition, data: torch.Tensor, points: torch.Tensor, *,
                 oversampling: int = DEFAULT_OVERSAMPLING, summed: bool = False, progress: bool = False) -> torch.Tensor:
    """A^H y per frame at ``points`` (Q, 3) [m] by range-profile back-projection: (V, Q)
    complex64, or with ``summed`` their sum over the frames (1, Q) (a scan's coherent image).

    data : (V, T, R, K) complex. Agrees with ``SensingOperator.adjoint(..., per_view=True)``
    to the interpolation error (relative ~ 1 / oversampling^2).
    """
    if oversampling < 2:
        raise ValueError(f"oversampling must be >= 2, got {oversampling}")
    pts = points.detach().cpu().double().numpy()
    freqs = acquisition.frequencies_hz.numpy()
    k_c = float(2 * math.pi * freqs.mean() / SPEED_OF_LIGHT)
    out = np.zeros((1 if summed else acquisition.shape[0], len(pts)), np.complex128)
    frame = np.zeros(len(pts), np.complex128)
    lower, upper = pts.min(0), pts.max(0)
    for v in progress_bar(range(acquisition.shape[0]), desc="fast A^H y", enabled=progress):
        tx, rx = acquisition.tx_m[v].numpy(), acquisition.rx_m[v].numpy()
        path_min = _nearest(tx, lower, upper).min() + _nearest(rx, lower, upper).min()
        path_max = _farthest(tx, lower, upper).max() + _farthest(rx, lower, upper).max()
        profiles, step = range_profiles(data[v].detach().cpu().numpy(), freqs, path_min, path_max, oversampling)
        parts = np.ascontiguousarray(np.stack([profiles.real, profiles.imag], axis=-1))
        target = frame if summed else out[v]
        _back_project(parts, path_min - step, step, tx, rx, acquisition.boresight[v].numpy(),
                      float(acquisition.pattern_exponent), bool(acquisition.spreading), k_c, pts, target)
        if summed:
            out[0] += frame
    return torch.from_numpy(out.astype(np.complex64))


def _nearest(elements: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(E,) distance [m] from each element to the nearest point of the box [lower, upper]."""
    return np.linalg.norm(elements - np.clip(elements, lower, upper), axis=1)


def _farthest(elements: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(E,) distance [m] from each element to the farthest corner of the box."""
    return np.linalg.norm(np.maximum(np.abs(elements - lower), np.abs(elements - upper)), axis=1)
