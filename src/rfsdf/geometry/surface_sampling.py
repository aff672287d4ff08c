"""Points on a triangle mesh for quadrature: area-uniform random, or stratified.

The simulator's data are a sum over surface samples, a quadrature of the scattering
integral. Independent random points (``trimesh.sample.sample_surface``) leave a Monte
Carlo error that every sampling draws anew, with energy ~ area x spacing^2: on faces
turned away from the radar, where the true return is small, it dominates (study
``roughness``: +15 dB over a smooth plate's converged return at lambda / 3). Stratified
points put exactly one sample in each of N strata of equal area: the faces are ordered
along a Morton (Z-order) curve through their centroids, so that consecutive area is
spatially compact, and sample i falls at cumulative area (i + u_i) A / N, u_i uniform.
Each sample then stands for its own compact patch, as a jittered grid does on a plane.
"""

from __future__ import annotations

import numpy as np
import trimesh

__all__ = ["morton_order", "stratified_surface_points"]

_MORTON_BITS = 10  # per axis: 1024^3 cells over the mesh's bounding cube
_STRATA_PER_EDGE = 2.0  # longest triangle edge, in stratum sides sqrt(2 area / count)


def morton_order(points: np.ndarray) -> np.ndarray:
    """(N,) indices sorting ``points`` (N, 3) along a Morton (Z-order) curve of their bounding cube."""
    span = max(float(np.ptp(points, axis=0).max()), 1e-30)
    cells = ((points - points.min(0)) / span * (2**_MORTON_BITS - 1)).astype(np.uint64)
    code = np.zeros(len(points), np.uint64)
    for bit in range(_MORTON_BITS):
        for axis in range(3):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


def stratified_surface_points(mesh: trimesh.Trimesh, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points on ``mesh``, one in each of ``count`` strata of equal area (module
    docstring): (count, 3) points and (count,) face indices, as trimesh's sampler returns."""
    rng = np.random.default_rng(seed)
    triangles, parent = _fine_triangles(mesh, count)
    order = morton_order(triangles.mean(1))
    cumulative = np.cumsum(trimesh.triangles.area(triangles)[order])
    targets = (np.arange(count) + rng.random(count)) * (cumulative[-1] / count)
    faces = order[np.minimum(np.searchsorted(cumulative, targets), len(order) - 1)]
    a, b = rng.random(count), rng.random(count)
    outside = a + b > 1  # fold the unit square onto the triangle: uniform barycentric coordinates
    a[outside], b[outside] = 1 - a[outside], 1 - b[outside]
    corners = triangles[faces]
    points = corners[:, 0] + a[:, None] * (corners[:, 1] - corners[:, 0]) + b[:, None] * (corners[:, 2] - corners[:, 0])
    return points, parent[faces]


def _fine_triangles(mesh: trimesh.Trimesh, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's triangles (F', 3, 3), split until none has an edge longer than
    ``_STRATA_PER_EDGE`` strata, and the index (F',) of the face each came from: within one
    triangle a point is uniform, so a face much larger than a stratum (a wall of two
    triangles from a ray tracer's scene) would make the samples on it independent again."""
    edge = _STRATA_PER_EDGE * np.sqrt(2 * mesh.area / count)
    if mesh.edges_unique_length.max() <= edge:
        return mesh.triangles, np.arange(len(mesh.faces))
    vertices, faces, parent = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge,
                                                               max_iter=16, return_index=True)
    return vertices[faces], parent
