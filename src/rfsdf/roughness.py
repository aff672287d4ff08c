"""Surface roughness: a fixed random height field of stated rms height and correlation length.

A surface that is smooth at the radar's wavelength returns only where it mirrors a view (its
specular points and edges); a rough one also returns diffusely, because its height h(p)
along the normal shifts each patch's round-trip phase by about 2 k h cos(theta). The height
field here is Gaussian with

    E[h] = 0,  E[h(p) h(q)] = rms^2 exp(-|p - q|^2 / correlation^2),

so its rms slope is sqrt(2) rms / correlation and, at normal incidence, the mean (coherent)
return of a flat face falls by the Rayleigh roughness factor exp(-2 k^2 rms^2) while the
difference goes into a diffuse return (Ament; Ulaby, Long, "Microwave radar and radiometric
remote sensing", ch. 10). The field is a sum of random Fourier modes (Rahimi and Recht's
features: wavevectors drawn from the spectrum, which for this correlation is Gaussian with
per-axis standard deviation sqrt(2) / correlation, and uniform phases) fixed by a seed, so
it is a property of the surface: every sampling of the same object sees the same heights,
and the simulated data converge as the sampling refines instead of changing with it.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import torch

__all__ = ["Roughness", "HEIGHT_MODES"]

HEIGHT_MODES = 512  # Fourier modes of a height field: the one-point distribution is Gaussian to ~1/sqrt(M)
_CHUNK = 16_384  # points per (points, modes) block: 64 MB in float64


@dataclass(frozen=True)
class Roughness:
    """Gaussian random height field: rms height ``rms_m`` [m], Gaussian correlation length
    ``correlation_m`` [m] (where the correlation falls to 1/e), realisation ``seed``."""

    rms_m: float
    correlation_m: float
    seed: int = 0

    def __post_init__(self):
        if not (math.isfinite(self.rms_m) and self.rms_m >= 0):
            raise ValueError(f"roughness rms_m must be a height >= 0 [m], got {self.rms_m}")
        if not (math.isfinite(self.correlation_m) and self.correlation_m > 0):
            raise ValueError(f"roughness correlation_m must be a length > 0 [m], got {self.correlation_m}")

    @property
    def rms_slope(self) -> float:
        """sqrt(2) rms / correlation: the rms of the field's slope along any direction."""
        return math.sqrt(2.0) * self.rms_m / self.correlation_m

    def height(self, points: torch.Tensor, surface: str = "") -> torch.Tensor:
        """h (N,) [m] at ``points`` (N, 3) [m], float64. ``surface`` names the surface (an
        object's name): two surfaces with the same roughness and seed get independent fields."""
        generator = torch.Generator().manual_seed(zlib.crc32(f"{surface}:{self.seed}".encode()))
        wavevectors = torch.randn(HEIGHT_MODES, 3, generator=generator, dtype=torch.float64)
        wavevectors *= math.sqrt(2.0) / self.correlation_m
        phases = 2 * math.pi * torch.rand(HEIGHT_MODES, generator=generator, dtype=torch.float64)
        p = points.detach().to("cpu", torch.float64)
        sums = [torch.cos(chunk @ wavevectors.T + phases).sum(1) for chunk in p.split(_CHUNK)]  # cos: (n, M)
        return self.rms_m * math.sqrt(2.0 / HEIGHT_MODES) * torch.cat([p.new_zeros(0), *sums])
