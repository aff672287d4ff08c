"""Marching cubes: mesh error and cost against the grid resolution N.

Marching cubes places each vertex by linear interpolation of the field along a grid edge,
so on an exact SDF of a smooth surface the vertices' distance to the true surface falls
like h^2 (h = box / N) times the curvature, while the cost is the N^3 field evaluations.
On a fitted field the mesh can be no better than the field: the error falls with N
until it meets the fit's own error and then stays there, while the cost keeps growing as
N^3 (each evaluation is a network pass).

Measured: a torus (radii 5 and 2 cm in a 20 cm box), meshed from its exact SDF and from
a RadarField regressed onto that SDF (the warm start's regression, `fit_to_image`): per
N, the mean and largest distance of the mesh vertices to the true torus [mm] (|f_true| at
the vertex, exact for this SDF), the relative area error, the number of field
evaluations and the seconds they took.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch

from ..field import RadarField
from ..geometry import Torus
from ..mesh import extract_mesh
from ..recon.warm_start import fit_to_image
from ..viz.figures import plt, save_figure

NAME = "marching-cubes"
SUMMARY = "mesh error (~h^2 on an exact SDF, a plateau on a fitted one) and N^3 cost against grid resolution"

_MAJOR, _MINOR, _HALF = 0.05, 0.02, 0.1  # torus radii and half box [m]


@dataclass(frozen=True)
class Settings:
    resolutions: tuple[int, ...] = (16, 24, 32, 48, 64, 96, 128)
    fit_steps: int = 400
    seed: int = 0


QUICK = Settings(resolutions=(16, 32, 48), fit_steps=60)


@dataclass(frozen=True)
class Result:
    resolutions: list[int]
    exact: dict[str, list[float]]  # mean_mm, max_mm, area_error, evaluations, seconds
    fitted: dict[str, list[float]]
    fit_residual_mm: float  # the regression's last clipped L1 residual
    error_order: float  # slope of log(mean error) against log(N) on the exact SDF (about -2)


class _Counted:
    """An SDF that counts the points it is evaluated at."""

    def __init__(self, sdf):
        self.sdf, self.count = sdf, 0

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        self.count += len(points)
        return self.sdf(points)


def _measure(sdf, truth, resolution: int) -> dict[str, float]:
    counted = _Counted(sdf)
    start = time.perf_counter()
    mesh = extract_mesh(counted, (-_HALF,) * 3, (_HALF,) * 3, resolution)
    seconds = time.perf_counter() - start
    with torch.no_grad():
        distance = truth(torch.as_tensor(mesh.vertices, dtype=torch.float64)).abs().numpy() * 1e3
    area = 4 * math.pi**2 * _MAJOR * _MINOR
    return {"mean_mm": float(distance.mean()), "max_mm": float(distance.max()),
            "area_error": float(mesh.area / area - 1), "evaluations": counted.count, "seconds": seconds}


def _columns(rows: list[dict[str, float]]) -> dict[str, list[float]]:
    return {key: [row[key] for row in rows] for key in rows[0]}


def run(settings: Settings) -> Result:
    torch.manual_seed(settings.seed)
    truth = Torus(_MAJOR, _MINOR, (0.0, 1.0, 1.0))
    field = RadarField((-_HALF,) * 3, (_HALF,) * 3, levels=4)
    residual = fit_to_image(field, (-_HALF,) * 3, (_HALF,) * 3, lambda p: truth(p.double()).float(), None,
                            steps=settings.fit_steps, lr=1e-3, batch=4096, eikonal_weight=0.1,
                            generator=torch.Generator().manual_seed(settings.seed))
    exact = [_measure(lambda p: truth(p.double()).float(), truth, n) for n in settings.resolutions]
    fitted = [_measure(field.sdf, truth, n) for n in settings.resolutions]
    order = float(np.polyfit(np.log(settings.resolutions), np.log([r["mean_mm"] for r in exact]), 1)[0])
    return Result(list(settings.resolutions), _columns(exact), _columns(fitted), residual * 1e3, order)


def plot(result: Result, path) -> None:
    fig, (error, cost) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    n = np.asarray(result.resolutions)
    for key, style in (("exact", "o-"), ("fitted", "s-")):
        error.loglog(n, getattr(result, key)["mean_mm"], style, label=f"{key} SDF: mean")
        error.loglog(n, getattr(result, key)["max_mm"], style, alpha=0.4, label=f"{key} SDF: largest")
        cost.loglog(n, getattr(result, key)["seconds"], style, label=f"{key} SDF")
    error.loglog(n, result.exact["mean_mm"][0] * (n / n[0]) ** -2.0, "k:", label="~ N^-2")
    error.set_xlabel("grid resolution N [voxels per box edge]")
    error.set_ylabel("vertex distance to the true torus [mm]")
    error.set_title(f"mesh error (exact: slope {result.error_order:.2f})")
    error.legend(fontsize=8)
    cost.loglog(n, result.exact["seconds"][-1] * (n / n[-1]) ** 3.0, "k:", label="~ N^3")
    cost.set_xlabel("grid resolution N [voxels per box edge]")
    cost.set_ylabel("field evaluation + marching cubes [s]")
    cost.set_title("cost")
    cost.legend(fontsize=8)
    save_figure(fig, path)
