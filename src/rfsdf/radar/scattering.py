"""How one surface sample scatters in one view: Fresnel x lobe x area, facing and shadowing.

The one physics behind both the simulator (exact scene surface samples, Fresnel of their
material) and the reconstruction's coherent renderer (samples of the neural surface, a
learned reflectivity). A sample at p with outward normal n and area dA, lit from the Tx
phase centre s and seen from the Rx phase centre r, scatters with

    c = (j k / 2 pi) * Gamma(cos theta_inc) * L * dA * lit,
    L = (1 - w_d) max(0, m . o)^n_s + w_d max(0, cos theta_inc),

theta_inc the angle between n and the direction to s, m the mirror image of the incident
direction, o the unit vector to r, w_d the diffuse weight and n_s the specular exponent.
j k / 2 pi is physical optics' factor, evaluated at the centre frequency here and scaled to
each frequency k_f by ``po_spectrum`` on the data (a per-frequency constant, so it factors
out of the sum over samples): with it a sample's c is
sqrt(sigma / 4 pi) of its radar cross-section sigma (a flat plate of area A at normal
incidence, sigma = 4 pi A^2 / lambda^2: c = A / lambda), so the sensing operator's
1 / (d_tx d_rx) puts the data in the units of the field, and a large flat wall d away
returns Gamma / (2 d) from range d, the image source's value (tests/test_rooms.py).
A sample that stands for a flat triangle (``radar/facets.py``) takes the integral of the
phase across it in the sensing operator, per frequency; c is the same.
``lit`` is 0 for samples facing away from s or r and for samples whose ray to the array's
phase centre meets the scene first (sphere tracing against an occluder SDF).
"""

from __future__ import annotations

from typing import Callable

import torch

from ..geometry import sphere_trace

__all__ = ["scatter", "lit_mask", "unblocked", "po_spectrum", "SPECULAR_EXPONENT", "DIFFUSE_WEIGHT"]

SPECULAR_EXPONENT = 8.0  # n_s of the lobe
DIFFUSE_WEIGHT = 0.5  # w_d of the lobe
_TRACE_EPS_M = 1e-5  # hit tolerance of shadow rays [m]
_SHADOW_OFFSET_M = 4 * _TRACE_EPS_M  # shadow rays start this far off the surface along n [m]

Reflection = Callable[[torch.Tensor], torch.Tensor]


def _directions(points, tx_centre_m, rx_centre_m):
    """Vectors sample -> Tx (Q, 3) and sample -> Rx (Q, 3) [m]."""
    return tx_centre_m.to(points) - points, rx_centre_m.to(points) - points


def lit_mask(points: torch.Tensor, normals: torch.Tensor, tx_centre_m: torch.Tensor, rx_centre_m: torch.Tensor, *,
             occluder: Callable[[torch.Tensor], torch.Tensor] | None = None,
             shadow_offset_m: float = _SHADOW_OFFSET_M) -> torch.Tensor:
    """(Q,) bool: the sample faces both phase centres and, with an ``occluder`` SDF, its ray
    to their midpoint is not blocked (:func:`unblocked`)."""
    with torch.no_grad():
        to_tx, to_rx = _directions(points, tx_centre_m, rx_centre_m)
        lit = ((to_tx * normals).sum(1) > 0) & ((to_rx * normals).sum(1) > 0)
        if occluder is None or not lit.any():
            return lit
        idx = lit.nonzero().squeeze(1)
        lit[idx] = unblocked(points[idx], normals[idx], 0.5 * (tx_centre_m + rx_centre_m), occluder,
                             shadow_offset_m=shadow_offset_m)
        return lit


def unblocked(points: torch.Tensor, normals: torch.Tensor, centre_m: torch.Tensor,
              occluder: Callable[[torch.Tensor], torch.Tensor], *, shadow_offset_m: float = _SHADOW_OFFSET_M) -> torch.Tensor:
    """(Q,) bool: the ray from each sample (started ``shadow_offset_m`` off the surface along
    its normal) to ``centre_m`` (3,) [m] meets no surface of the ``occluder`` SDF first."""
    with torch.no_grad():
        origins = points + shadow_offset_m * normals
        direction = centre_m.to(points) - origins
        distance = direction.norm(dim=1)
        trace = sphere_trace(occluder, origins, direction, eps=_TRACE_EPS_M, max_steps=256, t_max=distance)
        return ~(trace.hit & (trace.t < distance))


def po_spectrum(frequencies_hz: torch.Tensor) -> torch.Tensor:
    """(K,) physical optics' j k / 2 pi at each frequency over its value at the centre
    frequency (their mean, ``Acquisition.center_frequency_hz``), where :func:`scatter`
    takes it: the data y (..., K) of ``scatter``'s c are multiplied by it."""
    f = frequencies_hz.double()
    return f / f.mean()


def scatter(points: torch.Tensor, normals: torch.Tensor, area_m2: torch.Tensor, reflection: Reflection,
            tx_centre_m: torch.Tensor, rx_centre_m: torch.Tensor, wavenumber_rad_m: float, *,
            specular_exponent: float = SPECULAR_EXPONENT, diffuse_weight: float = DIFFUSE_WEIGHT,
            occluder: Callable[[torch.Tensor], torch.Tensor] | None = None) -> torch.Tensor:
    """Complex reflectivity c (Q,) of surface samples in one view (see the module docstring).

    points, normals : (Q, 3) [m] and outward unit normals, scene frame. area_m2 : (Q,) [m^2].
    reflection : cos(theta_inc) (Q,) -> Gamma (Q,), e.g. the Fresnel coefficient of each
    sample's material, or a learned non-negative amplitude. tx_centre_m, rx_centre_m : (3,)
    [m]. wavenumber_rad_m : k = 2 pi f / c at the centre frequency. occluder : scene SDF
    for shadows (None: facing only). Differentiable in points, normals, area and whatever
    ``reflection`` returns; dtype follows ``points``.
    """
    to_tx, to_rx = _directions(points, tx_centre_m, rx_centre_m)
    dist_tx = to_tx.norm(dim=1)
    cos_inc = (to_tx * normals).sum(1) / dist_tx
    incident = -to_tx / dist_tx[:, None]
    mirror = incident - 2 * (incident * normals).sum(1, keepdim=True) * normals
    cos_spec = (mirror * torch.nn.functional.normalize(to_rx, dim=1)).sum(1)
    lobe = (1 - diffuse_weight) * cos_spec.clamp(min=0) ** specular_exponent + diffuse_weight * cos_inc.clamp(min=0)
    lit = lit_mask(points, normals, tx_centre_m, rx_centre_m, occluder=occluder)
    return 1j * reflection(cos_inc.clamp(0, 1)) * (lobe * area_m2 * lit * (wavenumber_rad_m / (2 * torch.pi)))
