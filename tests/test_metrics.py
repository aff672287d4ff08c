import numpy as np
import pytest
import torch
import trimesh

from rfsdf.geometry import Sphere
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import compare_meshes, nearest, once_per_samples, to_surface, volumetric_iou


def test_identical_meshes_score_perfectly():
    mesh = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    m = compare_meshes(mesh, mesh.copy(), samples=20_000)
    assert m.chamfer_l1_mm == pytest.approx(0.0, abs=1e-9) and m.hausdorff95_mm == pytest.approx(0.0, abs=1e-9)
    assert m.fscore == pytest.approx(1.0)
    assert m.normal_consistency == pytest.approx(1.0)


def test_two_samplings_of_one_surface_score_zero_not_their_spacing():
    """Distances go to the other surface, not to its nearest sample: a sphere against itself
    sampled with another seed, 2,000 samples (4 mm apart), scores its facets' sag, where
    nearest samples stand about half their spacing apart."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.05)
    m = compare_meshes(sphere, sphere.copy(), samples=2_000, seed=1)
    assert m.chamfer_l1_mm < 1e-6
    on, _ = trimesh.sample.sample_surface(sphere, 2_000, seed=2)
    assert nearest(trimesh.sample.sample_surface(sphere, 2_000, seed=1)[0], on)[0].mean() > 1e-3  # the floor it removes


def test_distances_to_a_surface_match_the_sphere_in_closed_form():
    """to_surface against a fine icosphere: | |p| - r | within the facets' sag (a triangle's
    circumradius, edge / sqrt(3), deep in a sphere of radius r)."""
    r = 0.05
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=r)
    points = np.random.default_rng(0).normal(size=(500, 3)) * 0.04
    distance, faces = to_surface(points, sphere)
    sag = r - np.sqrt(r**2 - sphere.edges_unique_length.max() ** 2 / 3)
    np.testing.assert_allclose(distance, np.abs(np.linalg.norm(points, axis=1) - r), atol=sag)
    closest = sphere.triangles_center[faces]  # the triangle found faces the point
    assert (np.einsum("ij,ij->i", closest, points) > 0).all()


def test_a_mesh_moved_in_place_is_measured_where_it_is_now():
    """to_surface keeps each mesh's tree: moving the mesh's vertices must not reuse the old one."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    points = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    np.testing.assert_allclose(to_surface(points, sphere)[0], [0.05, 0.05], atol=1e-3)
    sphere.apply_translation((0.2, 0.0, 0.0))
    np.testing.assert_allclose(to_surface(points, sphere)[0], [0.15, 0.05], atol=1e-3)


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


def _two_ball_scene(tmp_path):
    from rfsdf.scene import load_scene

    path = tmp_path / "two.toml"
    path.write_text('name = "two"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
                    '[[objects]]\nname = "left"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02, center_m = [-0.05, 0, 0] }\n'
                    '[[objects]]\nname = "right"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02, center_m = [0.05, 0, 0] }\n')
    return load_scene(path)


def test_per_object_metrics_name_the_missed_object(tmp_path):
    from rfsdf.metrics import evaluate_scene

    scene = _two_ball_scene(tmp_path)
    only_left = extract_mesh(Sphere(0.02, (-0.05, 0.0, 0.0)), (-0.1,) * 3, (0.1,) * 3, 96)
    result = evaluate_scene(only_left, scene, samples=20_000)
    left, right = result.objects["left"], result.objects["right"]
    assert left.recall > 0.99 and left.precision > 0.99 and left.found and left.chamfer_l1_mm < 0.5
    assert abs(left.bias_mm) < 0.1 and right.bias_mm is None
    assert right.recall == 0.0 and not right.found and right.chamfer_l1_mm is None
    assert result.full.recall == pytest.approx(0.5, abs=0.02)  # half the true surface is missing
    assert result.as_dict()["objects"]["right"]["found"] is False
    grown = extract_mesh(Sphere(0.023, (-0.05, 0.0, 0.0)), (-0.1,) * 3, (0.1,) * 3, 96)
    assert evaluate_scene(grown, scene, samples=5_000).objects["left"].bias_mm == pytest.approx(3.0, abs=0.1)


def test_observed_fraction_of_a_sphere_seen_by_one_view_is_its_cap(tmp_path):
    """One single-element view on +z at 1 m: the cone is 0, so the observed surface is the cap
    whose normals lie within the tolerance of the direction to the radar; its area fraction
    is (1 - cos a) / 2 for a half-angle a (closed form, parallax neglected)."""
    import math

    import torch

    from rfsdf.metrics import evaluate_scene
    from rfsdf.radar import Acquisition
    from rfsdf.radar.coverage import observed_mask

    scene = _two_ball_scene(tmp_path)
    here = torch.tensor([[[0.0, 0.0, 1.0]]], dtype=torch.float64)
    acq = Acquisition(here, here.clone(), torch.tensor([79e9]), torch.tensor([[0.0, 0.0, -1.0]], dtype=torch.float64))
    tolerance = math.radians(20.0)
    seen = lambda p, n: observed_mask(p, n, acq, scene.sdf, tolerance_rad=tolerance)  # noqa: E731
    truth = trimesh.util.concatenate(scene.object_meshes())
    result = evaluate_scene(truth, scene, observed=seen, samples=40_000)
    assert result.observed_fraction == pytest.approx((1 - math.cos(tolerance)) / 2, rel=0.1)
    assert result.observed.chamfer_l1_mm < 0.5 and result.observed.recall > 0.99
    for ball in result.objects.values():  # each ball shows the radar the same cap
        assert ball.observed_fraction == pytest.approx((1 - math.cos(tolerance)) / 2, rel=0.15)
        assert ball.observed_recall > 0.99


def test_the_observed_mask_traces_only_the_samples_in_a_cone_and_equals_tracing_them_all(tmp_path):
    """Two balls on the x axis, three views of 4 cm arrays, one of them on the axis (the right
    ball shadows the left): the mask equals the slow one that traces a shadow ray for every
    sample and view, and the shadows change it."""
    from rfsdf.radar import Acquisition
    from rfsdf.radar.coverage import observed_mask

    scene = _two_ball_scene(tmp_path)
    centres = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.7, 0.0, 0.7]], dtype=torch.float64)
    offsets = torch.tensor([[0.0, 0.02, 0.02], [0.0, -0.02, -0.02]], dtype=torch.float64)
    acq = Acquisition(centres[:, None] + offsets, centres[:, None] - offsets, torch.tensor([79e9]), -centres)
    n = torch.nn.functional.normalize(torch.randn(4000, 3, generator=torch.Generator().manual_seed(0)), dim=1)
    p = torch.cat([n[:2000] * 0.02 + torch.tensor([-0.05, 0, 0]), n[2000:] * 0.02 + torch.tensor([0.05, 0, 0])])

    shadowed = _observed_by_every_element(p, n, acq, scene.sdf)
    assert torch.equal(observed_mask(p, n, acq, scene.sdf), shadowed)
    assert (_observed_by_every_element(p, n, acq, None) & ~shadowed)[:2000].sum() > 20  # the left ball's cap facing +x, behind the right one


def test_the_observed_mask_of_a_scan_measures_its_cone_on_the_hull_and_equals_every_element_s():
    """A scan's 5,445 elements (sar-77g: 1,089 frames of 1 Tx and 4 Rx) reduce to their hull's
    corners for the cone: the same mask as the angle to every element, on samples with
    normals in every direction in and around the scene's box."""
    from rfsdf.radar import load_radar
    from rfsdf.radar.coverage import _hull_corners, observed_mask

    acq = load_radar("sar-77g").acquisition()
    tx, rx = acq.view_elements(0)
    assert len(_hull_corners(torch.cat([tx, rx]))) < 12
    g = torch.Generator().manual_seed(1)
    n = torch.nn.functional.normalize(torch.randn(6000, 3, generator=g, dtype=torch.float64), dim=1)
    p = (torch.rand(6000, 3, generator=g, dtype=torch.float64) - 0.5) * torch.tensor([0.12, 0.12, 0.3])
    slow = _observed_by_every_element(p, n, acq, None)
    assert 100 < int(slow.sum()) < 5900
    assert torch.equal(observed_mask(p, n, acq, None), slow)


def _observed_by_every_element(p, n, acq, occluder):
    """The observed mask the slow, obvious way: every sample's cone from the angle to every
    element of each view, a shadow ray for every sample and view."""
    from rfsdf.radar.coverage import DEFAULT_TOLERANCE_RAD
    from rfsdf.radar.scattering import lit_mask

    seen = torch.zeros(len(p), dtype=torch.bool)
    for v in range(acq.num_views):
        tx_elements, rx_elements = acq.view_elements(v)
        tx, rx = tx_elements.mean(0), rx_elements.mean(0)
        to_centre = torch.nn.functional.normalize(0.5 * (tx + rx) - p, dim=1)
        elements = torch.cat([tx_elements, rx_elements])
        cone = torch.stack([torch.arccos((torch.nn.functional.normalize(e - p, dim=1) * to_centre).sum(1).clamp(-1, 1))
                            for e in elements]).max(dim=0).values
        tilt = torch.arccos((n * to_centre).sum(1).clamp(-1, 1))
        seen |= lit_mask(p, n, tx, rx, occluder=occluder) & (tilt <= cone + DEFAULT_TOLERANCE_RAD)
    return seen


def test_accuracy_and_completeness_are_split_by_whether_the_true_surface_is_observed(tmp_path):
    """The left ball is reconstructed exactly and observed; the right one 3 mm too large and
    not observed: the split puts ~0 mm (the meshing error) near the seen surface and ~3 mm near the unseen one."""
    from rfsdf.geometry import Union
    from rfsdf.metrics import evaluate_scene

    scene = _two_ball_scene(tmp_path)
    both = Union(Sphere(0.02, (-0.05, 0.0, 0.0)), Sphere(0.023, (0.05, 0.0, 0.0)))
    mesh = extract_mesh(both, (-0.1,) * 3, (0.1,) * 3, 128)
    result = evaluate_scene(mesh, scene, observed=lambda p, n: p[:, 0] < 0, samples=20_000)
    assert result.accuracy_near_observed_mm < 0.5  # the mesh's own error at 1.6 mm cells
    assert result.accuracy_near_unobserved_mm == pytest.approx(3.0, abs=0.2)
    assert result.completeness_observed_mm < 0.5 and result.completeness_unobserved_mm == pytest.approx(3.0, abs=0.2)
    f = result.observed_fraction  # the two halves of the completeness make up the full Chamfer's
    completeness = f * result.completeness_observed_mm + (1 - f) * result.completeness_unobserved_mm
    accuracy = 2 * result.full.chamfer_l1_mm - completeness
    assert accuracy == pytest.approx(0.5 * (result.accuracy_near_observed_mm + result.accuracy_near_unobserved_mm), abs=0.3)
    assert result.as_dict()["accuracy_near_unobserved_mm"] == result.accuracy_near_unobserved_mm
    assert evaluate_scene(mesh, scene, samples=2_000).accuracy_near_observed_mm is None


def test_the_objects_parts_of_the_observed_chamfer_sum_to_it_and_name_the_object_off(tmp_path):
    """Only the left ball observed, the right one 3 mm too large: the right ball's part is half of
    3 mm times its share of the predicted area (23^2 / (20^2 + 23^2)), the left's the meshing error,
    and the parts sum to the observed Chamfer."""
    from rfsdf.geometry import Union
    from rfsdf.metrics import evaluate_scene

    scene = _two_ball_scene(tmp_path)
    mesh = extract_mesh(Union(Sphere(0.02, (-0.05, 0.0, 0.0)), Sphere(0.023, (0.05, 0.0, 0.0))),
                        (-0.1,) * 3, (0.1,) * 3, 128)
    result = evaluate_scene(mesh, scene, observed=lambda p, n: p[:, 0] < 0, samples=20_000)
    left, right = result.objects["left"].observed_share_mm, result.objects["right"].observed_share_mm
    assert left + right == pytest.approx(result.observed.chamfer_l1_mm, rel=1e-9)
    assert right == pytest.approx(0.5 * 3.0 * 23**2 / (20**2 + 23**2), abs=0.15) and left < 0.25
    assert evaluate_scene(mesh, scene, samples=2_000).objects["left"].observed_share_mm is None


def test_the_observed_mask_is_traced_once_per_set_of_samples():
    """A demo scores five meshes against the same true-surface samples: the mask is computed
    once for them, and again when the samples change."""
    calls = []
    mask = once_per_samples(lambda p, n: calls.append(len(p)) or p[:, 0] < 0)
    points, normals = torch.randn(50, 3), torch.randn(50, 3)
    first = mask(points, normals)
    assert torch.equal(mask(points.clone(), normals.clone()), first) and calls == [50]
    assert torch.equal(mask(points[:20], normals[:20]), points[:20, 0] < 0) and calls == [50, 20]
