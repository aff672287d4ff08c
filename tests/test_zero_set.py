"""Facets of an SDF's zero set: vertices on it, creases refined, the chord's sagitta restored,
and a quadrature two meshes of the same scene agree on (the converged forward model)."""

import math

import numpy as np
import pytest
import torch
import trimesh

from rfsdf.geometry import (
    Box, Sphere, chord_gaps, facet_geometry, project_to_zero_set, refine_creases, vertex_normals,
)
from rfsdf.mesh import extract_mesh_near_surface, mesh_blocks
from rfsdf.radar import simulate
from rfsdf.scene import Scene
from rfsdf.scene_spec import SceneSpec
from rfsdf.studies.ball_fit import small_radar

RADIUS = 0.02


def _sphere_mesh(subdivisions: int) -> tuple[torch.Tensor, torch.Tensor]:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=RADIUS)  # vertices on the sphere
    return torch.as_tensor(mesh.vertices), torch.as_tensor(mesh.faces, dtype=torch.int64)


def test_newton_steps_put_points_on_the_zero_set():
    points = torch.randn(500, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * 0.03
    on = project_to_zero_set(Sphere(RADIUS), points)
    assert (on.norm(dim=1) - RADIUS).abs().max() < 1e-12
    box = Box((0.02, 0.01, 0.03))
    assert box(project_to_zero_set(box, points)).abs().max() < 1e-12


def test_facets_are_moved_to_the_spheres_mean_height_over_them():
    """Chords of a sphere lie inside it by e^2 / 8R on average (about 70 um for 3 mm edges on a
    2 cm sphere); the height correction moves each facet out by that, so that the sphere lies
    as much above it as below (its centroid stays e^2 / 24R inside, where the sphere bulges
    most), and leaves the area of the chords unchanged."""
    vertices, faces = _sphere_mesh(3)
    normals = torch.nn.functional.normalize(vertices, dim=1)
    centroids, face_normals, area, corners = facet_geometry(vertices, faces, normals)
    weights = torch.distributions.Dirichlet(torch.ones(3, dtype=torch.float64)).sample((64,))  # points in a triangle

    def mean_gap(centres, triangle_corners):  # R - |x| over each triangle, (F,)
        points = centres[:, None] + torch.einsum("sc,fcd->fsd", weights, triangle_corners)
        return (RADIUS - points.norm(dim=2)).mean(1)

    chords = vertices[faces]
    chord_gap, corrected_gap = mean_gap(chords.mean(1), chords - chords.mean(1, keepdim=True)), mean_gap(centroids, corners)
    assert chord_gap.mean() > 5e-5
    assert corrected_gap.abs().mean() < 0.1 * chord_gap.mean()
    assert (face_normals * normals[faces].mean(1)).sum(1).min() > 0.99  # outward
    assert float(area.sum()) == pytest.approx(4 * math.pi * RADIUS**2, rel=0.01)
    torch.testing.assert_close(corners.mean(1), torch.zeros_like(centroids), atol=1e-15, rtol=0)


def test_facet_geometry_is_differentiable_in_the_vertices():
    vertices, faces = _sphere_mesh(1)
    normals = torch.nn.functional.normalize(vertices, dim=1)
    moved = vertices.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda v: facet_geometry(v, faces, normals)[0].sum(0), (moved,))
    assert torch.autograd.gradcheck(lambda v: facet_geometry(v, faces, normals)[2], (moved,))


def test_creases_are_refined_and_the_vertices_stay_on_the_surface():
    """A box meshed on 3 mm cells: its chords across the edges cut the corners by up to 1 mm;
    refined, every triangle whose chords leave the surface by more than 5 % of its size is
    within 0.4 mm, and the faces' own triangles are left whole."""
    box = Box((0.02, 0.015, 0.01))
    mesh = extract_mesh_near_surface(box, (-0.03,) * 3, (0.03,) * 3, 0.003)
    vertices = project_to_zero_set(box, torch.as_tensor(mesh.vertices))
    faces = torch.as_tensor(mesh.faces, dtype=torch.int64)
    assert chord_gaps(box, vertices, faces).max() > 5e-4
    refined, refined_faces = refine_creases(box, vertices, faces, min_edge_m=4e-4)
    assert box(refined).abs().max() < 1e-12
    triangles = refined[refined_faces]
    longest = (triangles - triangles.roll(1, dims=1)).norm(dim=2).max(1).values
    assert longest[chord_gaps(box, refined, refined_faces) > 0.05 * longest].max() <= 4e-4
    assert longest.max() > 2e-3  # the faces' triangles kept whole
    _, _, area, _ = facet_geometry(refined, refined_faces, vertex_normals(box, refined))
    assert float(area.sum()) == pytest.approx(2 * (0.04 * 0.03 + 0.04 * 0.02 + 0.03 * 0.02), rel=0.01)


def test_blocks_on_one_lattice_keep_a_face_that_lies_on_their_boundary():
    """A box's faces exactly on planes that blocks share: both blocks evaluate the same points,
    so each face is meshed, all but the marching-cubes chamfers along its edges (20 x 20 of its
    25 x 25 mm on 2.5 mm cells; computed per block, rounding lost most of a face)."""
    box = Box((0.0125, 0.0125, 0.0125))  # faces at +-12.5 mm, on the 2.5 mm lattice
    origins = np.stack(np.meshgrid(*[np.arange(-0.025, 0.025, 0.0125)] * 3, indexing="ij"), -1).reshape(-1, 3)
    mesh = mesh_blocks(lambda p: box(p.float()), origins, 0.0025, 5)
    for axis in range(3):
        for sign in (1, -1):
            flat = mesh.face_normals[:, axis] * sign > 0.99
            assert mesh.area_faces[flat].sum() == pytest.approx(0.02**2, rel=0.01)


def _block_and_ball() -> Scene:
    """A wooden block (creases) and a metal ball beside it."""
    objects = [{"name": "block", "material": "wood",
                "shape": {"type": "box", "half_extents_m": [0.03, 0.02, 0.015], "center_m": [-0.02, 0.0, 0.0]}},
               {"name": "ball", "material": "metal",
                "shape": {"type": "sphere", "radius_m": 0.015, "center_m": [0.03, 0.025, 0.0]}}]
    return Scene(SceneSpec.model_validate({"name": "block-and-ball", "objects": objects,
                                           "bounds": {"lower_m": [-0.06] * 3, "upper_m": [0.06] * 3}}))


@pytest.mark.parametrize("surface,agree", [("facets", True), ("points", False)])
def test_two_discretisations_of_a_scene_give_the_same_data(surface, agree):
    """The converged quadrature: a wooden block (creases) and a metal ball seen from six views,
    noise-free, simulated on facets of two meshes (another grid offset and another cell): the
    data agree per view to a correlation of 0.999 and within 1 % in amplitude. Points of two
    seeds (lambda/3, stratified) do not (0.78-0.93 on the demo scene)."""
    scene = _block_and_ball()
    radar = small_radar(snr_db=None, array_m=0.08, elements_per_edge=4, rings=((4, 0.0), (2, 0.6)))
    cells = (1.5e-3, 1.2e-3) if surface == "facets" else (None, None)
    first, second = (simulate(scene, radar, seed=seed, spacing_m=cell, surface=surface).data.flatten(1)
                     for seed, cell in zip((0, 1), cells))
    correlation = (first.conj() * second).sum(1).abs() / (first.norm(dim=1) * second.norm(dim=1))
    amplitude = (first.norm(dim=1) / second.norm(dim=1) - 1).abs()
    assert (bool(correlation.min() > 0.999) and bool(amplitude.max() < 0.01)) == agree, (correlation, amplitude)
