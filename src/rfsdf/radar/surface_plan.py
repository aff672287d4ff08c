"""How the simulator covers a scene's surface: facets of its zero set, points, range-sized facets, or a refusal.

A small scene is summed as flat triangles on marching-cubes cells ``spacing_m`` (lambda/3 by
default), their vertices on the exact zero set, creases refined and each triangle at the
surface's mean height (:mod:`~rfsdf.geometry.zero_set`), whose piecewise linear phase is
integrated exactly (``radar/facets.py``): the converged quadrature, two meshes agreeing per
view to 0.9996 where lambda/3 points agreed to 0.78-0.93 (``benchmarks/forward_convergence.py``).
Points that far apart (``surface="points"``) stay for comparison; their sum is a Monte Carlo
quadrature (study ``roughness``). A room does not fit either way: l-room's 186 m^2 at 60 GHz
would take 68 million cells, and a sum of samples 35 mm apart, what a cap of 150,000 left
before, is speckle. So, when points ``spacing_m`` apart would exceed ``max_samples``:

1. the surface becomes flat triangles that integrate a piecewise linear phase exactly; the
   objects' meshes are split until each triangle's longest edge e is within
   sqrt(lambda R / 32) at its range R from the nearest view, at the highest frequency: the
   linear interpolation then misses the curved wavefront's phase by at most
   k e^2 / 4R = pi / 64 (12 mm at 64 GHz and 1 m). Measured on a 4 m metal wall 1 m away
   against the image source (tests/test_rooms.py): 24 mm triangles 8 % off, 12 mm 1.3 %,
   6 mm 0.01 % (the interpolation error repeats with the mesh and scatters like a grating);
2. only the triangles some view can see are kept: facing a view's array and in front of it
   (shadows are left to the scattering, per view);
3. more of them than ``max_samples`` is refused, with the count that would be needed.

A curved surface of radius of curvature R_c asks the same of its triangles with R_c for R;
that limit is not checked (a room's faces are flat; the small scenes' curvature is what the
zero-set facets' height correction takes care of).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["SurfacePlan", "plan_surface", "surface_samples", "seen_by_some_view", "FACET_PHASE_ERROR_RAD", "SURFACES"]

FACET_PHASE_ERROR_RAD = math.pi / 64  # most a facet's linear phase may miss the wavefront's, k e^2 / 4R
SURFACES = ("facets", "points")  # how a surface the simulator can cover at its spacing is summed


@dataclass(frozen=True)
class SurfacePlan:
    """The surface at ``spacing_m``: as ``surface`` says, flat triangles on marching-cubes
    cells of that edge or points that far apart; or (``facets``) triangles sized to their
    range; the surface's area [m^2] and the shortest wavelength [m] the facets are sized for."""

    spacing_m: float
    facets: bool
    total_area_m2: float
    shortest_wavelength_m: float
    surface: str = "facets"

    def facet_edge_m(self, range_m: np.ndarray) -> np.ndarray:
        """The longest edge [m] a facet ``range_m`` [m] from the nearest view may have."""
        return np.sqrt(4 * FACET_PHASE_ERROR_RAD * np.asarray(range_m) * self.shortest_wavelength_m / (2 * math.pi))

    def summary(self, count: int) -> str:
        """One line for people, given how many samples the plan made."""
        if not self.facets and self.surface == "points":
            return f"{count} surface points {self.spacing_m * 1e3:.3g} mm apart"
        if not self.facets:
            return f"{count} surface facets on {self.spacing_m * 1e3:.3g} mm cells, creases refined"
        return (f"{count} surface facets in view, edges within {float(self.facet_edge_m(1.0)) * 1e3:.3g} mm x "
                f"sqrt(range / 1 m): {self.total_area_m2:.3g} m^2 of surface would take "
                f"{self.total_area_m2 / self.spacing_m**2:,.0f} points {self.spacing_m * 1e3:.3g} mm apart")


def _view_centres(acquisition: Acquisition) -> torch.Tensor:
    return 0.5 * (acquisition.tx_m.mean(1) + acquisition.rx_m.mean(1)).double()  # (V, 3)


def seen_by_some_view(points: torch.Tensor, normals: torch.Tensor, acquisition: Acquisition) -> torch.Tensor:
    """(N,) bool: samples (N, 3) [m] with unit normals (N, 3) that face some view's array
    centre and lie in front of that array (boresight side). No shadows."""
    p, n = points.double(), normals.double()
    seen = torch.zeros(len(p), dtype=torch.bool, device=p.device)
    for centre, boresight in zip(_view_centres(acquisition).to(p), acquisition.boresight.to(p)):
        to_view = centre - p
        seen |= ((to_view * n).sum(1) > 0) & ((to_view * boresight).sum(1) < 0)
    return seen


def plan_surface(scene, acquisition: Acquisition, spacing_m: float, max_samples: int,
                 surface: str = "facets") -> SurfacePlan:
    """``surface`` ("facets" or "points") at ``spacing_m`` when ``max_samples`` points that far
    apart would cover it, else facets sized to their range (module docstring)."""
    if surface not in SURFACES:
        raise ValueError(f"unknown surface {surface!r}; known: {', '.join(SURFACES)}")
    total = float(sum(m.area for m in scene.object_meshes()))
    shortest = SPEED_OF_LIGHT / float(acquisition.frequencies_hz.max())
    return SurfacePlan(spacing_m, total / spacing_m**2 > max_samples, total, shortest, surface)


def surface_samples(scene, acquisition: Acquisition, spacing_m: float, max_samples: int, *, seed: int = 0,
                    stratified: bool = True, surface: str = "facets"):
    """The samples the simulator sums and their plan: ``(SurfaceSamples, SurfacePlan)``:
    facets of the zero set on cells ``spacing_m`` (``seed`` offsets their grid;
    :meth:`~rfsdf.scene.Scene.zero_set_facets`) or points that far apart (``stratified``
    or not; :meth:`~rfsdf.scene.Scene.sample_surface`), or past ``max_samples``, facets sized
    to their range; ValueError when those in view exceed ``max_samples``."""
    plan = plan_surface(scene, acquisition, spacing_m, max_samples, surface)
    if not plan.facets and surface == "points":
        return scene.sample_surface(spacing_m, seed=seed, stratified=stratified), plan
    if not plan.facets:
        return scene.zero_set_facets(spacing_m, seed=seed), plan
    centres = _view_centres(acquisition).numpy()

    def max_edge(centroids: np.ndarray) -> np.ndarray:
        nearest = np.min([np.linalg.norm(centroids - c, axis=1) for c in centres], axis=0)
        return plan.facet_edge_m(nearest)

    facets = scene.surface_facets(max_edge)
    facets = facets.select(seen_by_some_view(facets.points, facets.normals, acquisition))
    if len(facets.points) > max_samples:
        raise ValueError(
            f"scene {scene.name!r}: {len(facets.points):,} facets in view (edges within sqrt(lambda R / 32) at their "
            f"range R, {float(plan.facet_edge_m(1.0)) * 1e3:.3g} mm at 1 m) exceed max_samples {max_samples:,}: "
            "raise it (time and memory grow with it), or simulate a smaller scene")
    return facets, plan
