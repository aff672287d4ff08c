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
    "Material", "ParameterSet", "MATERIALS", "get_material", "class_permittivities", "fresnel", "fresnel_of_cosine", "mixture_fresnel", "FresnelTable", "reflectance", "brewster_angle",
    "PermittivityEstimate", "estimate_permittivity", "EPS0", "MATERIAL_CLASSES", "class_reflectivities",
    "point_reflectivity", "reflectivity_class",
]

EPS0 = 8.8541878128e-12  # vacuum permittivity [F/m]
POLARIZATIONS = ("TE", "TM", "mean")


@dataclass(frozen=True)
class ParameterSet:
    """One row of ITU-R P.2040 Table 3: eps' = a f^b, sigma = c f^d [S/m], f in GHz, valid
    over ``valid_ghz`` (the recommendation's frequency range for that fit)."""

    a: float = 1.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0
    valid_ghz: tuple[float, float] = (1.0, 100.0)


@dataclass(frozen=True)
class Material:
    """A material as ITU-R P.2040 models it: one or more parameter sets, each with its band.

    At a frequency the first set whose band holds it applies (the order of the table, which
    Sionna RT follows too, so both tools give a material the same permittivity); outside
    every band :meth:`permittivity` raises. ``pec`` marks a perfect electric conductor
    (|Gamma| = 1 at every angle and frequency).
    """

    name: str
    bands: tuple[ParameterSet, ...] = (ParameterSet(),)
    pec: bool = False

    def parameters(self, frequency_hz: float) -> ParameterSet:
        """The parameter set that applies at ``frequency_hz`` [Hz]; ValueError naming the
        material and its bands when none does."""
        f_ghz = frequency_hz / 1e9
        for band in self.bands:
            lo, hi = band.valid_ghz
            if lo <= f_ghz <= hi:
                return band
        ranges = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in (b.valid_ghz for b in self.bands))
        raise ValueError(f"material {self.name!r}: {f_ghz:.3g} GHz is outside its ITU-R P.2040 range {ranges} GHz")

    def in_band(self, frequency_hz: float) -> bool:
        """True when some parameter set (or the PEC) covers ``frequency_hz`` [Hz]."""
        return self.pec or any(lo <= frequency_hz / 1e9 <= hi for lo, hi in (b.valid_ghz for b in self.bands))

    def permittivity(self, frequency_hz: float) -> complex:
        """Complex relative permittivity eps' - j eps'' at ``frequency_hz`` [Hz] (inf for PEC)."""
        if self.pec:
            return complex(math.inf, 0.0)
        p = self.parameters(frequency_hz)
        f_ghz = frequency_hz / 1e9
        eps_real = p.a * f_ghz**p.b
        sigma = p.c * f_ghz**p.d  # [S/m]
        return complex(eps_real, -sigma / (2 * math.pi * frequency_hz * EPS0))

    @classmethod
    def from_permittivity(cls, name: str, eps_real: float, conductivity_s_per_m: float = 0.0) -> Material:
        """A user material with constant eps' and conductivity [S/m] at every frequency."""
        if not eps_real >= 1.0:
            raise ValueError(f"material {name!r}: relative permittivity must be >= 1, got {eps_real}")
        if not conductivity_s_per_m >= 0.0:
            raise ValueError(f"material {name!r}: conductivity must be >= 0 S/m, got {conductivity_s_per_m}")
        return cls(name, (ParameterSet(a=float(eps_real), c=float(conductivity_s_per_m), valid_ghz=(0.0, math.inf)),))


def _itu(name: str, *rows: tuple[float, float, float, float, float, float]) -> Material:
    """A catalogue material from rows (f_low_GHz, f_high_GHz, a, b, c, d) of P.2040-3 Table 3."""
    return Material(name, tuple(ParameterSet(a, b, c, d, (lo, hi)) for lo, hi, a, b, c, d in rows))


# ITU-R P.2040-3 (08/2023), Table 3, rows in the table's order (which decides where two bands
# overlap, e.g. plasterboard at 110-330 and 100-400 GHz). The 1-100 GHz rows are those of
# P.2040-1, so every result measured before is unchanged. Metal stays a perfect conductor at
# every frequency (Table 3's metal is sigma = 1e7 S/m over 1-100 GHz: |Gamma| 0.97-0.99 at
# 60-79 GHz, a few per cent below; rfsdf's radars and its earlier results use the PEC).
MATERIALS: dict[str, Material] = {
    m.name: m
    for m in [
        _itu("concrete", (1, 100, 5.24, 0, 0.0462, 0.7822), (110, 330, 5.17, 0, 0.0145, 1.09)),
        _itu("brick", (1, 40, 3.91, 0, 0.0238, 0.16), (110, 330, 4.15, 0, 0.0006, 1.5712)),
        _itu("plasterboard", (1, 100, 2.73, 0, 0.0085, 0.9395), (110, 330, 2.56, 0, 0.0001, 1.7799),
             (100, 400, 2.65, 0, 0.0002, 1.598)),
        _itu("wood", (0.001, 100, 1.99, 0, 0.0047, 1.0718), (110, 330, 1.82, 0, 0.004, 1.0761),
             (100, 400, 2.1183, 0, 0.0055, 1.1113)),
        _itu("glass", (0.1, 100, 6.31, 0, 0.0036, 1.3394), (220, 450, 5.79, 0, 0.0004, 1.658),
             (100, 400, 6.5767, 0, 0.0012, 1.4697)),
        _itu("clear_acrylic", (110, 330, 2.58, 0, 0.0001, 1.6524)),
        _itu("ceiling_board", (1, 100, 1.48, 0, 0.0011, 1.075), (220, 450, 1.52, 0, 0.0029, 1.029),
             (100, 400, 1.2567, 0, 0.00013, 1.454)),
        _itu("chipboard", (1, 100, 2.58, 0, 0.0217, 0.78), (100, 200, 2.16, 0, 0.0023, 1.359)),
        _itu("plywood", (1, 40, 2.71, 0, 0.33, 0.0), (110, 330, 1.94, 0, 0.0067, 0.9982),
             (100, 400, 2.17, 0, 0.0063, 1.045)),
        _itu("marble", (1, 60, 7.074, 0, 0.0055, 0.9262), (110, 330, 7.94, 0, 0.0001, 1.733),
             (100, 400, 8.62, 0, 0.0027, 1.15)),
        _itu("floorboard", (50, 100, 3.66, 0, 0.0044, 1.3515), (220, 300, 5.27, 0, 2.22e-17, 7.3413),
             (300, 400, 5.27, 0, 0.0003, 2.0298), (400, 450, 5.27, 0, 49.8726, 0.0),
             (100, 400, 3.1575, 0, 0.001675, 1.32775)),
        _itu("vinyl_tile", (1, 40, 3.62, 0, 0.0051, 0.8422)),
        _itu("carpet_tile", (1, 40, 2.08, 0, 0.0009, 0.82)),
        _itu("asphalt_concrete", (1, 40, 4.83, 0, 0.0108, 1.3969)),
        _itu("very_dry_ground", (1, 10, 3.0, 0, 0.00015, 2.52)),
        _itu("medium_dry_ground", (1, 10, 15.0, -0.1, 0.035, 1.63)),
        _itu("wet_ground", (1, 10, 30.0, -0.4, 0.15, 1.3)),
        Material("metal", (ParameterSet(valid_ghz=(0.0, math.inf)),), pec=True),
    ]
}
_ALIASES = {"drywall": "plasterboard", "pec": "metal"}


# the classes a material is told apart among when nothing else is said: the material head's
# default (rfsdf.recon.config) and a scene model's free material (rfsdf.scene_model)
MATERIAL_CLASSES = ("metal", "glass", "concrete", "plasterboard", "wood")


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

    Returns
    -------
    complex128 tensor of the broadcast shape.

    Notes
    -----
    Conventions: TE = E-field ratio;
    TM as in the design, (eps cos t - sqrt(eps - sin^2 t)) / (eps cos t + sqrt(...)), so
    Gamma_TM(0) = -Gamma_TE(0). Averaging the complex coefficients would therefore cancel
    at normal incidence; "mean" is the unpolarised amplitude sqrt((|TE|^2 + |TM|^2) / 2)
    with the TE phase. A PEC gives TE = -1, TM = +1.

    Examples
    --------
    At normal incidence |Gamma| = (sqrt(eps) - 1) / (sqrt(eps) + 1): 1/3 for eps = 4.

    >>> round(float(fresnel(0.0, 4.0).abs()), 4), float(fresnel(0.3, float("inf")).real)
    (0.3333, -1.0)
    """
    return fresnel_of_cosine(torch.cos(torch.as_tensor(theta_rad, dtype=torch.float64)), eps, polarization)


def fresnel_of_cosine(cos_inc, eps, polarization: str = "TE") -> torch.Tensor:
    """:func:`fresnel` of cos(theta_inc) (float or tensor in [0, 1]) instead of the angle:
    differentiable in the cosine everywhere, normal incidence included (where arccos is not),
    so a renderer can take gradients through the incidence geometry. complex128."""
    if polarization not in POLARIZATIONS:
        raise ValueError(f"polarization must be one of {POLARIZATIONS}, got {polarization!r}")
    cos_t = torch.as_tensor(cos_inc, dtype=torch.float64)
    eps = _as_eps(eps).to(cos_t.device)
    if polarization == "mean":
        te, tm = fresnel_of_cosine(cos_t, eps, "TE"), fresnel_of_cosine(cos_t, eps, "TM")
        amplitude = torch.sqrt((te.abs() ** 2 + tm.abs() ** 2) / 2)
        return amplitude * torch.sgn(te)
    pec = torch.isinf(eps.real)
    # the PEC's constant is taken below; its own branch gets a harmless cosine (at grazing
    # incidence the dielectric formula with eps = 1 is 0 / 0, whose NaN the gradient would carry)
    cos_c = torch.where(pec, torch.ones_like(cos_t), cos_t).to(torch.complex128)
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


class FresnelTable:
    """:func:`mixture_fresnel` at the cost of a lookup: each class's coefficient tabulated on
    ``samples`` cosines evenly spaced over [0, 1] and interpolated linearly between them.

    A renderer evaluates the mixture for every surface sample in every frame of a view (a scan:
    69 frames of 45,000 facets, five classes, two polarisations, complex128 square roots); the
    coefficients are smooth in the cosine (the PEC's constant, the dielectrics' sqrt(eps - 1 +
    cos^2) with eps - 1 far from 0), so 2049 samples reproduce the catalogue's to 1e-6 and
    their derivative in the cosine to 2e-3 of its largest value (tests/test_materials.py),
    at a tenth of the time, gradients included.

    eps : (K,) complex relative permittivities of the classes (inf: PEC).
    """

    def __init__(self, eps: torch.Tensor, polarization: str = "mean", samples: int = 2049):
        if samples < 2:
            raise ValueError(f"a Fresnel table needs at least 2 samples, got {samples}")
        cos = torch.linspace(0.0, 1.0, samples, dtype=torch.float64)
        table = fresnel_of_cosine(cos[:, None], _as_eps(eps)[None, :], polarization)  # (N, K) complex128
        self.values, self.slopes = table[:-1], table[1:] - table[:-1]  # (N - 1, K): segment starts and rises

    def to(self, device) -> "FresnelTable":
        """This table on ``device`` (in place; returns it)."""
        self.values, self.slopes = self.values.to(device), self.slopes.to(device)
        return self

    def mixture(self, cos_inc: torch.Tensor, probabilities: torch.Tensor) -> torch.Tensor:
        """sum_k p_k Gamma_k(theta_inc), (Q,) complex (complex64 for float32 cosines, complex128
        for float64). cos_inc : (Q,) in [0, 1] (clamped). probabilities : (Q, K).
        Differentiable in both (in the cosine, the slope of its segment)."""
        dtype = torch.promote_types(cos_inc.dtype, torch.complex64)
        position = cos_inc.clamp(0, 1) * len(self.values)
        segment = position.detach().floor().clamp(max=len(self.values) - 1).long()
        p = probabilities.to(dtype)
        start = (p * self.values.to(dtype)[segment]).sum(1)
        rise = (p * self.slopes.to(dtype)[segment]).sum(1)
        return start + (position - segment).to(dtype) * rise


def reflectance(theta_rad, eps, polarization: str = "TE") -> torch.Tensor:
    """Power reflectance |Gamma|^2 (float64 tensor), same arguments as :func:`fresnel`."""
    return fresnel(theta_rad, eps, polarization).abs() ** 2


def brewster_angle(eps_real: float) -> float:
    """Brewster angle arctan(sqrt(eps')) [rad], where the TM reflectance of a lossless dielectric vanishes.

    >>> theta = brewster_angle(4.0)
    >>> round(math.degrees(theta), 2), float(reflectance(theta, 4.0, "TM")) < 1e-30
    (63.43, True)
    """
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


def class_reflectivities(classes: tuple[str, ...], frequency_hz: float) -> torch.Tensor:
    """(K,) |Gamma| of each class at normal incidence at ``frequency_hz`` (unpolarised)."""
    return torch.as_tensor(point_reflectivity(torch.eye(len(classes)), classes, frequency_hz))


def point_reflectivity(probabilities: torch.Tensor, classes: tuple[str, ...], frequency_hz: float) -> np.ndarray:
    """(Q,) |sum_k p_k Gamma_k| at normal incidence: the reflectivity the renderer gives
    points whose class probabilities are ``probabilities`` (Q, K)."""
    cos = torch.ones(len(probabilities), dtype=torch.float64)
    eps = class_permittivities(classes, frequency_hz)
    return mixture_fresnel(cos, probabilities.detach().cpu().double(), eps).abs().numpy()


def reflectivity_class(reflectivity, classes: tuple[str, ...], frequency_hz: float) -> np.ndarray:
    """The class of ``classes`` whose |Gamma| at normal incidence is nearest to each
    ``reflectivity`` (scalar or array): an array of class names, same shape."""
    levels = class_reflectivities(classes, frequency_hz).numpy()
    nearest = np.abs(np.asarray(reflectivity, dtype=float)[..., None] - levels).argmin(-1)
    return np.asarray(classes)[nearest]
