"""Analytic SDFs against closed forms: Eikonal property, zero sets, CSG, transforms, tracing."""

import math

import numpy as np
import pytest
import torch

from rfsdf import geometry as geo

EXACT = {
    "sphere": geo.Sphere(0.3, (0.1, -0.2, 0.05)),
    "box": geo.Box((0.2, 0.3, 0.1), (0.0, 0.1, 0.0)),
    "halfspace": geo.HalfSpace((1.0, 2.0, 2.0), 0.1),
    "cylinder": geo.Cylinder(0.2, (1.0, 1.0, 0.0), (0.0, 0.1, 0.0)),
    "capped_cylinder": geo.CappedCylinder(0.2, 0.5, (0.0, 1.0, 1.0), (0.1, 0.0, 0.0)),
    "torus": geo.Torus(0.4, 0.1, (0.0, 0.0, 1.0)),
    "capsule": geo.Capsule((-0.2, 0.0, 0.0), (0.3, 0.1, 0.0), 0.15),
    "rotated_translated_box": geo.Box((0.1, 0.2, 0.3)).rotate((1, 1, 0), 0.7).translate((0.1, 0, 0)),
    "scaled_torus": geo.Torus(0.4, 0.1).scale(0.5),
}
EIKONAL_TOL = 1e-6


@pytest.mark.parametrize("name", EXACT)
def test_exact_primitives_have_unit_gradient(name, rng):
    sdf = EXACT[name]
    points = (torch.rand(4000, 3, generator=rng, dtype=torch.float64) - 0.5) * 2
    residual = geo.eikonal_residual(sdf, points)
    # Medial-axis points (where the gradient jumps) have measure zero; allow a few.
    assert (residual < EIKONAL_TOL).float().mean() > 0.995
    assert sdf.exact


def test_sphere_matches_closed_form(rng):
    points = torch.randn(100, 3, generator=rng, dtype=torch.float64)
    expected = torch.linalg.norm(points - torch.tensor([0.1, -0.2, 0.05], dtype=torch.float64), dim=1) - 0.3
    torch.testing.assert_close(EXACT["sphere"](points), expected)


def test_box_distance_at_hand_computed_points():
    box = geo.Box((1.0, 2.0, 3.0))
    pts = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 3.0, 0.0], [0.5, 0.0, 0.0], [2.0, 3.0, 4.0]])
    torch.testing.assert_close(box(pts), torch.tensor([-1.0, 1.0, math.sqrt(2), -0.5, math.sqrt(3)]))


def test_halfspace_normalises_its_normal():
    hs = geo.HalfSpace((0.0, 0.0, 2.0), 1.0)
    torch.testing.assert_close(hs(torch.tensor([[5.0, 5.0, 3.0]])), torch.tensor([2.0]))


def test_torus_and_capsule_zero_sets():
    torus = geo.Torus(0.4, 0.1)
    on_torus = torch.tensor([[0.5, 0.0, 0.0], [0.0, 0.3, 0.0], [0.4, 0.0, 0.1]])
    torch.testing.assert_close(torus(on_torus), torch.zeros(3), atol=1e-7, rtol=0)
    capsule = geo.Capsule((0, 0, 0), (1, 0, 0), 0.2)
    on_capsule = torch.tensor([[0.5, 0.2, 0.0], [-0.2, 0.0, 0.0], [1.0, 0.0, 0.2]])
    torch.testing.assert_close(capsule(on_capsule), torch.zeros(3), atol=1e-7, rtol=0)


def test_csg_zero_sets_and_operators():
    a, b = geo.Sphere(1.0, (-0.5, 0, 0)), geo.Sphere(1.0, (0.5, 0, 0))
    pts = torch.tensor([[-1.5, 0.0, 0.0], [1.5, 0.0, 0.0], [0.5, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    union, inter, diff = a | b, a & b, a - b
    torch.testing.assert_close(union(pts)[:2], torch.zeros(2))  # outer poles on the union surface
    torch.testing.assert_close(inter(pts)[2:4], torch.zeros(2))  # inner poles bound the lens
    assert diff(torch.tensor([[-1.0, 0.0, 0.0]])) < 0 < diff(torch.tensor([[0.0, 0.0, 0.0]]))
    torch.testing.assert_close((~a)(pts), -a(pts))
    assert (~a).exact and not union.exact and not inter.exact


def test_smooth_union_blends_only_near_the_seam():
    a, b = geo.Sphere(1.0, (-0.9, 0, 0)), geo.Sphere(1.0, (0.9, 0, 0))
    smooth = geo.smooth_union(a, b, blend_m=0.2)
    far = torch.tensor([[-2.5, 0.0, 0.0]])
    torch.testing.assert_close(smooth(far), (a | b)(far))
    seam = torch.tensor([[0.0, 0.5, 0.0]])
    assert smooth(seam) < (a | b)(seam)  # filled in between the spheres
    with pytest.raises(ValueError):
        geo.smooth_union(a, b, blend_m=0.0)


def test_transforms_match_moved_closed_forms(rng):
    pts = torch.randn(50, 3, generator=rng, dtype=torch.float64)
    torch.testing.assert_close(geo.Sphere(0.3).translate((1, 2, 3))(pts), geo.Sphere(0.3, (1, 2, 3))(pts))
    torch.testing.assert_close(geo.Sphere(0.3).scale(2.0)(pts), geo.Sphere(0.6)(pts))
    # Rotating the z-axis cylinder by 90 deg about x gives the y-axis cylinder.
    rotated = geo.Cylinder(0.2, (0, 0, 1)).rotate((1, 0, 0), math.pi / 2)
    torch.testing.assert_close(rotated(pts), geo.Cylinder(0.2, (0, 1, 0))(pts))


@pytest.mark.parametrize("bad", [lambda: geo.Sphere(-1.0), lambda: geo.Box((1, 0, 1)), lambda: geo.Torus(0.1, 0.2),
                                 lambda: geo.HalfSpace((0, 0, 0)), lambda: geo.Sphere(1.0, (0, 0))])
def test_bad_parameters_raise(bad):
    with pytest.raises(ValueError):
        bad()


def test_points_must_be_n_by_3():
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        geo.Sphere(1.0)(torch.zeros(5, 2))


def test_normals_of_sphere_are_radial(rng):
    pts = torch.randn(100, 3, generator=rng, dtype=torch.float64)
    torch.testing.assert_close(geo.normals(geo.Sphere(1.0), pts), pts / pts.norm(dim=1, keepdim=True))


def test_curvature_is_the_sum_of_the_principal_curvatures():
    """div(n) of the level set through each point: 2/r on a sphere, 1/rho on a cylinder, 0 on
    a plane, 1/a + cos(phi)/(R + a cos(phi)) on a torus (outer and inner equator)."""
    pts = torch.tensor([[0.3, 0.1, -0.2], [0.05, 0.4, 0.2], [-0.5, 0.0, 0.1]], dtype=torch.float64)
    _, sphere = geo.gradient_and_curvature(geo.Sphere(0.2, (0.0, 0.0, 0.1)), pts)
    torch.testing.assert_close(sphere, 2 / (pts - torch.tensor([0.0, 0.0, 0.1], dtype=torch.float64)).norm(dim=1))
    _, cylinder = geo.gradient_and_curvature(geo.Cylinder(0.2, (0.0, 0.0, 1.0)), pts)
    torch.testing.assert_close(cylinder, 1 / pts[:, :2].norm(dim=1))
    grad, plane = geo.gradient_and_curvature(geo.HalfSpace((1.0, 2.0, 2.0), 0.1), pts)
    assert plane.abs().max() < 1e-12 and torch.allclose(grad.norm(dim=1), torch.ones(3, dtype=torch.float64))
    equator = torch.tensor([[0.5, 0.0, 0.0], [0.0, 0.3, 0.0]], dtype=torch.float64)
    _, torus = geo.gradient_and_curvature(geo.Torus(0.4, 0.1), equator)
    torch.testing.assert_close(torus, torch.tensor([10 + 1 / 0.5, 10 - 1 / 0.3], dtype=torch.float64))


def test_sphere_trace_hits_analytic_intersection(rng):
    sphere = geo.Sphere(0.5, (0.0, 0.0, 2.0))
    origins = torch.zeros(200, 3, dtype=torch.float64)
    dirs = torch.nn.functional.normalize(torch.randn(200, 3, generator=rng, dtype=torch.float64) * 0.1
                                         + torch.tensor([0, 0, 1.0], dtype=torch.float64), dim=1)
    result = geo.sphere_trace(sphere, origins, dirs, eps=1e-9, max_steps=500)
    # Closed form: |t d - c|^2 = r^2 -> t = d.c - sqrt((d.c)^2 - |c|^2 + r^2).
    dc = dirs @ torch.tensor([0, 0, 2.0], dtype=torch.float64)
    disc = dc**2 - 4.0 + 0.25
    expected_hit = disc > 0
    assert torch.equal(result.hit, expected_hit)
    t_expected = dc[expected_hit] - disc[expected_hit].sqrt()
    # |f| < eps bounds the distance to the surface; along a grazing ray t may err by eps / cos.
    assert sphere(result.points[expected_hit]).abs().max() < 1e-9
    torch.testing.assert_close(result.t[expected_hit], t_expected, atol=1e-6, rtol=0)
    torch.testing.assert_close(result.normals[expected_hit], geo.normals(sphere, result.points[expected_hit]))


def test_sphere_trace_through_centre_converges_in_one_step():
    sphere = geo.Sphere(0.5, (0.0, 0.0, 2.0))
    result = geo.sphere_trace(sphere, torch.zeros(1, 3), torch.tensor([[0.0, 0.0, 1.0]]), record_history=True)
    assert result.hit.item() and result.steps.item() == 1
    assert result.t.item() == pytest.approx(1.5)
    assert result.history.shape[0] == 2


def test_sphere_trace_reports_misses_and_inside_starts():
    sphere = geo.Sphere(0.5)
    origins = torch.tensor([[0.0, 0.0, -2.0], [0.0, 0.0, 0.0]])
    dirs = torch.tensor([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    result = geo.sphere_trace(sphere, origins, dirs, t_max=5.0)
    assert not result.hit.any()
    assert result.started_inside.tolist() == [False, True]
    assert result.t[0] > 5.0


def test_sphere_trace_stops_each_ray_at_its_own_limit():
    """Two rays at a box face 1 m off: the one whose own limit is 0.8 m misses (its step to
    the face passes its limit); the one allowed 3 m hits at t = 1."""
    origins = torch.tensor([[0.0, 0.0, -1.5], [0.0, 0.1, -1.5]], dtype=torch.float64)
    dirs = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    box = geo.Box([0.5, 0.5, 0.5])
    result = geo.sphere_trace(box, origins, dirs, t_max=torch.tensor([0.8, 3.0], dtype=torch.float64))
    assert result.hit.tolist() == [False, True] and float(result.t[1]) == pytest.approx(1.0)
    assert float(result.t[0]) > 0.8


def test_occupancy_is_half_on_surface_and_saturates():
    sphere = geo.Sphere(1.0)
    pts = torch.tensor([[1.0, 0, 0], [0, 0, 0], [3.0, 0, 0]])
    occ = geo.occupancy(sphere, pts, alpha=100.0)
    assert occ[0].item() == pytest.approx(0.5)
    assert occ[1].item() > 1 - 1e-12 and occ[2].item() < 1e-12


def test_grid_points_are_voxel_centres():
    grid = geo.Grid((0, 0, 0), (1, 2, 3), (2, 4, 6))
    pts = grid.points()
    assert pts.shape == (48, 3)
    torch.testing.assert_close(pts[0], torch.tensor([0.25, 0.25, 0.25]))
    torch.testing.assert_close(pts[-1], torch.tensor([0.75, 1.75, 2.75]))
    torch.testing.assert_close(grid.points(start=10, stop=20), pts[10:20])
    np.testing.assert_allclose(grid.voxel_m, [0.5, 0.5, 0.5])


def test_trilinear_is_exact_for_linear_fields_and_clamps_at_the_box(rng):
    grid = geo.Grid((0, 0, 0), (1, 2, 3), (4, 5, 6))
    centres = grid.points(dtype=torch.float64)
    slopes = torch.tensor([[0.3, -1.2, 2.0], [1.0, 0.5, -0.7]], dtype=torch.float64)  # two linear fields
    values = (centres @ slopes.T + torch.tensor([0.1, -2.0], dtype=torch.float64)).T.reshape(2, *grid.shape)
    lookup = geo.trilinear(values, grid)
    axes = grid.axes()
    first, last = (torch.tensor([a[i] for a in axes]) for i in (0, -1))
    # points between the outer voxel centres
    inner = first + (last - first) * torch.rand(200, 3, dtype=torch.float64, generator=rng)
    expected = inner @ slopes.T + torch.tensor([0.1, -2.0], dtype=torch.float64)
    torch.testing.assert_close(lookup(inner), expected)
    torch.testing.assert_close(geo.trilinear(values[1], grid)(inner), expected[:, 1])  # one channel alone
    beyond = torch.tensor([[-5.0, 1.0, 1.5], [0.01, 1.0, 1.5]], dtype=torch.float64)  # both read the x = first face
    clamped = lookup(beyond)
    torch.testing.assert_close(clamped[0], clamped[1])
    assert lookup(inner.float()).dtype == torch.float32


def test_a_cuboid_mesh_is_recognised_with_its_frame_and_any_other_mesh_is_not():
    import trimesh

    from rfsdf.geometry.cuboids import cuboid_of

    turn = trimesh.transformations.rotation_matrix(0.4, [1, 2, 3])
    box = trimesh.creation.box(extents=(4.0, 3.0, 2.5)).subdivide()  # faces split: still the box
    box.apply_transform(turn)
    box.apply_translation((1.0, -2.0, 1.25))
    found = cuboid_of(box)
    np.testing.assert_allclose(found.center_m, [1.0, -2.0, 1.25], atol=1e-12)
    np.testing.assert_allclose(found.half_extents_m, [2.0, 1.5, 1.25], atol=1e-12)
    np.testing.assert_allclose(np.abs(found.axes @ turn[:3, :3]), np.eye(3), atol=1e-12)  # the box's own axes
    assert np.linalg.det(found.axes) == pytest.approx(1.0)
    quad = trimesh.Trimesh([[-1, -0.5, 2], [1, -0.5, 2], [1, 0.5, 2], [-1, 0.5, 2]], [[0, 1, 2], [0, 2, 3]])
    wall = cuboid_of(quad)
    assert wall.flat and sorted(wall.half_extents_m[:2]) == [0.5, 1.0] and wall.center_m.tolist() == [0, 0, 2]
    np.testing.assert_allclose(np.abs(wall.axes[2]), [0, 0, 1])
    ell = trimesh.Trimesh([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]],
                          [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]])
    open_box = trimesh.creation.box()
    open_box.update_faces(np.arange(10))  # one face gone
    two_quads = trimesh.util.concatenate([quad, quad.copy().apply_translation((0, 0, 1))])
    for other in (trimesh.creation.icosphere(), trimesh.creation.cylinder(1.0, 2.0), ell, open_box, two_quads):
        assert cuboid_of(other) is None
