"""Scenes: presets, sampling, materials, and one-line errors for bad files."""

import math
from pathlib import Path

import pytest
import torch
import trimesh

from rfsdf.errors import RfsdfError
from rfsdf.geometry import Grid, MeshSDF
from rfsdf.scene import Scene, load_scene, scene_presets
from rfsdf.scene_model import load_scene_model
from rfsdf.scene_spec import SceneSpec


def test_presets_exist_and_load():
    assert {"objects", "l-room", "sphere"} <= set(scene_presets())
    objects = load_scene("objects")
    sizes = [m.extents.max() for m in objects.object_meshes()]
    assert all(0.03 <= s <= 0.1 + 1e-3 for s in sizes)
    assert len({o.material.name for o in objects.objects}) >= 4


BENCHMARK_SCENES = sorted((Path(__file__).parents[1] / "benchmarks" / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", BENCHMARK_SCENES, ids=lambda path: path.stem)
def test_every_benchmark_scene_loads_with_its_objects_in_its_bounds(path):
    """A benchmark's scene file (or scene model, at its start) loads, and each object reaches into
    the bounds: some point of a 64-voxel grid of them (finer than the load's own check at 24) lies
    inside it or within a voxel diagonal of its surface. A typo, or a transform that turns an
    object about the origin out of the scene, shows here and not only when a benchmark runs."""
    if path.stem.endswith("-model"):  # a scene model: its scene at the start
        model = load_scene_model(path)
        scene = Scene(model.spec, model.base_dir)
    else:
        scene = load_scene(path)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, float(scene.extent_m.max()) / 64)
    points, reach = grid.points(dtype=torch.float64), math.hypot(*grid.voxel_m)
    with torch.no_grad():
        outside = [obj.name for obj in scene.objects if not (obj.sdf(points) < reach).any()]
    assert not outside, f"{path.name}: outside the bounds: {outside}"


def test_sphere_scene_surface_sampling_is_exact():
    scene = load_scene("sphere")
    samples = scene.sample_surface(0.002, seed=1)
    r = samples.points.norm(dim=1)
    torch.testing.assert_close(r, torch.full_like(r, 0.02), atol=1e-6, rtol=0)
    torch.testing.assert_close(samples.normals, samples.points / r[:, None], atol=1e-5, rtol=0)
    assert samples.area_m2.sum().item() == pytest.approx(4 * math.pi * 0.02**2, rel=5e-3)
    assert len(samples.points) == pytest.approx(4 * math.pi * 0.02**2 / 0.002**2, rel=0.01)


def test_sampling_is_reproducible_and_respects_max_samples():
    scene = load_scene("objects")
    a, b = scene.sample_surface(0.004, seed=3), scene.sample_surface(0.004, seed=3)
    torch.testing.assert_close(a.points, b.points)
    assert len(scene.sample_surface(0.001, max_samples=2000).points) <= 2100


def test_material_at_and_sdf():
    scene = load_scene("objects")
    ball = torch.tensor([[0.05, 0.05, 0.0]])
    assert scene.material_at(ball)[0].name == "metal"
    assert scene.sdf(ball).item() == pytest.approx(-0.025)


def test_mesh_object_in_scene(tmp_path, spot_path):
    (tmp_path / "cow.toml").write_text(f"""
name = "cow"
[bounds]
lower_m = [-0.1, -0.1, -0.1]
upper_m = [0.1, 0.1, 0.1]
[[objects]]
name = "spot"
material = "wood"
shape = {{ type = "mesh", path = "{spot_path}", size_m = 0.1, center_m = [0.0, 0.0, 0.0] }}
""")
    scene = load_scene(tmp_path / "cow.toml")
    assert scene.object_meshes()[0].extents.max() == pytest.approx(0.1)
    assert scene.sdf(torch.zeros(1, 3)).item() < 0
    samples = scene.sample_surface(0.003)
    assert scene.sdf(samples.points.double()).abs().max().item() < 1e-6


def test_scene_sdf_skips_a_far_mesh_without_changing_a_value(tmp_path, monkeypatch):
    trimesh.creation.icosphere(subdivisions=3, radius=1.0).export(tmp_path / "ball.ply")
    (tmp_path / "two.toml").write_text("""
name = "two"
[bounds]
lower_m = [-0.1, -0.1, -0.1]
upper_m = [0.1, 0.1, 0.1]
[[objects]]
name = "ball"
material = "metal"
shape = { type = "mesh", path = "ball.ply", size_m = 0.04, transform = { scale = 0.5, rotate_rad = 0.3, translate_m = [0.03, 0.0, 0.0] } }
[[objects]]
name = "box"
material = "wood"
shape = { type = "box", half_extents_m = [0.02, 0.02, 0.02], center_m = [-0.05, 0.0, 0.0] }
""")
    scene = load_scene(tmp_path / "two.toml")
    queried = []
    evaluate = MeshSDF._evaluate
    monkeypatch.setattr(MeshSDF, "_evaluate", lambda self, p: queried.append(len(p)) or evaluate(self, p))
    points = (torch.rand(4000, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) - 0.5) * 0.2
    points.requires_grad_(True)
    values = scene.sdf(points)
    assert sum(queried) < 0.9 * len(points)  # the points nearer the box never reach the mesh
    reference = scene._object_values(points.detach()).min(0).values  # every object everywhere
    torch.testing.assert_close(values.detach(), reference, rtol=0, atol=1e-12)
    (grad,) = torch.autograd.grad(values.sum(), points)
    torch.testing.assert_close(grad.norm(dim=1), torch.ones(len(points), dtype=torch.float64), rtol=0, atol=1e-6)
    centre, radius = scene.objects[0].sdf.bounding_sphere()  # the transforms carry it along
    torch.testing.assert_close(centre, torch.tensor([0.03, 0.0, 0.0], dtype=torch.float64), rtol=0, atol=1e-9)
    assert radius == pytest.approx(0.01, rel=1e-6)


BAD_SCENES = {
    "radius": ('shape = { type = "sphere", radius_m = -0.1 }', r"objects\[0\]\.shape.*radius_m.*greater than 0"),
    "material": ('material = "unobtainium"\nshape = { type = "sphere", radius_m = 0.1 }', "unknown material"),
    "type": ('shape = { type = "blob", radius_m = 0.1 }', r"objects\[0\]\.shape.*blob"),
    "typo": ('shape = { type = "sphere", radius = 0.1 }', "radius"),
    "roughness": ('shape = { type = "sphere", radius_m = 0.1 }\nroughness = { rms_m = 1e-4, correlation_m = 0 }',
                  r"objects\[0\]\.roughness\.correlation_m.*greater than 0"),
    "roughness key": ('shape = { type = "sphere", radius_m = 0.1 }\nroughness = { rms = 1e-4, correlation_m = 3e-3 }',
                      r"objects\[0\]\.roughness.*rms"),
}


@pytest.mark.parametrize("case", BAD_SCENES)
def test_bad_scene_files_give_one_line_errors(tmp_path, case):
    body, pattern = BAD_SCENES[case]
    if "material" not in body:
        body = 'material = "metal"\n' + body
    path = tmp_path / "bad.toml"
    path.write_text(f'name = "x"\n[bounds]\nlower_m = [-1, -1, -1]\nupper_m = [1, 1, 1]\n[[objects]]\nname = "a"\n{body}\n')
    with pytest.raises(RfsdfError, match=pattern) as info:
        load_scene(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "\n" not in message


def test_malformed_toml_and_bad_bounds(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("name = \n")
    with pytest.raises(RfsdfError, match="broken.toml: invalid TOML"):
        load_scene(path)
    path.write_text('name = "x"\n[bounds]\nlower_m = [1, 1, 1]\nupper_m = [0, 2, 2]\n'
                    '[[objects]]\nname="a"\nmaterial="metal"\nshape={type="sphere", radius_m=0.1}\n')
    with pytest.raises(RfsdfError, match="bounds: lower_m"):
        load_scene(path)


def test_an_object_is_as_thick_as_its_thinnest_part():
    """The boxed preset's cardboard walls are 3 mm; its ball 4 cm across."""
    boxed = load_scene("boxed")
    by_name = {o.name: o for o in boxed.objects}
    assert boxed.thinnest_m(by_name["box"]) == pytest.approx(0.003, rel=0.05)
    assert boxed.thinnest_m(by_name["metal_ball"]) == pytest.approx(0.04, rel=0.05)


@pytest.mark.parametrize("half_extents, thickness", [((0.0015, 0.12, 0.12), 0.003), ((0.02, 0.12, 0.15), 0.04),
                                                     ((0.05, 0.7, 1.2), 0.1), ((0.3, 0.25, 0.9), 0.5)])
def test_a_box_in_a_room_is_as_thick_as_its_smallest_edge(half_extents, thickness):
    """A pane, a board, a partition and a cabinet in a 6 m room, on the grid's planes as designed
    scenes put them: each reads its smallest edge (the depth below the surface read a 3 mm pane
    0.35 mm thick and meshed it at 0.12 mm, 17 million faces; the rims' lines of sight graze)."""
    spec = {"name": "room", "bounds": {"lower_m": [-3.2, -2.2, -0.2], "upper_m": [3.2, 2.2, 3.2]},
            "objects": [{"name": "box", "material": "glass",
                         "shape": {"type": "box", "half_extents_m": list(half_extents), "center_m": [-0.5, 1.1, 1.2]}}]}
    room = Scene(SceneSpec.model_validate(spec))
    assert room.thinnest_m(room.objects[0]) == pytest.approx(thickness, rel=0.02)
