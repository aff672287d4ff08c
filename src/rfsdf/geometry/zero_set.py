"""Flat triangles on an SDF's zero set: a surface integral's quadrature that converges.

A coherent sum over surface *points* is a Monte Carlo quadrature of the scattering integral:
on faces turned away from the radar, where the round-trip phase turns by more than a radian
between neighbours, every sampling leaves its own speckle (two lambda/3 samplings of the demo
scene correlated 0.78-0.93 per view). Flat triangles whose phase is integrated across them in
closed form (``radar/facets.py``) cancel there as the surface does, provided the triangles
follow the surface:

1. Vertices on the zero set. A marching-cubes mesh (cells ``cell_m``) has its vertices
   interpolated along the cells' edges; Newton steps p <- p - f grad f / |grad f|^2 put them
   on f = 0 (:func:`project_to_zero_set`).
2. Creases refined. Where the surface turns sharply (a box's edge, a cylinder's rim) a
   triangle spanning the crease cuts the corner by a bevel as wide as the cell, and that
   bevel glints; triangles whose edges' midpoints lie off the surface by more than
   ``CREASE_RATIO`` of the triangle's size are split in four, their new vertices moved onto
   the surface along their edge's mean normal (so that they land on the crease), until their
   edges are shorter than a given length (:func:`refine_creases`; the simulator's: a third
   of the cell).
3. The chord's sagitta restored. A flat triangle with its corners on a curved surface lies
   inside it, by e^2 / 8 R on average for edges e on a sphere of radius R (28 um for 1.5 mm
   on a 1 cm radius, 0.2 rad of round-trip phase at 79 GHz). Each triangle is moved out along
   its normal by the mean height of the surface over it, estimated from its vertex normals
   as sum over its edges of (n_j - n_i) . (v_j - v_i) / 24 (exact to second order:
   e^2 / 8 R on a sphere; :func:`facet_geometry`).

Measured on the demo scene (``benchmarks/forward_convergence.py``): two meshes with other
grid offsets, on lambda/3 and lambda/4 cells, agree per view to a correlation of 0.999 and
within 1 % in amplitude. The vertices are differentiable: a vertex v on f = 0 moves by
dv = -n df / |grad f| when f changes (MeshSDF's iso-surface gradient), which is one Newton
step from the vertex along its frozen gradient (``recon/surface_mesh.py``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import torch
import trimesh

from .differential import gradient

__all__ = ["project_to_zero_set", "project_along", "vertex_normals", "chord_gaps", "refine_creases", "facet_geometry",
           "CREASE_RATIO", "SLIVER_AREA", "NEWTON_STEPS"]

NEWTON_STEPS = 3  # projections onto f = 0 of a vertex interpolated on a cell's edge (float64)
# a chord off the surface by this share of its triangle's longest edge marks a crease: a smooth
# surface's chords leave it by e / 8R, 1.6 % of 1.26 mm on the demo's tightest radius (1 cm);
# a 90 degree crease's by about a quarter of the edge
CREASE_RATIO = 0.05
SLIVER_AREA = 1e-6  # of a cell's area: a triangle smaller is one of marching cubes' slivers (or degenerate)
_MAX_ROUNDS = 12  # of splitting crease triangles in four

SDFCallable = Callable[[torch.Tensor], torch.Tensor]


def project_to_zero_set(sdf: SDFCallable, points: torch.Tensor, steps: int = NEWTON_STEPS) -> torch.Tensor:
    """(N, 3) [m]: ``points`` moved onto f = 0 by ``steps`` Newton steps along grad f, in their
    dtype (float64 for a clean surface of an analytic SDF), no graph."""
    p = torch.as_tensor(points)
    for _ in range(steps):
        g = gradient(sdf, p)
        with torch.no_grad():
            p = p - (sdf(p) / (g * g).sum(1).clamp(min=1e-24))[:, None] * g
    return p


def vertex_normals(sdf: SDFCallable, vertices: torch.Tensor) -> torch.Tensor:
    """(N, 3) outward unit normals grad f / |grad f| at ``vertices`` (N, 3) [m], no graph."""
    return torch.nn.functional.normalize(gradient(sdf, vertices), dim=1)


def chord_gaps(sdf: SDFCallable, vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """(F,) [m] the largest |f| at the midpoints of each triangle's edges: how far its chords
    lie off the surface (e^2 / 8R on a sphere of radius R, half the edge across a 90 degree
    crease), no graph."""
    triangles = vertices[faces]  # (F, 3, 3)
    midpoints = 0.5 * (triangles + triangles.roll(1, dims=1))
    with torch.no_grad():
        return sdf(midpoints.reshape(-1, 3)).reshape(-1, 3).abs().max(1).values


def refine_creases(sdf: SDFCallable, vertices: torch.Tensor, faces: torch.Tensor, *, min_edge_m: float,
                   ratio: float = CREASE_RATIO) -> tuple[torch.Tensor, torch.Tensor]:
    """Vertices (N', 3) float64 on f = 0 and faces (F', 3) int64 of a mesh whose triangles with
    a chord off the surface by more than ``ratio`` of their longest edge (:func:`chord_gaps`:
    those across a crease; a smooth surface's sagitta is the height correction's) are split
    in four until their longest edge is within ``min_edge_m`` [m], their new vertices moved
    onto the surface along their edge's mean normal (the module docstring). A split
    triangle's neighbour keeps its edge whole: a crack of the chord's gap along that edge,
    which the refinement itself makes small."""
    vertices = torch.as_tensor(vertices, dtype=torch.float64)
    faces = torch.as_tensor(faces, dtype=torch.int64)
    normals = vertex_normals(sdf, vertices)
    for _ in range(_MAX_ROUNDS):
        triangles = vertices[faces]
        longest = (triangles - triangles.roll(1, dims=1)).norm(dim=2).max(1).values
        split = ((chord_gaps(sdf, vertices, faces) > ratio * longest) & (longest > min_edge_m)).nonzero().squeeze(1)
        if not len(split):
            break
        new_vertices, new_faces, attributes = trimesh.remesh.subdivide(
            vertices.numpy(), faces.numpy(), face_index=split.numpy(), vertex_attributes={"normal": normals.numpy()})
        fresh = torch.arange(len(vertices), len(new_vertices))
        vertices = torch.as_tensor(new_vertices, dtype=torch.float64)
        mean_normals = torch.nn.functional.normalize(torch.as_tensor(attributes["normal"][fresh.numpy()]), dim=1)
        vertices[fresh] = project_along(sdf, vertices[fresh], mean_normals)
        normals = torch.cat([normals, vertex_normals(sdf, vertices[fresh])])
        faces = torch.as_tensor(np.ascontiguousarray(new_faces), dtype=torch.int64)
    return vertices, faces


def project_along(sdf: SDFCallable, points: torch.Tensor, directions: torch.Tensor,
                  steps: int = NEWTON_STEPS) -> torch.Tensor:
    """(N, 3) [m]: ``points`` moved along unit ``directions`` (N, 3) onto f = 0 by Newton steps
    on t -> f(p + t d), no graph. An edge's midpoint moved along its ends' mean normal lands on
    the surface above it, on a crease where the edge crosses one (moved along its own
    gradient it would land on the nearer face, and the edge's halves would cross the crease
    again); where d is tangent to the surface it falls back on :func:`project_to_zero_set`."""
    p = torch.as_tensor(points)
    for _ in range(steps):
        g = gradient(sdf, p)
        with torch.no_grad():
            slope = (g * directions).sum(1)
            along = slope.abs() > 0.1 * g.norm(dim=1)
            step = torch.where(along[:, None], (sdf(p) / torch.where(along, slope, 1.0))[:, None] * directions,
                               (sdf(p) / (g * g).sum(1).clamp(min=1e-24))[:, None] * g)
            p = p - step
    return p


def facet_geometry(vertices: torch.Tensor, faces: torch.Tensor, normals: torch.Tensor
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The flat facets of a mesh on a curved surface: centroids (F, 3) [m], unit face normals
    (F, 3), areas (F,) [m^2] and corners (F, 3, 3) [m] relative to the centroids, each
    triangle moved out along its normal by the surface's mean height over it (the module
    docstring), from vertices (N, 3) [m], faces (F, 3) and the surface's unit normals (N, 3)
    at the vertices. Differentiable in ``vertices`` (not in ``normals``), with finite
    gradients everywhere. Degenerate triangles have area about 0 and a zero normal."""
    triangles = vertices[faces]  # (F, 3, 3)
    cross = torch.linalg.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    tiny = torch.finfo(cross.dtype).tiny
    double_area = (cross * cross).sum(1).clamp(min=tiny).sqrt()  # no 0/0 in the gradient of a degenerate one
    face_normals = cross / double_area[:, None]
    n = normals[faces].to(triangles).detach()
    height = ((n.roll(-1, dims=1) - n) * (triangles.roll(-1, dims=1) - triangles)).sum((1, 2)) / 24
    centroids = triangles.mean(1) + height[:, None] * face_normals
    corners = triangles - triangles.mean(1, keepdim=True)
    return centroids, face_normals, 0.5 * double_area, corners
