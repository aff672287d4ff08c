"""MeshSDF against an exhaustive reference (every triangle) and trimesh's containment."""

import numpy as np
import pytest
import torch
import trimesh

from rfsdf import geometry as geo
from rfsdf.geometry.mesh_sdf import _closest_on_triangles

DIST_TOL = 1e-9  # float64 arithmetic, same formula: only rounding differs


def _brute_force_distance(mesh, points):
    tri = mesh.triangles
    out = np.empty(len(points))
    for i, p in enumerate(points):
        q, _ = _closest_on_triangles(np.repeat(p[None], len(tri), 0), tri[:, 0], tri[:, 1], tri[:, 2])
        out[i] = np.sqrt(((q - p) ** 2).sum(1)).min()
    return out


def test_closest_point_on_triangle_regions():
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    cases = {  # point -> expected closest point
        (0.2, 0.2, 1.0): (0.2, 0.2, 0.0), (-1.0, -1.0, 0.0): (0.0, 0.0, 0.0), (2.0, -0.5, 0.0): (1.0, 0.0, 0.0),
        (0.5, -1.0, 0.0): (0.5, 0.0, 0.0), (1.0, 1.0, 0.0): (0.5, 0.5, 0.0), (-1.0, 0.5, 3.0): (0.0, 0.5, 0.0),
    }
    for p, expected in cases.items():
        q, _ = _closest_on_triangles(np.array([p]), a, b, c)
        np.testing.assert_allclose(q[0], expected, atol=1e-12)


def test_mesh_sdf_of_icosphere_is_close_to_sphere():
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    sdf = geo.MeshSDF(mesh)
    pts = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.2, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(sdf(pts), torch.tensor([-0.5, 0.5, -0.3], dtype=torch.float64), atol=2e-3, rtol=0)


def test_mesh_sdf_matches_references_on_spot(spot_path):
    sdf = geo.MeshSDF(spot_path)
    assert sdf.mesh.is_watertight
    rng = np.random.default_rng(0)
    surface, _ = trimesh.sample.sample_surface(sdf.mesh, 150, seed=1)
    pts = np.concatenate([surface + rng.normal(scale=0.01, size=surface.shape), rng.uniform(-1, 1, (50, 3))])
    values = sdf(torch.as_tensor(pts)).numpy()
    np.testing.assert_allclose(np.abs(values), _brute_force_distance(sdf.mesh, pts), atol=DIST_TOL)
    np.testing.assert_array_equal(values < 0, sdf.mesh.contains(pts))


def test_mesh_sdf_gradient_is_unit(spot_path):
    sdf = geo.MeshSDF(spot_path)
    pts = torch.rand(200, 3, dtype=torch.float64) - 0.5
    assert geo.eikonal_residual(sdf, pts).max() < 1e-9


def test_open_mesh_is_rejected(tmp_path):
    mesh = trimesh.creation.box()
    mesh.update_faces(np.arange(len(mesh.faces) - 1))
    path = tmp_path / "open.ply"
    mesh.export(path)
    with pytest.raises(ValueError, match="open.ply.*not watertight"):
        geo.MeshSDF(path)
