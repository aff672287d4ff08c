"""The neural surface f_theta = 0 as flat facets, differentiable in theta: the converged renderer's surface.

Points on the surface are a Monte Carlo quadrature whose speckle is as large as the signal
of a millimetre's error (``recon/surface.py``, ``geometry/zero_set.py``); facets whose phase
is integrated across them in closed form are not. The facets of the neural surface:

1. At a refresh (no gradient): marching cubes of f on cells of edge h <= ``cell_m`` inside
   each voxel of the image grid that the surface can cross (|f(centre)| below a voxel, the
   test of ``recon/surface.py``), the blocks' shared vertices merged; the vertices v0
   projected onto f = 0 by Newton steps, and g0 = grad f(v0) kept.
2. Every step (differentiable): v = v0 - f_theta(v0) g0 / |g0|^2, one Newton step along
   the frozen gradient, so dv/dtheta = -g0 (df/dtheta) / |g0|^2: the normal velocity of the
   level set under a change of theta (MeshSDF's iso-surface gradient, Remelli et al. 2020).
   The facets' centroids, normals and areas follow from the moved vertices
   (:func:`~rfsdf.geometry.facet_geometry`), so a facet turns when its vertices move apart
   along the normal and grows when the surface moves out where it is curved: no curvature
   term and no double backward are needed, as the point sampler's were.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from ..geometry import SLIVER_AREA, facet_geometry, gradient, project_to_zero_set
from ..mesh import mesh_blocks
from .surface import cells_per_voxel, crossing_voxels, smoothed_velocity

__all__ = ["SurfaceMesh", "surface_mesh", "mesh_facets", "Facets"]

_NEWTON_STEPS = 2  # onto f = 0 from a vertex interpolated on a cell's edge
_MIN_GRADIENT_SQ = 0.25  # |grad f|^2 below which a vertex's Newton step is shortened (|grad f| = 1 on an SDF)


@dataclass(frozen=True)
class Facets:
    """Flat triangles (F of them): centroids (F, 3) [m], unit normals (F, 3), areas (F,)
    [m^2], corners (F, 3, 3) [m] relative to the centroids."""

    centroids: torch.Tensor
    normals: torch.Tensor
    area_m2: torch.Tensor
    corners_m: torch.Tensor

    def select(self, index: torch.Tensor) -> Facets:
        """The facets ``index`` (n,)."""
        return Facets(self.centroids[index], self.normals[index], self.area_m2[index], self.corners_m[index])


@dataclass(frozen=True)
class SurfaceMesh:
    """A mesh of f = 0 fixed between refreshes: vertices ``vertices`` (N, 3) [m] on f = 0,
    ``gradients`` (N, 3) grad f there (detached), ``faces`` (F, 3) int64, and the facets as
    they were at the refresh (``facets``), whose centroids stand for the surface wherever the
    trainer needs points of it (Eikonal points, material labels): ``anchors`` and ``area_m2``,
    as the point sampler's candidates."""

    vertices: torch.Tensor
    gradients: torch.Tensor
    faces: torch.Tensor
    facets: Facets

    @property
    def anchors(self) -> torch.Tensor:
        """(F, 3) [m] the facets' centroids at the refresh."""
        return self.facets.centroids

    @property
    def area_m2(self) -> torch.Tensor:
        """(F,) [m^2] the facets' areas at the refresh."""
        return self.facets.area_m2

    @property
    def normals(self) -> torch.Tensor:
        """(F, 3) the facets' unit normals at the refresh."""
        return self.facets.normals

    def __len__(self) -> int:
        return len(self.faces)

    def state(self) -> dict:
        """What a checkpoint keeps of it (tensors): the rest is computed from these."""
        return {"vertices": self.vertices, "gradients": self.gradients, "faces": self.faces}

    @classmethod
    def from_state(cls, state: dict) -> SurfaceMesh:
        """The mesh :meth:`state` kept."""
        vertices, gradients, faces = state["vertices"], state["gradients"], state["faces"]
        return cls(vertices, gradients, faces, _facets(vertices, gradients, faces))


def _facets(vertices: torch.Tensor, gradients: torch.Tensor, faces: torch.Tensor) -> Facets:
    return Facets(*facet_geometry(vertices, faces, torch.nn.functional.normalize(gradients, dim=1)))


def surface_mesh(sdf: Callable[[torch.Tensor], torch.Tensor], voxel_centres_m: torch.Tensor,
                 voxel_values_m: torch.Tensor, voxel_m: float, cell_m: float) -> SurfaceMesh:
    """The mesh of f = 0 (module docstring, step 1) from the voxels (N, 3) [m] of the image
    grid whose values f (N,) [m] say the surface may cross them; cells of edge
    ``voxel_m / s`` <= ``cell_m`` [m]. An empty mesh where no voxel holds surface."""
    device, dtype = voxel_centres_m.device, voxel_centres_m.dtype
    cells = cells_per_voxel(voxel_m, cell_m)
    crossing = crossing_voxels(voxel_centres_m, voxel_values_m, voxel_m)
    sdf_in_dtype = lambda p: sdf(p.to(device, dtype))  # noqa: E731
    try:
        mesh = mesh_blocks(sdf_in_dtype, (crossing - 0.5 * voxel_m).cpu().double().numpy(), voxel_m / cells, cells,
                           device=device)
    except ValueError:  # no voxel holds surface
        empty = torch.zeros(0, 3, device=device, dtype=dtype)
        faces = torch.zeros(0, 3, dtype=torch.int64, device=device)
        return SurfaceMesh(empty, empty, faces, _facets(empty, empty, faces))
    vertices = project_to_zero_set(sdf_in_dtype, torch.as_tensor(np.asarray(mesh.vertices), dtype=dtype, device=device),
                                   steps=_NEWTON_STEPS)
    faces = torch.as_tensor(np.asarray(mesh.faces), dtype=torch.int64, device=device)
    gradients = torch.cat([gradient(sdf, chunk) for chunk in vertices.split(1 << 16)]) if len(vertices) else vertices
    facets = _facets(vertices, gradients, faces)
    kept = facets.area_m2 > SLIVER_AREA * cell_m**2  # marching cubes' slivers out
    return SurfaceMesh(vertices, gradients, faces[kept], facets.select(kept))


def mesh_facets(sdf: Callable[[torch.Tensor], torch.Tensor], mesh: SurfaceMesh, *, smoothing_m: float = 0.0) -> Facets:
    """The facets of ``mesh`` with its vertices moved onto the current f = 0 (module docstring,
    step 2), differentiable in the parameters of ``sdf`` when gradients are being recorded;
    ``smoothing_m`` [m]: the vertices' velocities the loss asks for averaged over that radius
    (:func:`~rfsdf.recon.surface.smoothed_velocity`)."""
    g = mesh.gradients
    values = smoothed_velocity(sdf(mesh.vertices), mesh.vertices, smoothing_m)
    # |g| is about 1 on a fitted SDF; a vertex where it nearly vanishes is not moved farther than
    # its value (a step along g / |g|^2 would throw it away, and a fit with it)
    vertices = mesh.vertices - (values / (g * g).sum(1).clamp(min=_MIN_GRADIENT_SQ))[:, None] * g
    return Facets(*facet_geometry(vertices, mesh.faces, torch.nn.functional.normalize(g, dim=1)))
