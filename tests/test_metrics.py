import numpy as np
import pytest
import trimesh

from rfsdf.geometry import Sphere
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import compare_meshes, volumetric_iou


def test_identical_meshes_score_perfectly():
    mesh = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    m = compare_meshes(mesh, mesh.copy(), samples=20_000)
    assert m.chamfer_l1_mm == 0.0 and m.hausdorff95_mm == 0.0
    assert m.fscore == pytest.approx(1.0)
    assert m.normal_consistency == pytest.approx(1.0)


def test_shifted_plane_matches_hand_computed_distances():
    # Two parallel 1 m squares 3 mm apart: every nearest distance is ~3 mm (edges aside).
    a = trimesh.creation.box(extents=(1.0, 1.0, 1e-6))
    b = a.copy().apply_translation((0, 0, 0.003))
    m = compare_meshes(a, b, threshold_m=0.005, samples=20_000)
    assert m.chamfer_l1_mm == pytest.approx(3.0, abs=0.3)
    assert m.fscore == pytest.approx(1.0)
    assert compare_meshes(a, b, threshold_m=0.002, samples=20_000).fscore < 0.05


def test_analytic_sphere_mesh_is_well_below_a_voxel():
    voxel = 0.2 / 64
    mesh = extract_mesh(Sphere(0.05), (-0.1,) * 3, (0.1,) * 3, 64)
    truth = trimesh.creation.icosphere(subdivisions=6, radius=0.05)
    assert compare_meshes(mesh, truth, samples=20_000).chamfer_l1_mm < 0.25 * voxel * 1e3


def test_iou_of_offset_spheres_matches_closed_form():
    r, d = 0.05, 0.05  # lens volume of two spheres of radius r, centres d apart
    lens = np.pi * (4 * r + d) * (2 * r - d) ** 2 / 12
    sphere = 4 / 3 * np.pi * r**3
    expected = lens / (2 * sphere - lens)
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=r)
    iou = volumetric_iou(mesh, lambda p: Sphere(r).translate((d, 0, 0))(p) < 0, (-0.06, -0.06, -0.06),
                         (0.11, 0.06, 0.06), samples=20_000)
    assert iou == pytest.approx(expected, abs=0.03)


def test_evaluate_mesh_against_a_scene_fills_in_the_iou_of_a_closed_mesh():
    from rfsdf.metrics import evaluate_mesh
    from rfsdf.scene import load_scene

    scene = load_scene("sphere")
    closed = extract_mesh(scene.sdf, scene.lower_m, scene.upper_m, 48)
    metrics = evaluate_mesh(closed, scene, samples=10_000)
    assert metrics.chamfer_l1_mm < 0.5 and metrics.iou > 0.97
    cap = trimesh.Trimesh(closed.vertices, closed.faces[closed.triangles_center[:, 2] > 0])  # open
    assert evaluate_mesh(cap, scene, samples=10_000).iou is None
