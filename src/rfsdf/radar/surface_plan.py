"""How the simulator samples a scene's surface: points, facets, or a refusal.

Points lambda/3 apart (``SAMPLES_PER_WAVELENGTH``) resolve the phase of every path, and a
coherent sum of them converges to the scattering integral (study ``roughness``). A room does
not fit: l-room's 186 m^2 at 60 GHz would take 68 million, and a sum of samples 35 mm apart,
what a cap of 150,000 left before, is speckle, the wall's return lost in the samples'
random phases. So, when lambda/3 points would exceed ``max_samples``:

1. the surface becomes flat triangles (``radar/facets.py``) that integrate a piecewise
   linear phase exactly; the objects' meshes are split until each triangle's longest edge
   e is within sqrt(lambda R / 32) at its range R from the nearest view, at the highest
   frequency: the linear interpolation then misses the curved wavefront's phase by at most
   k e^2 / 4R = pi / 64 (12 mm at 64 GHz and 1 m). Measured on a 4 m metal wall 1 m away
   against the image source (tests/test_rooms.py): 24 mm triangles 8 % off, 12 mm 1.3 %,
   6 mm 0.01 % (the interpolation error repeats with the mesh and scatters like a grating);
2. only the triangles some view can see are kept: facing a view's array and in front of it
   (shadows are left to the scattering, per view);
3. more of them than ``max_samples`` is refused, with the count that would be needed.

A curved surface of radius of curvature R_c asks the same of its triangles with R_c for R;
that limit is not checked (a room's faces are flat, and the small scenes, where curvature
matters, fit as points).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["SurfacePlan", "plan_surface", "surface_samples", "seen_by_some_view", "FACET_PHASE_ERROR_RAD"]

FACET_PHASE_ERROR_RAD = math.pi / 64  # most a facet's linear phase may miss the wavefront's, k e^2 / 4R


@dataclass(frozen=True)
class SurfacePlan:
    """Points ``spacing_m`` apart, or (``facets``) triangles sized to their range; the
    surface's area [m^2] and the shortest wavelength [m] the facets are sized for."""

    spacing_m: float
    facets: bool
    total_area_m2: float
    shortest_wavelength_m: float

    def facet_edge_m(self, range_m: np.ndarray) -> np.ndarray:
        """The longest edge [m] a facet ``range_m`` [m] from the nearest view may have."""
        return np.sqrt(4 * FACET_PHASE_ERROR_RAD * np.asarray(range_m) * self.shortest_wavelength_m / (2 * math.pi))

    def summary(self, count: int) -> str:
        """One line for people, given how many samples the plan made."""
        if not self.facets:
            return f"{count} surface points {self.spacing_m * 1e3:.3g} mm apart"
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


def plan_surface(scene, acquisition: Acquisition, spacing_m: float, max_samples: int) -> SurfacePlan:
    """Points ``spacing_m`` apart when ``max_samples`` holds them, else facets (module docstring)."""
    total = float(sum(m.area for m in scene.object_meshes()))
    shortest = SPEED_OF_LIGHT / float(acquisition.frequencies_hz.max())
    return SurfacePlan(spacing_m, total / spacing_m**2 > max_samples, total, shortest)


def surface_samples(scene, acquisition: Acquisition, spacing_m: float, max_samples: int, *, seed: int = 0,
                    stratified: bool = True):
    """The samples the simulator sums and their plan: ``(SurfaceSamples, SurfacePlan)``;
    ValueError when the facets in view exceed ``max_samples``."""
    plan = plan_surface(scene, acquisition, spacing_m, max_samples)
    if not plan.facets:
        return scene.sample_surface(spacing_m, seed=seed, stratified=stratified), plan
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
