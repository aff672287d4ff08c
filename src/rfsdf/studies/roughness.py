"""What a rough surface returns, and why the simulator needs roughness for diffuse returns.

A square metal plate 0.5 m in front of one co-located Tx/Rx (77-81 GHz, 16 frequencies),
its data the Kirchhoff sum the simulator forms: samples of the surface, each moved along
the normal by the surface's height field (:class:`rfsdf.roughness.Roughness`), summed
through the sensing operator. Two claims:

1. Facing the radar, the mean return of a rough plate over realisations of its heights
   falls by the Rayleigh (Ament) factor exp(-2 k^2 h^2) of its rms height h, the rest going
   into a diffuse return (Ulaby and Long, "Microwave radar and radiometric remote sensing",
   ch. 10).
2. Tilted away from the radar, a smooth plate returns only from its edges; what random
   samples add on top is quadrature noise, different for every sampling, larger than the
   edges' return at the simulator's lambda / 3 and falling as the samples refine. A rough
   plate returns diffusely: two samplings agree and the return stays as they refine.
   A jittered-grid (stratified) placement of the same number of samples is shown beside
   the random one: it is the quadrature, not the surface, that makes the smooth plate's
   noise.

Measured: the mean return's factor against the closed form per rms height; per tilt,
surface and placement, the return's energy and the energy of the difference between two
samplings, both in dB re the smooth plate facing the radar.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ..radar import Acquisition
from ..radar.operator import SensingOperator
from ..roughness import Roughness
from ..viz.figures import plt, save_figure

NAME = "roughness"
SUMMARY = ("a rough plate's mean return falls by the Rayleigh factor exp(-2 k^2 h^2); tilted away, its diffuse "
           "return is the surface's (two samplings agree), where a smooth plate's is the random sampling's")

FREQUENCIES_HZ = (77e9, 81e9, 16)  # first, last, count
WAVELENGTH_M = 299_792_458.0 / 79e9
PLACEMENTS = ("random", "stratified")


@dataclass(frozen=True)
class Settings:
    side_m: float = 0.08
    range_m: float = 0.5
    rms_wavelengths: tuple[float, ...] = (1 / 40, 1 / 20, 1 / 12, 1 / 8)  # claim 1: rms height / lambda
    correlation_m: float = 3e-3
    realisations: int = 12
    tilts_deg: tuple[float, ...] = (25.0, 40.0)  # claim 2
    rough_rms_m: tuple[float, ...] = (3e-4, 5e-4)  # the objects-rough scene's wood block and concrete ring
    samples_per_wavelength: tuple[float, ...] = (3, 6, 12, 24)
    seed: int = 0


QUICK = Settings(rms_wavelengths=(1 / 20,), realisations=6, tilts_deg=(25.0,), rough_rms_m=(5e-4,),
                 samples_per_wavelength=(3, 12))


@dataclass(frozen=True)
class Result:
    wavelength_mm: float
    rms_mm: list[float]
    mean_return_factor: list[float]  # |mean over realisations of y_rough . y_smooth^* / |y_smooth|^2|
    rayleigh_factor: list[float]  # exp(-2 k^2 h^2)
    oblique: list[dict]  # tilt_deg, surface, placement, samples_per_wavelength, return_db, sampling_difference_db


def plate_samples(spacing_m: float, tilt_rad: float, seed: int, side_m: float, placement: str = "random"):
    """Samples of a square plate through the origin, its normal tilted from +z about y by
    ``tilt_rad``: points (N, 3) [m], normals (N, 3), areas (N,) [m^2], float64. "random":
    area-uniform like the simulator's; "stratified": one point in each cell of a grid."""
    per_edge = max(1, round(side_m / spacing_m))
    generator = torch.Generator().manual_seed(seed)
    if placement == "random":
        uv = torch.rand(per_edge**2, 2, generator=generator, dtype=torch.float64)
    elif placement == "stratified":
        cells = torch.cartesian_prod(torch.arange(per_edge), torch.arange(per_edge)).double()
        uv = (cells + torch.rand(per_edge**2, 2, generator=generator, dtype=torch.float64)) / per_edge
    else:
        raise ValueError(f"unknown placement {placement!r}; known: {', '.join(PLACEMENTS)}")
    uv = (uv - 0.5) * side_m
    c, s = math.cos(tilt_rad), math.sin(tilt_rad)
    points = torch.stack([uv[:, 0] * c, uv[:, 1], -uv[:, 0] * s], dim=1)
    normals = torch.tensor([s, 0.0, c], dtype=torch.float64).expand(len(points), 3)
    return points, normals, torch.full((len(points),), side_m**2 / len(points), dtype=torch.float64)


def plate_return(spacing_m: float, tilt_rad: float, roughness: Roughness | None, *, seed: int = 0,
                 side_m: float = 0.08, range_m: float = 0.5, placement: str = "random") -> torch.Tensor:
    """(K,) complex128: the plate's data at one co-located Tx/Rx ``range_m`` [m] up the z axis."""
    tx = torch.tensor([[[0.0, 0.0, range_m]]], dtype=torch.float64)
    acquisition = Acquisition(tx, tx.clone(), torch.linspace(*FREQUENCIES_HZ, dtype=torch.float64),
                              torch.tensor([[0.0, 0.0, -1.0]]))
    points, normals, area = plate_samples(spacing_m, tilt_rad, seed, side_m, placement)
    if roughness is not None:
        points = points + roughness.height(points, "plate")[:, None] * normals
    return SensingOperator(acquisition).forward(points, area.to(torch.complex128)).reshape(-1)


def _energy(y: torch.Tensor) -> float:
    return float((y.abs() ** 2).sum())


def run(settings: Settings) -> Result:
    geometry = {"side_m": settings.side_m, "range_m": settings.range_m}
    k = 2 * math.pi / WAVELENGTH_M
    facing = plate_return(WAVELENGTH_M / 6, 0.0, None, seed=settings.seed, **geometry)
    rms_m = [fraction * WAVELENGTH_M for fraction in settings.rms_wavelengths]
    factors = []
    for rms in rms_m:
        ratios = []
        for realisation in range(settings.realisations):
            rough = Roughness(rms, settings.correlation_m, settings.seed + realisation)
            y = plate_return(WAVELENGTH_M / 6, 0.0, rough, seed=settings.seed, **geometry)
            ratios.append(complex((y * facing.conj()).sum()) / _energy(facing))
        factors.append(float(abs(np.mean(ratios))))
    reference = _energy(facing)
    decibels = lambda energy: 10 * math.log10(max(energy, 1e-300) / reference)  # noqa: E731
    surfaces = {"smooth": None, **{f"rms {rms * 1e3:g} mm": Roughness(rms, settings.correlation_m, settings.seed)
                                   for rms in settings.rough_rms_m}}
    oblique = []
    for tilt in settings.tilts_deg:
        for surface, roughness in surfaces.items():
            for placement in PLACEMENTS:
                for per_wavelength in settings.samples_per_wavelength:
                    first, second = (plate_return(WAVELENGTH_M / per_wavelength, math.radians(tilt), roughness,
                                                  seed=settings.seed + s, placement=placement, **geometry)
                                     for s in (0, 1))
                    oblique.append({"tilt_deg": tilt, "surface": surface, "placement": placement,
                                    "samples_per_wavelength": per_wavelength, "return_db": decibels(_energy(first)),
                                    "sampling_difference_db": decibels(_energy(first - second))})
    return Result(WAVELENGTH_M * 1e3, [r * 1e3 for r in rms_m], factors,
                  [math.exp(-2 * k**2 * r**2) for r in rms_m], oblique)


def plot(result: Result, path) -> None:
    tilts = sorted({row["tilt_deg"] for row in result.oblique})
    fig, axes = plt.subplots(1, 1 + len(tilts), figsize=(5 * (1 + len(tilts)), 4), layout="constrained")
    left = axes[0]
    fine = np.linspace(0, max(result.rms_mm) * 1.1, 100)
    left.plot(fine, np.exp(-2 * (2 * np.pi / result.wavelength_mm) ** 2 * fine**2), "k-", label="exp(-2 k^2 h^2)")
    left.plot(result.rms_mm, result.mean_return_factor, "o", label="mean return / smooth return")
    left.set_xlabel("rms height h [mm]")
    left.set_title("facing the radar: mean return of a rough plate")
    left.legend(fontsize=8)
    for ax, tilt in zip(axes[1:], tilts):
        surfaces = list(dict.fromkeys(row["surface"] for row in result.oblique))
        for colour, surface in enumerate(surfaces):
            for placement, style in zip(PLACEMENTS, ("-", "--")):
                rows = [r for r in result.oblique if (r["tilt_deg"], r["surface"], r["placement"]) ==
                        (tilt, surface, placement)]
                x = [r["samples_per_wavelength"] for r in rows]
                ax.semilogx(x, [r["return_db"] for r in rows], style, marker="o", color=f"C{colour}",
                            label=f"{surface}, {placement}: return")
                if placement == "random":
                    ax.semilogx(x, [r["sampling_difference_db"] for r in rows], ":", marker="x", color=f"C{colour}",
                                label=f"{surface}, random: two samplings' difference")
        ax.minorticks_off()
        ax.set_xticks(x, [f"{n:g}" for n in x])
        ax.set_xlabel("samples per wavelength")
        ax.set_ylabel("energy [dB re the smooth plate facing the radar]")
        ax.set_title(f"plate tilted {tilt:g} deg away")
    axes[1].legend(fontsize=7)
    save_figure(fig, path)
