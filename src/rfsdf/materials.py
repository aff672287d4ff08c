"""Electromagnetic materials: ITU-R P.2040 permittivities, Fresnel reflection, permittivity estimation.

Time convention exp(+j omega t) (the radar model's propagation phase is exp(-j k d)), so a
lossy medium has eps = eps' - j eps''. With conductivity sigma [S/m] and f [Hz],
eps'' = sigma / (2 pi f eps0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from scipy import optimize

__all__ = [
    "Material", "MATERIALS", "get_material", "class_permittivities", "fresnel", "fresnel_of_cosine", "mixture_fresnel", "reflectance", "brewster_angle",
    "PermittivityEstimate", "estimate_permittivity", "EPS0",
]

EPS0 = 8.8541878128e-12  # vacuum permittivity [F/m]
POLARIZATIONS = ("TE", "TM", "mean")


@dataclass(frozen=True)
class Material:
    """A material as ITU-R P.2040 models it: eps' = a f^b, sigma = c f^d, f in GHz.

    ``pec`` marks a perfect electric conductor (|Gamma| = 1 at every angle).
    ``valid_ghz`` is the frequency range the recommendation gives the fit for.
    """

    name: str
    a: float = 1.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0
    pec: bool = False
    valid_ghz: tuple[float, float] = (1.0, 100.0)

    def permittivity(self, frequency_hz: float) -> complex:
        """Complex relative permittivity eps' - j eps'' at ``frequency_hz`` [Hz] (inf for PEC)."""
        if self.pec:
            return complex(math.inf, 0.0)
        f_ghz = frequency_hz / 1e9
        lo, hi = self.valid_ghz
        if not lo <= f_ghz <= hi:
            raise ValueError(f"material {self.name!r}: {f_ghz:.3g} GHz is outside its ITU-R P.2040 range {lo}-{hi} GHz")
        eps_real = self.a * f_ghz**self.b
        sigma = self.c * f_ghz**self.d  # [S/m]
        return complex(eps_real, -sigma / (2 * math.pi * frequency_hz * EPS0))

    @classmethod
    def from_permittivity(cls, name: str, eps_real: float, conductivity_s_per_m: float = 0.0) -> Material:
        """A user material with constant eps' and conductivity [S/m] at every frequency."""
        if not eps_real >= 1.0:
            raise ValueError(f"material {name!r}: relative permittivity must be >= 1, got {eps_real}")
        if not conductivity_s_per_m >= 0.0:
            raise ValueError(f"material {name!r}: conductivity must be >= 0 S/m, got {conductivity_s_per_m}")
        return cls(name, a=float(eps_real), c=float(conductivity_s_per_m), valid_ghz=(0.0, math.inf))


# ITU-R P.2040-1 (07/2015), Table 3.
MATERIALS: dict[str, Material] = {
    m.name: m
    for m in [
        Material("concrete", 5.24, 0.0, 0.0462, 0.7822),
        Material("brick", 3.91, 0.0, 0.0238, 0.16, valid_ghz=(1.0, 40.0)),
        Material("plasterboard", 2.73, 0.0, 0.0085, 0.9395),
        Material("wood", 1.99, 0.0, 0.0047, 1.0718, valid_ghz=(0.001, 100.0)),
        Material("glass", 6.31, 0.0, 0.0036, 1.3394, valid_ghz=(0.1, 100.0)),
        Material("metal", pec=True, valid_ghz=(0.0, math.inf)),
    ]
}
_ALIASES = {"drywall": "plasterboard", "pec": "metal"}


def get_material(name: str) -> Material:
    """The catalogue material called ``name`` (aliases: drywall, pec); clear error otherwise."""
    key = _ALIASES.get(name.lower(), name.lower())
    if key not in MATERIALS:
        known = ", ".join(sorted([*MATERIALS, *_ALIASES]))
        raise ValueError(f"unknown material {name!r}; known: {known}")
    return MATERIALS[key]


def _as_eps(eps) -> torch.Tensor:
    return torch.as_tensor(eps, dtype=torch.complex128)


def fresnel(theta_rad, eps, polarization: str = "TE") -> torch.Tensor:
    """Complex Fresnel reflection coefficient, air to relative permittivity ``eps``.

    Parameters
    ----------
    theta_rad : float or (N,) tensor, incidence angle from the normal [rad], in [0, pi/2].
    eps : complex or (N,) tensor, relative permittivity (eps' - j eps''); ``inf`` is a PEC.
    polarization : "TE" (s), "TM" (p) or "mean".

    Returns complex128 tensor of the broadcast shape. Conventions: TE = E-field ratio;
    TM as in the design, (eps cos t - sqrt(eps - sin^2 t)) / (eps cos t + sqrt(...)), so
    Gamma_TM(0) = -Gamma_TE(0). Averaging the complex coefficients would therefore cancel
    at normal incidence; "mean" is the unpolarised amplitude sqrt((|TE|^2 + |TM|^2) / 2)
    with the TE phase. A PEC gives TE = -1, TM = +1.
    """
    return fresnel_of_cosine(torch.cos(torch.as_tensor(theta_rad, dtype=torch.float64)), eps, polarization)


def fresnel_of_cosine(cos_inc, eps, polarization: str = "TE") -> torch.Tensor:
    """:func:`fresnel` of cos(theta_inc) (float or tensor in [0, 1]) instead of the angle:
    differentiable in the cosine everywhere, normal incidence included (where arccos is not),
    so a renderer can take gradients through the incidence geometry. complex128."""
    if polarization not in POLARIZATIONS:
        raise ValueError(f"polarization must be one of {POLARIZATIONS}, got {polarization!r}")
    cos_t = torch.as_tensor(cos_inc).to(torch.float64)
    eps = _as_eps(eps).to(cos_t.device)
    if polarization == "mean":
        te, tm = fresnel_of_cosine(cos_t, eps, "TE"), fresnel_of_cosine(cos_t, eps, "TM")
        amplitude = torch.sqrt((te.abs() ** 2 + tm.abs() ** 2) / 2)
        return amplitude * torch.sgn(te)
    cos_c = cos_t.to(torch.complex128)
    pec = torch.isinf(eps.real)
    eps_safe = torch.where(pec, torch.ones_like(eps), eps)
    root = torch.sqrt(eps_safe - 1 + cos_c**2)  # sqrt(eps - sin^2 t), principal branch: Im <= 0, decaying
    if polarization == "TE":
        gamma = (cos_c - root) / (cos_c + root)
        pec_value = -1.0
    else:
        gamma = (eps_safe * cos_c - root) / (eps_safe * cos_c + root)
        pec_value = 1.0
    return torch.where(pec, torch.full_like(gamma, pec_value), gamma)


def class_permittivities(names, frequency_hz: float) -> torch.Tensor:
    """(K,) complex128 relative permittivities of the catalogue materials ``names`` at
    ``frequency_hz`` (inf for metal): the classes a material head mixes."""
    return torch.tensor([complex(get_material(name).permittivity(frequency_hz)) for name in names],
                        dtype=torch.complex128)


def mixture_fresnel(cos_inc: torch.Tensor, probabilities: torch.Tensor, eps: torch.Tensor,
                    polarization: str = "mean") -> torch.Tensor:
    """The expected Fresnel coefficient of points whose material is class k with probability
    p_k: sum_k p_k Gamma_k(theta_inc) (Q,) complex128.

    cos_inc : (Q,) cos(theta_inc) in [0, 1]. probabilities : (Q, K). eps : (K,) complex
    relative permittivities of the classes (inf: PEC). Differentiable in both inputs."""
    gamma = fresnel_of_cosine(cos_inc[:, None], eps[None, :], polarization)  # (Q, K)
    return (probabilities.to(gamma.dtype) * gamma).sum(1)


def reflectance(theta_rad, eps, polarization: str = "TE") -> torch.Tensor:
    """Power reflectance |Gamma|^2 (float64 tensor), same arguments as :func:`fresnel`."""
    return fresnel(theta_rad, eps, polarization).abs() ** 2


def brewster_angle(eps_real: float) -> float:
    """Brewster angle arctan(sqrt(eps')) [rad], where the TM reflectance of a lossless dielectric vanishes."""
    return math.atan(math.sqrt(eps_real))


@dataclass(frozen=True)
class PermittivityEstimate:
    """eps_real: the fitted relative permittivity; rms_residual: RMS reflectance misfit
    (relative to the RMS of the data when the gain was unknown); gain: the fitted
    calibration factor of the reflectances (1 when it was known)."""

    eps_real: float
    rms_residual: float
    gain: float = 1.0


def estimate_permittivity(
    thetas_rad, reflectances, polarization: str = "TE", *,
    bracket: tuple[float, float] = (1.0, 100.0), tolerance: float = 0.02, unknown_gain: bool = False,
) -> PermittivityEstimate:
    """Recover eps' of a lossless dielectric from power reflectances at >= 2 incidence angles.

    Least squares over ``bracket``: a log-spaced scan (vectorised) finds the basin, bounded
    Brent refines it. With ``unknown_gain`` the reflectances are known only up to a factor
    (a radar's amplitude calibration): for each eps' the factor is fitted in closed form,
    so only the shape of R(theta) across the angles decides, and the misfit is relative.
    Raises ValueError when the inputs are invalid or the best fit still misses the data
    by more than ``tolerance`` (RMS, in reflectance units, or relative with unknown gain).
    """
    thetas = np.asarray(thetas_rad, dtype=float).ravel()
    measured = np.asarray(reflectances, dtype=float).ravel()
    if thetas.size != measured.size or thetas.size < 2:
        raise ValueError(f"need reflectances at >= 2 angles with one angle each, got {thetas.size} and {measured.size}")
    if not np.all((thetas >= 0) & (thetas < np.pi / 2)):
        raise ValueError("incidence angles must lie in [0, pi/2) rad")
    if not np.all(np.isfinite(measured) & (measured >= 0) & ((measured <= 1) | unknown_gain)):
        raise ValueError("reflectances must be finite and in [0, 1]")
    t = torch.as_tensor(thetas)

    def misfits(eps_real: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(misfit, gain) for each eps' of a (S,) array."""
        model = reflectance(t[None, :], torch.as_tensor(eps_real)[:, None], polarization).numpy()
        if not unknown_gain:
            return np.sqrt(np.mean((model - measured) ** 2, axis=1)), np.ones(len(model))
        gain = (model @ measured) / np.maximum((model**2).sum(1), 1e-300)
        scale = max(float(np.sqrt(np.mean(measured**2))), 1e-300)
        return np.sqrt(np.mean((gain[:, None] * model - measured) ** 2, axis=1)) / scale, gain

    scan = np.geomspace(*bracket, 400)
    i = int(np.argmin(misfits(scan)[0]))
    lo, hi = scan[max(i - 1, 0)], scan[min(i + 1, scan.size - 1)]
    result = optimize.minimize_scalar(lambda e: float(misfits(np.array([e]))[0][0]), bounds=(lo, hi),
                                      method="bounded", options={"xatol": 1e-8})
    eps_best = float(result.x)
    rms, gain = (float(v[0]) for v in misfits(np.array([eps_best])))
    if rms > tolerance:
        raise ValueError(
            f"no permittivity in [{bracket[0]}, {bracket[1]}] fits these reflectances "
            f"(best eps'={eps_best:.3g} misses by RMS {rms:.3g} > {tolerance})"
        )
    return PermittivityEstimate(eps_best, rms, gain)
