"""MeshSDF against trimesh's independent closest-point and containment queries."""

import pickle

import numpy as np
import pytest
import torch
import trimesh

from rfsdf import geometry as geo
from rfsdf.geometry.mesh_sdf import _EAB, _ECA, _FACE, _VB, _features

DIST_TOL = 1e-9  # float64 arithmetic on both sides: only rounding differs


def _brute_force_distance(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Distance to every triangle (trimesh's closest point on a triangle), the least per point."""
    triangles = np.tile(mesh.triangles, (len(points), 1, 1))
    repeated = np.repeat(points, len(mesh.triangles), axis=0)
    closest = trimesh.triangles.closest_point(triangles, repeated)
    return np.linalg.norm(closest - repeated, axis=1).reshape(len(points), -1).min(1)


def _check_against_trimesh(mesh: trimesh.Trimesh, points: np.ndarray) -> None:
    values = geo.MeshSDF(mesh)(torch.as_tensor(points)).numpy()
    np.testing.assert_allclose(np.abs(values), _brute_force_distance(mesh, points), atol=DIST_TOL)
    np.testing.assert_array_equal(values < 0, mesh.contains(points))


def _dented_box() -> trimesh.Trimesh:
    """A box with a pit pushed into the middle of every face: concave vertices and edges,
    where only the pseudo-normal of the right feature gives the right sign."""
    mesh = trimesh.creation.box(extents=(1.0, 0.8, 0.6)).subdivide()
    vertices = mesh.vertices.copy()
    centres = np.isclose(np.abs(vertices), [0.5, 0.4, 0.3]).sum(1) == 1  # face centres only
    vertices[centres] *= 0.6
    return trimesh.Trimesh(vertices, mesh.faces)


def test_closest_feature_from_barycentric_coordinates():
    triangle = np.array([[[0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0]]])
    for point, feature in (((0.2, 0.2, 0.0), _FACE), ((1.0, 0.0, 0.0), _VB), ((0.5, 0.0, 0.0), _EAB),
                           ((0.0, 0.5, 0.0), _ECA)):
        assert _features(triangle, np.array([point]))[0] == feature, point


def test_mesh_sdf_matches_trimesh_on_a_dented_box():
    mesh = _dented_box()
    assert mesh.is_watertight and mesh.volume > 0
    rng = np.random.default_rng(0)
    surface, _ = trimesh.sample.sample_surface(mesh, 300, seed=1)
    near_features = np.concatenate([mesh.vertices, mesh.vertices[mesh.edges_unique].mean(1)])
    points = np.concatenate([surface + rng.normal(scale=0.02, size=surface.shape),
                             near_features + rng.normal(scale=0.01, size=near_features.shape),
                             rng.uniform(-1, 1, (100, 3))])
    _check_against_trimesh(mesh, points)


def test_mesh_sdf_of_icosphere_is_close_to_sphere():
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    sdf = geo.MeshSDF(mesh)
    pts = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.2, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(sdf(pts), torch.tensor([-0.5, 0.5, -0.3], dtype=torch.float64), atol=2e-3, rtol=0)


def test_mesh_sdf_matches_trimesh_on_spot(spot_path):
    mesh = geo.MeshSDF(spot_path).mesh
    rng = np.random.default_rng(0)
    surface, _ = trimesh.sample.sample_surface(mesh, 150, seed=1)
    _check_against_trimesh(mesh, np.concatenate([surface + rng.normal(scale=0.01, size=surface.shape),
                                                 rng.uniform(-1, 1, (50, 3))]))


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


def test_mesh_sdf_survives_pickling():
    """Worker processes get scenes by pickle; the C++ tree is rebuilt on the other side."""
    sdf = geo.MeshSDF(_dented_box())
    points = torch.rand(100, 3, dtype=torch.float64) - 0.5
    torch.testing.assert_close(pickle.loads(pickle.dumps(sdf))(points), sdf(points), rtol=0, atol=0)
