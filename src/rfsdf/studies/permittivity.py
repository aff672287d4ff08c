"""The real permittivity of a planar interface from its power reflectance at two angles.

A radar measures reflectance only up to its amplitude calibration, an unknown gain g. One
angle then says nothing about eps'; two angles do, through the *shape* of R(theta): the
ratio R(theta_2) / R(theta_1) depends on eps' alone for a lossless dielectric, and
:func:`rfsdf.materials.estimate_permittivity` with ``unknown_gain`` fits eps' and g by
least squares. With noise, how well depends on how much that ratio changes with eps'
between the two angles: little for nearby angles, and for TE at small angles, where
R(theta) is flat; TM changes fastest towards the Brewster angle (66 deg for eps' = 5.24).
The worked case is a concrete-like interface: eps' = 5.24, ITU-R P.2040 concrete's real
part at 79 GHz, treated as lossless.

Measured: per polarisation, relative noise level of each reflectance and separation of
the two angles (from 20 deg), the relative RMS error of eps' over Monte Carlo trials and
the share of trials the estimator refuses (no eps' in [1, 100] fits); the pair "separates
eps' from noise" where the error is below 20 % and at most 10 % of trials are refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ..materials import brewster_angle, estimate_permittivity, reflectance
from ..viz.figures import plt, save_figure

NAME = "permittivity"
SUMMARY = "eps' of a planar interface from TE/TM reflectance at two angles (unknown gain), against noise and separation"


@dataclass(frozen=True)
class Settings:
    eps_real: float = 5.24
    gain: float = 3.7  # the radar's calibration, unknown to the estimator
    base_angle_deg: float = 20.0
    separations_deg: tuple[float, ...] = (2.0, 10.0, 30.0, 50.0)
    noise_levels: tuple[float, ...] = (0.001, 0.01, 0.03, 0.1)  # relative std of each reflectance
    trials: int = 200
    seed: int = 0


QUICK = Settings(separations_deg=(2.0, 50.0), noise_levels=(0.001, 0.1), trials=30)


@dataclass(frozen=True)
class Result:
    brewster_deg: float
    noiseless_estimate: dict[str, float]  # per polarisation, at the widest separation
    relative_rms_error: dict[str, list[list[float]]]  # [polarisation][noise][separation]
    refused_share: dict[str, list[list[float]]]
    separable: dict[str, list[list[bool]]]
    noise_levels: list[float]
    separations_deg: list[float]


def _estimate(thetas, measured, polarization) -> float | None:
    try:
        return estimate_permittivity(thetas, np.maximum(measured, 0.0), polarization, unknown_gain=True,
                                     tolerance=0.5).eps_real
    except ValueError:
        return None


def run(settings: Settings) -> Result:
    rng = np.random.default_rng(settings.seed)
    errors, refused, separable, noiseless = {}, {}, {}, {}
    for pol in ("TE", "TM"):
        errors[pol], refused[pol], separable[pol] = [], [], []
        for noise in settings.noise_levels:
            row_error, row_refused = [], []
            for separation in settings.separations_deg:
                thetas = np.radians([settings.base_angle_deg, settings.base_angle_deg + separation])
                clean = settings.gain * reflectance(torch.as_tensor(thetas), settings.eps_real, pol).numpy()
                estimates = [_estimate(thetas, clean * (1 + noise * rng.standard_normal(2)), pol)
                             for _ in range(settings.trials)]
                fitted = np.array([e for e in estimates if e is not None])
                row_refused.append(1 - len(fitted) / settings.trials)
                row_error.append(float(np.sqrt(np.mean((fitted / settings.eps_real - 1) ** 2))) if len(fitted)
                                 else math.inf)
            errors[pol].append(row_error)
            refused[pol].append(row_refused)
            separable[pol].append([e < 0.2 and r <= 0.1 for e, r in zip(row_error, row_refused)])
        widest = np.radians([settings.base_angle_deg, settings.base_angle_deg + max(settings.separations_deg)])
        clean = settings.gain * reflectance(torch.as_tensor(widest), settings.eps_real, pol).numpy()
        noiseless[pol] = _estimate(widest, clean, pol)
    return Result(math.degrees(brewster_angle(settings.eps_real)), noiseless, errors, refused, separable,
                  list(settings.noise_levels), list(settings.separations_deg))


def plot(result: Result, path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), layout="constrained", sharey=True)
    for ax, pol in zip(axes, ("TE", "TM")):
        for noise, row in zip(result.noise_levels, result.relative_rms_error[pol]):
            ax.semilogy(result.separations_deg, np.minimum(row, 1e3), marker="o", label=f"noise {noise:.1%}")
        ax.axhline(0.2, color="grey", ls="--", lw=0.8, label="20 %")
        ax.set_xlabel("separation of the two angles [deg] (the first at 20 deg)")
        ax.set_title(f"{pol}: eps' = 5.24, gain unknown (Brewster {result.brewster_deg:.1f} deg)")
        ax.legend(fontsize=8)
    axes[0].set_ylabel("relative RMS error of eps' [1]")
    save_figure(fig, path)
