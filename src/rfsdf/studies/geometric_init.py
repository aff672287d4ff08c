"""Geometric initialisation (SAL): the network starts as a sphere's SDF.

With SAL's initialisation (Atzmon & Lipman 2020; the last layer set from the mean profile
so f starts near |p| - r, `field/networks.py`) the zero level set of a fresh network is one
closed surface. With PyTorch's default initialisation f is a random smooth function whose
zero set is whatever it happens to be: several pieces, or none inside the box. A fit has
to create, merge or delete those pieces, and the Eikonal term alone does not.

Measured, over seeds: the connected components of {f < 0} on a grid in the box, at
initialisation and after regressing f onto a torus's SDF for a few hundred steps (the warm
start's regression), the regression's last residual, and the components the torus has.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage

from ..field import RadarField
from ..geometry import Grid, Torus
from ..mesh import evaluate_on_grid
from ..recon.warm_start import fit_to_image
from ..viz.figures import plt, save_figure

NAME = "geometric-init"
SUMMARY = "connected components of the zero level set and the fit's residual with and without SAL initialisation"

_HALF = 0.1  # half box [m]


@dataclass(frozen=True)
class Settings:
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    fit_steps: int = 300
    batch: int = 4096
    resolution: int = 48


QUICK = Settings(seeds=(0, 1, 2), fit_steps=30, batch=1024, resolution=32)


@dataclass(frozen=True)
class Result:
    components_at_init: dict[str, list[int]]  # "geometric" / "random": per seed
    components_after_fit: dict[str, list[int]]
    residual_mm: dict[str, list[float]]
    target_components: int


def _components(sdf, grid: Grid) -> int:
    return int(ndimage.label(evaluate_on_grid(sdf, grid) < 0)[1])


def run(settings: Settings) -> Result:
    lower, upper = (-_HALF,) * 3, (_HALF,) * 3
    grid = Grid(lower, upper, (settings.resolution,) * 3)
    torus = Torus(0.05, 0.02, (0.0, 1.0, 1.0))
    at_init, after, residual = {}, {}, {}
    for key, geometric in (("geometric", True), ("random", False)):
        at_init[key], after[key], residual[key] = [], [], []
        for seed in settings.seeds:
            torch.manual_seed(seed)
            field = RadarField(lower, upper, levels=4, geometric_init=geometric)
            at_init[key].append(_components(field.sdf, grid))
            last = fit_to_image(field, lower, upper, torus, None, steps=settings.fit_steps, lr=1e-3, batch=settings.batch,
                                eikonal_weight=0.1, generator=torch.Generator().manual_seed(seed))
            after[key].append(_components(field.sdf, grid))
            residual[key].append(last * 1e3)
    return Result(at_init, after, residual, _components(torus, grid))


def plot(result: Result, path) -> None:
    fig, (count, fit) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    seeds = np.arange(len(result.residual_mm["geometric"]))
    for offset, key in ((-0.2, "geometric"), (0.2, "random")):
        count.bar(seeds + offset - 0.1, result.components_at_init[key], 0.2, label=f"{key} init: at start")
        count.bar(seeds + offset + 0.1, result.components_after_fit[key], 0.2, label=f"{key} init: after the fit")
        fit.bar(seeds + offset, result.residual_mm[key], 0.4, label=f"{key} init")
    count.axhline(result.target_components, color="k", ls=":", label="the torus")
    count.set_xlabel("seed")
    count.set_ylabel("components of {f < 0} [count]")
    count.legend(fontsize=8)
    fit.set_xlabel("seed")
    fit.set_ylabel("regression residual after the fit [mm]")
    fit.legend(fontsize=8)
    save_figure(fig, path)
