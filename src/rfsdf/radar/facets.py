"""Flat triangular facets whose phase is integrated across them: surfaces too large for points.

A sample that stands for a triangle T (centroid p, corners v_i relative to p, area A), seen
from the phase centres s and r of a view at wavenumber k, scatters c (``scattering.py``,
at p) times

    F = (1 / A) integral over T of exp(-j k (P(x) - P(p))) dA,

P(x) = |x - s| + |x - r| the path, taken linear across the triangle between its exact
values at the corners, a_i = k (P(p + v_i) - P(p)). By the Hermite-Genocchi formula F is
-2 times the second divided difference of exp(-j t) at the three a_i, in closed form.
The triangles of a mesh then integrate one continuous, piecewise linear phase exactly:
on a wall, where the phase turns many times across each triangle, their sum cancels as
the wall's integral does, where points at the same spacing alias into speckle; near the
specular point F -> 1 and a facet is a point. (Linearising P about each centroid instead,
a_i = -k (u_s + u_r) . v_i, leaves neighbours disagreeing on their shared edge by the
wavefront's curvature: a 4 m wall 1 m away was 7 % off the image source with 24 mm
triangles.) F is evaluated per frequency (the phase across a 3 cm facet at 60 GHz turns by
up to 50 rad, so 6 % of bandwidth matters) at the view's phase centres: across a module a
few centimetres wide at 1 m, the phase slope moves by k x aperture / range, 0.25 rad over
a 1 cm facet.
"""

from __future__ import annotations

import math
from typing import Callable

import numba
import numpy as np
import torch

from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["triangle_phase_integral", "facet_phase_integrals", "corner_paths", "facet_phase_weights", "facet_weight"]

# spreads of the corners' phases [rad] below which F is taken from its Taylor expansion: its
# next term is ~ spread^3 / 100; the divided difference's rounding ~ eps / spread
_CLOSE = {torch.float32: 1e-2, torch.float64: 1e-4}


def _first_difference(a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(exp(-j b) - exp(-j a)) / (b - a) as (real, imaginary), stable for b -> a:
    -j exp(-j m) sinc(h) with m = (a + b) / 2, h = (b - a) / 2."""
    m, h = 0.5 * (a + b), 0.5 * (b - a)
    sinc = torch.sinc(h / torch.pi)
    return -torch.sin(m) * sinc, -torch.cos(m) * sinc


def triangle_phase_integral(alpha: torch.Tensor) -> torch.Tensor:
    """F (...,) complex: the mean of exp(-j a(x)) over a triangle, a linear across it with
    the values alpha (..., 3) [rad] at the corners; 1 at alpha = 0. Real arithmetic in
    alpha's dtype; complex64 for float32, complex128 for float64. The closed form written
    out in torch, for any shape: the reference the compiled :func:`facet_phase_integrals`,
    which the simulator runs, is tested against."""
    shape, alpha = alpha.shape[:-1], alpha.reshape(-1, 3)
    low, high = alpha.min(-1).values, alpha.max(-1).values
    middle = alpha.sum(-1) - low - high
    spread = high - low
    close = spread <= _CLOSE[alpha.dtype]
    right, left = _first_difference(middle, high), _first_difference(low, middle)
    scale = -2 / torch.where(close, torch.ones_like(spread), spread)  # finite gradients where unused
    # about the mean where the spread is small: exp(-j mean) (1 - E[d^2] / 2), E[d^2] = sum (a_i - mean)^2 / 12
    mean = alpha.mean(-1)
    taper = 1 - ((alpha - mean[:, None]) ** 2).sum(-1) / 24
    real = torch.where(close, torch.cos(mean) * taper, scale * (right[0] - left[0]))
    imaginary = torch.where(close, -torch.sin(mean) * taper, scale * (right[1] - left[1]))
    return torch.complex(real, imaginary).reshape(shape)


@numba.njit(cache=True)
def _rotor(x, k0, dk):
    """cos, sin of k0 x and of dk x: a phasor at the first wavenumber and its step."""
    return math.cos(k0 * x), math.sin(k0 * x), math.cos(dk * x), math.sin(dk * x)


@numba.njit(parallel=True, cache=True)
def _phase_integrals(extra, k0, dk, count, close, out):
    """out[n, q] = F of triangle q at wavenumber k0 + n dk (as triangle_phase_integral with
    alpha = k extra[q]), facets in parallel; out (K, Q) complex64. The sines and cosines of
    k x come from phasors turned by dk x per wavenumber (six products instead of a sine)."""
    for q in numba.prange(extra.shape[0]):
        x, y, z = extra[q, 0], extra[q, 1], extra[q, 2]
        low, high = min(x, min(y, z)), max(x, max(y, z))
        middle = x + y + z - low - high
        mean = (x + y + z) / 3.0
        moment = ((x - mean) ** 2 + (y - mean) ** 2 + (z - mean) ** 2) / 24.0
        # phasors of k m1, k h1, k m2, k h2 and k mean: (cos, sin) now and per step
        c1, s1, dc1, ds1 = _rotor(0.5 * (middle + high), k0, dk)
        ch1, sh1, dch1, dsh1 = _rotor(0.5 * (high - middle), k0, dk)
        c2, s2, dc2, ds2 = _rotor(0.5 * (low + middle), k0, dk)
        ch2, sh2, dch2, dsh2 = _rotor(0.5 * (middle - low), k0, dk)
        cm, sm, dcm, dsm = _rotor(mean, k0, dk)
        for n in range(count):
            w = k0 + n * dk
            spread = w * (high - low)
            if spread <= close:
                taper = 1.0 - w * w * moment
                out[n, q] = complex(cm * taper, -sm * taper)
            else:
                h1, h2 = 0.5 * w * (high - middle), 0.5 * w * (middle - low)
                sinc1 = sh1 / h1 if h1 > 1e-9 else 1.0
                sinc2 = sh2 / h2 if h2 > 1e-9 else 1.0
                scale = -2.0 / spread
                out[n, q] = complex(scale * (s2 * sinc2 - s1 * sinc1), scale * (c2 * sinc2 - c1 * sinc1))
            c1, s1 = c1 * dc1 - s1 * ds1, s1 * dc1 + c1 * ds1
            ch1, sh1 = ch1 * dch1 - sh1 * dsh1, sh1 * dch1 + ch1 * dsh1
            c2, s2 = c2 * dc2 - s2 * ds2, s2 * dc2 + c2 * ds2
            ch2, sh2 = ch2 * dch2 - sh2 * dsh2, sh2 * dch2 + ch2 * dsh2
            cm, sm = cm * dcm - sm * dsm, sm * dcm + cm * dsm


def facet_phase_integrals(extra_path_m: torch.Tensor, wavenumbers_rad_m: torch.Tensor) -> torch.Tensor:
    """(K, Q) complex64: F of triangles whose corners' paths exceed their centroid's by
    ``extra_path_m`` (Q, 3) [m], at uniformly spaced wavenumbers (K,) [rad/m] (the torch
    form for others); compiled (numba, parallel over facets, float64 inside)."""
    k = wavenumbers_rad_m.detach().cpu().double()
    steps = torch.diff(k)
    if len(k) > 1 and bool((steps - steps.mean()).abs().max() > 1e-9 * k.abs().max()):
        alpha = k.to(extra_path_m.device)[:, None, None] * extra_path_m.double()[None]
        return triangle_phase_integral(alpha).to(torch.complex64)
    extra = np.ascontiguousarray(extra_path_m.detach().cpu().double().numpy())
    out = np.empty((len(k), len(extra)), np.complex64)
    _phase_integrals(extra, float(k[0]), float(steps.mean()) if len(k) > 1 else 0.0, len(k),
                     _CLOSE[torch.float64], out)
    return torch.from_numpy(out).to(extra_path_m.device)


def corner_paths(centroids_m: torch.Tensor, corners_m: torch.Tensor, tx_m: torch.Tensor,
                 rx_m: torch.Tensor) -> torch.Tensor:
    """(Q, 3) [m] float64: how much longer the path Tx -> corner -> Rx is than the path through
    the centroid, for triangles with centroids (Q, 3) [m] and corners (Q, 3, 3) [m] relative
    to them, seen from phase centres ``tx_m`` and ``rx_m`` (3,) [m]; differentiable."""
    p, corners = centroids_m.double(), corners_m.double()
    s, r = tx_m.to(p), rx_m.to(p)

    def path(x):  # (..., 3) -> (...) [m]
        return (s - x).norm(dim=-1) + (r - x).norm(dim=-1)

    return path(p[:, None, :] + corners) - path(p)[:, None]


def facet_phase_weights(centroids_m: torch.Tensor, corners_m: torch.Tensor, tx_m: torch.Tensor, rx_m: torch.Tensor,
                        wavenumbers_rad_m: torch.Tensor) -> torch.Tensor:
    """(K, Q) complex: F of each triangle at each wavenumber (K,) [rad/m] seen from one
    view's phase centres (:func:`corner_paths`), differentiable in the centroids and corners
    (the renderer's; the simulator runs the compiled :func:`facet_phase_integrals`). In the
    centroids' dtype: complex64 for float32."""
    extra = corner_paths(centroids_m, corners_m, tx_m, rx_m)  # (Q, 3)
    alpha = wavenumbers_rad_m.to(extra)[:, None, None] * extra[None]  # (K, Q, 3)
    return triangle_phase_integral(alpha.to(centroids_m.dtype))


def facet_weight(acquisition: Acquisition, centroids_m: torch.Tensor,
                 corners_m: torch.Tensor) -> Callable[[slice, slice], torch.Tensor]:
    """The ``weight`` of :meth:`~rfsdf.radar.operator.SensingOperator.forward_weighted` for
    triangles with centroids (Q, 3) [m] and corners (Q, 3, 3) [m] relative to them: F of
    each (view, frequency, facet), (v, K, q) complex, at each view's Tx and Rx phase centres."""
    k = 2 * torch.pi * acquisition.frequencies_hz.double() / SPEED_OF_LIGHT  # (K,)
    tx, rx = acquisition.tx_m.mean(1).double(), acquisition.rx_m.mean(1).double()  # (V, 3)

    def weight(views: slice, pts: slice) -> torch.Tensor:
        p, corners = centroids_m[pts], corners_m[pts]
        return torch.stack([facet_phase_integrals(corner_paths(p, corners, s, r), k)  # (K, q) each
                            for s, r in zip(tx[views], rx[views])])

    return weight
