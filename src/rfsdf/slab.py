"""Dielectric slabs: reflection and transmission of a layer of finite thickness (ITU-R P.2040).

A plane wave meets a slab of relative permittivity eps and thickness d at incidence angle
theta in air. With the single interface's Fresnel coefficient R' (:func:`~rfsdf.materials.fresnel`,
TE or TM) and q = (2 pi d / lambda) sqrt(eps - sin^2 theta), the slab's internal multiple
reflections sum to (P.2040-3, eqs. 43-44)

    R = R' (1 - e^{-j2q}) / (1 - R'^2 e^{-j2q}),
    T = (1 - R'^2) e^{-j(q - q0)} / (1 - R'^2 e^{-j2q}),   q0 = (2 pi d / lambda) cos theta.

T is the field behind the slab over the field there without it: a ray traced straight
through the slab keeps its free-space phase and takes T on top (Sionna RT's
``itu_coefficients_single_layer_slab`` leaves out the e^{+j q0}, the free-space phase of
the slab's own thickness). Its phase is the slab's excess electrical path,
d (sqrt(eps' - sin^2 theta) - cos theta) for a weak loss (:func:`excess_path`), which a
radar reads as the target behind standing that much farther. A PEC reflects as the half
space and transmits nothing. Time convention exp(+j omega t), as in :mod:`rfsdf.materials`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import torch

from .materials import POLARIZATIONS, fresnel_of_cosine

__all__ = ["slab_coefficients", "slab_over_band", "band_delay", "excess_path"]

_SPEED_OF_LIGHT = 299_792_458.0  # [m/s]


def slab_coefficients(cos_inc, eps, thickness_m, frequency_hz: float,
                      polarization: str = "TE") -> tuple[torch.Tensor, torch.Tensor]:
    """(R, T) complex128 of a slab (see the module docstring), broadcast over the inputs.

    cos_inc : cos(theta_inc) in [0, 1], float or tensor. eps : complex relative permittivity
    eps' - j eps'' (inf: PEC). thickness_m : d [m] >= 0. polarization : "TE", "TM" or "mean"
    (the unpolarised amplitude sqrt((|TE|^2 + |TM|^2) / 2) with the TE phase, as
    :func:`~rfsdf.materials.fresnel`).

    Examples
    --------
    A lossless half-wave slab (d = lambda / (2 sqrt(eps))) is transparent at normal incidence:

    >>> wavelength = _SPEED_OF_LIGHT / 79e9
    >>> r, t = slab_coefficients(1.0, 4.0, wavelength / 4, 79e9)
    >>> round(float(r.abs()), 12), round(float(t.abs()), 12)
    (0.0, 1.0)
    """
    eps = torch.as_tensor(eps, dtype=torch.complex128)
    return next(slab_over_band(cos_inc, lambda _: eps, thickness_m, frequency_hz, [frequency_hz], polarization))


def slab_over_band(cos_inc, permittivity: Callable[[float], torch.Tensor], thickness_m, centre_hz: float,
                   frequencies_hz, polarization: str = "TE") -> Iterator[tuple[torch.Tensor, torch.Tensor]]:
    """(R, T) of :func:`slab_coefficients` at each of ``frequencies_hz`` [Hz] in turn, the
    slab's eps at a frequency given by ``permittivity(f)`` (broadcast with ``cos_inc``):
    its phase q with each frequency's eps, the single interface's R' with the centre
    frequency's (which moves it by about 0.1 % across 77-81 GHz), so a frequency costs the
    phases' two exponentials and one square root, not a Fresnel coefficient per polarization."""
    if polarization not in POLARIZATIONS:
        raise ValueError(f"polarization must be one of {POLARIZATIONS}, got {polarization!r}")
    cos_t = torch.as_tensor(cos_inc, dtype=torch.float64)
    d = torch.as_tensor(thickness_m, dtype=torch.float64, device=cos_t.device)
    if not bool((d >= 0).all()):
        raise ValueError("slab thickness must be >= 0 m")
    eps_c = torch.as_tensor(permittivity(centre_hz), dtype=torch.complex128).to(cos_t.device)
    pec = torch.isinf(eps_c.real)
    singles = [fresnel_of_cosine(cos_t, eps_c, p) for p in (("TE", "TM") if polarization == "mean" else (polarization,))]
    sin_sq = (1 - cos_t**2).to(torch.complex128)
    for frequency_hz in frequencies_hz:
        k0 = 2 * math.pi * float(frequency_hz) / _SPEED_OF_LIGHT
        eps = torch.as_tensor(permittivity(float(frequency_hz)), dtype=torch.complex128).to(cos_t.device)
        eps_safe = torch.where(pec, torch.ones_like(eps), eps)
        q = k0 * d * torch.sqrt(eps_safe - sin_sq)  # principal root: Im q <= 0, decaying
        round_trip, through = torch.exp(-2j * q), torch.exp(-1j * (q - k0 * d * cos_t))
        pairs = []
        for single in singles:
            denominator = 1 - single**2 * round_trip
            r, t = single * (1 - round_trip) / denominator, (1 - single**2) * through / denominator
            pairs.append((torch.where(pec, single, r), torch.where(pec, torch.zeros_like(t), t)))
        if polarization == "mean":  # the unpolarised amplitude with the TE phase
            (r_te, t_te), (r_tm, t_tm) = pairs
            yield tuple(torch.sqrt((te.abs() ** 2 + tm.abs() ** 2) / 2) * torch.sgn(te)
                        for te, tm in ((r_te, r_tm), (t_te, t_tm)))
        else:
            yield pairs[0]


def band_delay(cos_inc, permittivity: Callable[[float], torch.Tensor], thickness_m, centre_hz: float,
               frequencies_hz, window) -> torch.Tensor:
    """The slab's one-way delay [m] (float64, broadcast of ``cos_inc`` and ``thickness_m``) as
    a band sees it: -d arg T / dk, the slope of T's unwrapped phase over the wavenumber k by
    least squares over ``frequencies_hz`` (F,) [Hz], each weighted by ``window`` (F,) times
    |T|^4 (the round trip's power). A range profile through the slab peaks this far behind
    (within 0.25 mm over 5 mm to 4 cm of glass, plasterboard and wood at 28, 60 and 79 GHz),
    where its internal reflections move the excess path's estimate by up to 3 mm (2 cm of
    glass over 26.5-29.5 GHz: 27.2 mm for 30.2). The frequencies must sample T's phase at
    less than pi a step (unwrapped by its increments)."""
    transmissions = torch.stack([t for _, t in slab_over_band(cos_inc, permittivity, thickness_m, centre_hz,
                                                               frequencies_hz, "mean")])  # (F, ...)
    steps = torch.angle(transmissions[1:] / transmissions[:-1])
    phase = torch.cat([torch.zeros_like(steps[:1]), steps.cumsum(0)])
    shape = (-1,) + (1,) * (phase.dim() - 1)
    k = (2 * math.pi / _SPEED_OF_LIGHT * torch.as_tensor(frequencies_hz, dtype=torch.float64)).reshape(shape)
    weight = torch.as_tensor(window, dtype=torch.float64).reshape(shape) * transmissions.abs() ** 4
    total = weight.sum(0).clamp(min=torch.finfo(torch.float64).tiny)
    k_mean, phase_mean = (weight * k).sum(0) / total, (weight * phase).sum(0) / total
    slope = (weight * (k - k_mean) * (phase - phase_mean)).sum(0) / (weight * (k - k_mean) ** 2).sum(0)
    return -slope


def excess_path(cos_inc, eps_real, thickness_m) -> torch.Tensor:
    """The slab's one-way excess electrical path d (sqrt(eps' - sin^2 theta) - cos theta) [m]
    (float64): how much farther a ray's target stands for crossing it (the group delay of a
    weakly lossy, non-dispersive slab, its internal reflections aside)."""
    cos_t = torch.as_tensor(cos_inc, dtype=torch.float64)
    return torch.as_tensor(thickness_m, dtype=torch.float64) * (torch.sqrt(eps_real - 1 + cos_t**2) - cos_t)
