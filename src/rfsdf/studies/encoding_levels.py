"""Positional-encoding levels against the smallest feature a field can hold.

A network on raw coordinates is biased to smooth functions; the positional encoding feeds
it sinusoids down to half-period S / 2^L (S the box), and `levels_for(S, s)` picks the
fewest levels whose finest half-period is at most the feature size s. Too few levels and
a wavelength-sized feature is blurred; too many give the regression high-frequency
freedom that its finite batches do not pin down, and the error grows again.

Measured: a RadarField (default depth 6 and width 128) regressed onto the SDF of a 20 mm
ball with a 4 mm ball (about one wavelength at 79 GHz) 10 mm beside it, in a 12 cm box,
by the warm start's regression (a quarter of each batch near the two surfaces), for each
L: the mean |f - f_true| over points within 2 mm of the small ball's surface and of the
large ball's, and whether the small ball's centre is inside the fit (f < 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..field import RadarField, levels_for
from ..geometry import Sphere, union
from ..recon.warm_start import fit_to_image
from ..viz.figures import plt, save_figure

NAME = "encoding-levels"
SUMMARY = "error on a wavelength-sized feature against the number of encoding levels, levels_for marked"

_HALF, _SMALL, _LARGE = 0.06, 0.004, 0.02  # half box, small and large ball radii [m]
_SMALL_CENTRE = (_LARGE + 0.010 + _SMALL, 0.0, 0.0)


@dataclass(frozen=True)
class Settings:
    levels: tuple[int, ...] = (1, 3, 4, 5, 7)  # (L = 0, raw coordinates, diverged in this regression)
    steps: int = 600
    batch: int = 4096
    seed: int = 0


QUICK = Settings(levels=(1, 4), steps=60, batch=1024)  # too short to rank the levels: keys and sanity only


@dataclass(frozen=True)
class Result:
    levels: list[int]
    suggested_levels: int  # levels_for(box, small ball's diameter)
    small_error_mm: list[float]
    large_error_mm: list[float]
    small_ball_inside: list[bool]


def _shell(centre, radius: float, count: int, generator: torch.Generator) -> torch.Tensor:
    """(count, 3) points within 2 mm of a sphere's surface [m]."""
    direction = torch.nn.functional.normalize(torch.randn(count, 3, generator=generator), dim=1)
    return torch.tensor(centre) + (radius + (torch.rand(count, 1, generator=generator) * 2 - 1) * 0.002) * direction


def run(settings: Settings) -> Result:
    lower, upper = (-_HALF,) * 3, (_HALF,) * 3
    truth = union(Sphere(_LARGE), Sphere(_SMALL, _SMALL_CENTRE))
    generator = torch.Generator().manual_seed(settings.seed)
    near_small, near_large = _shell(_SMALL_CENTRE, _SMALL, 2000, generator), _shell((0.0, 0.0, 0.0), _LARGE, 2000, generator)
    small, large, inside = [], [], []
    for levels in settings.levels:
        torch.manual_seed(settings.seed)
        field = RadarField(lower, upper, levels=levels, init_radius_m=_LARGE)
        fit_to_image(field, lower, upper, truth, None, steps=settings.steps, lr=1e-3, batch=settings.batch,
                     eikonal_weight=0.1, generator=torch.Generator().manual_seed(settings.seed),
                     near_m=torch.cat([near_small, near_large]), near_share=0.25, near_jitter_m=0.001)
        with torch.no_grad():
            small.append(float((field.sdf(near_small) - truth(near_small)).abs().mean()) * 1e3)
            large.append(float((field.sdf(near_large) - truth(near_large)).abs().mean()) * 1e3)
            inside.append(bool(field.sdf(torch.tensor([_SMALL_CENTRE])) < 0))
    return Result(list(settings.levels), levels_for(2 * _HALF, 2 * _SMALL), small, large, inside)


def plot(result: Result, path) -> None:
    fig, ax = plt.subplots(figsize=(6.5, 4), layout="constrained")
    ax.plot(result.levels, result.small_error_mm, "o-", label="near the 4 mm ball")
    ax.plot(result.levels, result.large_error_mm, "s-", label="near the 20 mm ball")
    for level, error, kept in zip(result.levels, result.small_error_mm, result.small_ball_inside):
        if not kept:
            ax.annotate("4 mm ball lost", (level, error), textcoords="offset points", xytext=(-40, 8), fontsize=8)
    ax.axvline(result.suggested_levels, color="k", ls=":", label=f"levels_for = {result.suggested_levels}")
    ax.set_xlabel("positional-encoding levels L")
    ax.set_ylabel("mean |f - f_true| within 2 mm of the surface [mm]")
    ax.set_title("a wavelength-sized feature against encoding levels")
    ax.legend(fontsize=8)
    save_figure(fig, path)
