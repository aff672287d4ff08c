"""|grad f| = 1: where the library's SDFs are exact distances, and where CSG stops being one.

Every primitive and rigid transform (and a uniform scale, which scales the distance) keeps
|grad f| = 1 everywhere but on a measure-zero medial set. Union (min) and intersection
(max) of exact SDFs keep |grad f| = 1 too, since the gradient is one child's, yet they are
*not* distances: inside a union of two overlapping balls, min(f1, f2) is the distance to
the nearer ball's own surface, part of which lies inside the other ball, so it
underestimates the distance to the union's boundary. The Eikonal residual cannot see that
error; only a comparison with the true distance can. Smooth blends bend the field in
their blend zone, where |grad f| < 1.

Measured: the residual | |grad f| - 1 | of each shape at random points (float64 autograd),
and on the plane y = 0 around a union and a smooth union of two balls, both the residual
and the error against the true distance (nearest point of a dense sampling of the
union's boundary).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree

from ..geometry import Box, CappedCylinder, Capsule, Cylinder, HalfSpace, Sphere, Torus, eikonal_residual
from ..geometry import smooth_union, union
from ..viz.figures import plt, save_figure

NAME = "eikonal"
SUMMARY = "|grad f| = 1 for every primitive and transform; where union and smooth blends stop being distances"

_A, _B, _R = (-0.03, 0.0, 0.0), (0.03, 0.0, 0.0), 0.05  # two overlapping balls [m]


@dataclass(frozen=True)
class Settings:
    points: int = 20_000
    plane_resolution: int = 100  # even: no sample on the plane x = 0, where min() ties
    boundary_samples: int = 400_000
    blend_m: float = 0.03
    seed: int = 0


QUICK = Settings(points=2_000, plane_resolution=60, boundary_samples=60_000)


@dataclass(frozen=True)
class Result:
    residual_p99: dict[str, float]  # per shape, 99th percentile of | |grad f| - 1 | at random points
    residual_max: dict[str, float]
    union: dict[str, float]  # max residual; max |distance error| [mm] outside and inside
    smooth_union: dict[str, float]
    plane_extent_m: float
    maps: dict[str, list[list[float]]]  # residual and distance error [mm] on y = 0, per blend


def _shapes() -> dict:
    box = Box((0.03, 0.02, 0.01))
    return {"sphere": Sphere(0.04), "box": box, "halfspace": HalfSpace((1.0, 2.0, 2.0), 0.01),
            "cylinder": Cylinder(0.02, (1.0, 1.0, 0.0)), "capped_cylinder": CappedCylinder(0.02, 0.05),
            "torus": Torus(0.04, 0.01, (0.0, 1.0, 1.0)), "capsule": Capsule((-0.03, 0.0, 0.0), (0.02, 0.01, 0.0), 0.01),
            "box rotated": box.rotate((1.0, 1.0, 1.0), 0.7), "box translated": box.translate((0.01, -0.02, 0.03)),
            "box scaled": box.scale(1.7)}


def _union_boundary(count: int, generator: torch.Generator) -> np.ndarray:
    """Points of the union's boundary: each ball's surface outside the other ball."""
    directions = torch.nn.functional.normalize(torch.randn(count, 3, generator=generator, dtype=torch.float64), dim=1)
    points = []
    for centre, other in ((_A, _B), (_B, _A)):
        p = torch.tensor(centre, dtype=torch.float64) + _R * directions
        points.append(p[torch.linalg.norm(p - torch.tensor(other, dtype=torch.float64), dim=1) >= _R])
    return torch.cat(points).numpy()


def run(settings: Settings) -> Result:
    generator = torch.Generator().manual_seed(settings.seed)
    points = (0.2 * torch.rand(settings.points, 3, generator=generator, dtype=torch.float64) - 0.1)
    residuals = {name: eikonal_residual(shape, points).numpy() for name, shape in _shapes().items()}
    extent = 0.1
    u = np.linspace(-extent, extent, settings.plane_resolution)
    xx, zz = np.meshgrid(u, u, indexing="xy")
    plane = torch.tensor(np.stack([xx.ravel(), np.zeros(xx.size), zz.ravel()], axis=1))
    boundary = cKDTree(_union_boundary(settings.boundary_samples, generator))
    a, b = Sphere(_R, _A), Sphere(_R, _B)
    summaries, maps = {}, {}
    for key, shape in (("union", union(a, b)), ("smooth_union", smooth_union(a, b, blend_m=settings.blend_m))):
        with torch.no_grad():
            values = shape(plane).numpy()
        residual = eikonal_residual(shape, plane).numpy()
        if key == "union":  # the true distance to the union's boundary, signed like f
            truth = np.where(values < 0, -1.0, 1.0) * boundary.query(plane.numpy())[0]
            error_mm = (values - truth) * 1e3
            summaries[key] = {"residual_max": float(residual.max()),
                              "error_outside_max_mm": float(np.abs(error_mm[values > 0]).max()),
                              "error_inside_max_mm": float(np.abs(error_mm[values < 0]).max())}
        else:  # a blend changes the surface itself: the residual is what it does to the field
            summaries[key] = {"residual_max": float(residual.max()),
                              "blend_zone_share": float((residual > 1e-3).mean())}
        maps[f"{key}_residual"] = residual.reshape(xx.shape).round(4).tolist()
        if key == "union":
            maps["union_error_mm"] = error_mm.reshape(xx.shape).round(3).tolist()
    return Result({n: float(np.quantile(r, 0.99)) for n, r in residuals.items()},
                  {n: float(r.max()) for n, r in residuals.items()}, summaries["union"], summaries["smooth_union"],
                  extent, maps)


def plot(result: Result, path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), layout="constrained")
    extent = [-result.plane_extent_m * 1e3, result.plane_extent_m * 1e3] * 2
    panels = (("union_residual", "union: | |grad f| - 1 |", "magma", None),
              ("union_error_mm", "union: f - true distance [mm]", "RdBu_r", "mm"),
              ("smooth_union_residual", "smooth union: | |grad f| - 1 |", "magma", None))
    for ax, (key, title, cmap, unit) in zip(axes, panels):
        values = np.asarray(result.maps[key])
        limit = max(float(np.abs(values).max()), 1e-9)
        image = ax.imshow(values, origin="lower", extent=extent, cmap=cmap,
                          vmin=-limit if unit else 0, vmax=limit)
        fig.colorbar(image, ax=ax, label=unit or "residual [1]")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("z [mm]")
        ax.set_title(title)
    save_figure(fig, path)
