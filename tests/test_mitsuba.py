"""Sionna RT / Mitsuba 3 scenes: the ITU-R P.2040-3 catalogue, reading the XML subset
(transforms, materials, surfaces read as solids, sheets and shells), hostile files, and the
round trip through `rfsdf scene export`. Every XML here is built by the test; Sionna is never
needed."""

import json
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.errors import RfsdfError
from rfsdf.geometry import MeshSDF
from rfsdf.materials import EPS0, MATERIALS, get_material
from rfsdf.mitsuba.write import export_scene, write_ply
from rfsdf.radar import simulate
from rfsdf.recon.primitive import PrimitiveField
from rfsdf.scene import Scene, build_shape, load_scene, scene_presets
from rfsdf.scene_model import SceneModel, analytic_spec
from rfsdf.scene_spec import SceneSpec
from test_hostile_inputs import _refused
from test_rooms import _monostatic

# Every ITU material name Sionna RT 2.x accepts in an itu-radio-material (its itu.py, minus vacuum).
SIONNA_ITU_NAMES = ["concrete", "brick", "plasterboard", "wood", "glass", "clear_acrylic", "ceiling_board",
                    "chipboard", "plywood", "marble", "floorboard", "vinyl_tile", "carpet_tile",
                    "asphalt_concrete", "metal", "very_dry_ground", "medium_dry_ground", "wet_ground"]


def _xml(folder: Path, body: str, name: str = "scene.xml") -> Path:
    path = folder / name
    path.write_text(f'<scene version="2.1.0">\n{body}\n</scene>\n')
    return path


def _ply(folder: Path, name: str, mesh: trimesh.Trimesh) -> None:
    (folder / "meshes").mkdir(exist_ok=True)
    write_ply(mesh, folder / "meshes" / name)


def _quad(half: float = 1.0) -> trimesh.Trimesh:
    return trimesh.Trimesh([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]],
                           [[0, 1, 2], [0, 2, 3]], process=False)


ITU_CONCRETE = '<bsdf type="itu-radio-material" id="c"><string name="type" value="concrete"/>' \
               '<float name="thickness" value="0.02"/></bsdf>'


# Materials --------------------------------------------------------------------------------
def test_every_sionna_itu_name_is_in_the_catalogue():
    assert set(SIONNA_ITU_NAMES) <= set(MATERIALS)


def test_the_itu_formula_and_the_first_band_that_holds_the_frequency():
    def itu(a, b, c, d, f_ghz):
        return complex(a * f_ghz**b, -c * f_ghz**d / (2 * math.pi * f_ghz * 1e9 * EPS0))

    assert get_material("marble").permittivity(30e9) == pytest.approx(itu(7.074, 0, 0.0055, 0.9262, 30))
    assert get_material("concrete").permittivity(200e9) == pytest.approx(itu(5.17, 0, 0.0145, 1.09, 200))
    # plasterboard lists 110-330 before 100-400 GHz: at 105 GHz only the second holds, at 200 the first
    assert get_material("plasterboard").permittivity(105e9) == pytest.approx(itu(2.65, 0, 0.0002, 1.598, 105))
    assert get_material("plasterboard").permittivity(200e9) == pytest.approx(itu(2.56, 0, 0.0001, 1.7799, 200))
    # the grounds' eps' falls with frequency (b < 0)
    assert get_material("wet_ground").permittivity(5e9).real == pytest.approx(30 * 5**-0.4)


def test_a_material_between_its_bands_is_one_clear_line():
    with pytest.raises(ValueError, match=r"'brick': 60 GHz is outside its ITU-R P.2040 range 1-40, 110-330 GHz"):
        get_material("brick").permittivity(60e9)


# Reading ----------------------------------------------------------------------------------
def test_a_rectangle_wall_is_a_slab_of_the_material_thickness_centred_on_it(tmp_path):
    path = _xml(tmp_path, f"""{ITU_CONCRETE}
  <default name="height" value="1.5"/>
  <shape type="rectangle" id="wall">
    <transform name="to_world">
      <scale x="0.5" y="0.4" z="1"/>
      <rotate y="1" angle="90"/>
      <translate value="2, 0, $height"/>
    </transform>
    <ref id="c" name="bsdf"/>
  </shape>""")
    scene = load_scene(path)
    (wall,) = scene.objects
    assert wall.material.name == "concrete"
    # rotated 90 deg about y, the unit square's normal +z becomes +x: a wall in the plane x = 2,
    # 0.8 m along y and 1 m along z around height 1.5
    points = torch.tensor([[2.3, 0.0, 1.5], [1.995, 0.1, 1.2], [2.0, 0.6, 1.5], [2.0, 0.0, 2.2]], dtype=torch.float64)
    expected = [0.3 - 0.01, -0.005, 0.2, 0.2]  # in front, inside the slab, beyond each edge
    np.testing.assert_allclose(wall.sdf(points).detach().numpy(), expected, atol=1e-9)
    assert "open surface 0.8 m^2 read as a sheet 20 mm" in scene.summary()


def test_transforms_compose_in_order_and_a_matrix_is_read_by_rows(tmp_path):
    _ply(tmp_path, "box.ply", trimesh.creation.box(extents=(0.2, 0.2, 0.2)))
    matrix = trimesh.transformations.compose_matrix(angles=(0.3, -0.2, 0.5), translate=(0.1, 0.2, 0.3))
    rows = " ".join(f"{v:.17g}" for v in matrix.ravel())
    path = _xml(tmp_path, f"""{ITU_CONCRETE}
  <shape type="ply" id="a"><string name="filename" value="meshes/box.ply"/>
    <transform name="to_world"><translate x="1"/><scale value="2"/></transform><ref id="c"/></shape>
  <shape type="ply" id="b"><string name="filename" value="meshes/box.ply"/>
    <transform name="to_world"><matrix value="{rows}"/></transform><ref id="c"/></shape>""")
    a, b = load_scene(path).object_meshes()
    np.testing.assert_allclose(a.bounds, [[1.8, -0.2, -0.2], [2.2, 0.2, 0.2]], atol=1e-6)  # translate, then scale
    expected = trimesh.creation.box(extents=(0.2, 0.2, 0.2)).apply_transform(matrix)
    np.testing.assert_allclose(np.sort(b.vertices, axis=0), np.sort(expected.vertices, axis=0), atol=1e-6)


def test_each_material_kind_and_a_nested_bsdf(tmp_path):
    path = _xml(tmp_path, """<bsdf type="radio-material" id="teflon">
    <float name="relative_permittivity" value="2.1"/><float name="conductivity" value="0.001"/>
    <rgb name="color" value="0.5 0.5 0.5"/></bsdf>
  <shape type="sphere" id="ball"><point name="center" x="0.3" y="0" z="0"/><float name="radius" value="0.1"/>
    <ref id="teflon" name="bsdf"/></shape>
  <shape type="cube" id="block"><transform name="to_world"><scale value="0.05"/></transform>
    <bsdf type="itu-radio-material"><string name="type" value="metal"/></bsdf></shape>""")
    scene = load_scene(path)
    ball, block = scene.objects
    assert ball.material.permittivity(60e9) == pytest.approx(complex(2.1, -0.001 / (2 * math.pi * 60e9 * EPS0)))
    assert block.material.pec
    centre = torch.tensor([[0.3, 0.0, 0.0], [0.0, 0.0, 0.0]], dtype=torch.float64)
    np.testing.assert_allclose(ball.sdf(centre[:1]).item(), -0.1, rtol=2e-3)  # a solid: closed unit sphere
    np.testing.assert_allclose(block.sdf(centre[1:]).item(), -0.05, atol=1e-9)
    assert "closed surface" in scene.summary() and "read as a solid" in scene.summary()


def test_a_closed_room_around_the_radar_becomes_walls_whose_inner_faces_are_the_mesh(tmp_path):
    _ply(tmp_path, "room.ply", trimesh.creation.box(extents=(4.0, 3.0, 2.5)).apply_translation((0, 0, 1.25)))
    path = _xml(tmp_path, f'{ITU_CONCRETE}<shape type="ply" id="room"><string name="filename" value="meshes/room.ply"/>'
                          '<boolean name="face_normals" value="true"/><ref id="c" name="bsdf"/></shape>')
    scene = load_scene(path)
    radar_at = np.array([[0.5, 0.0, 1.5]])
    assert scene.objects[0].sdf(torch.tensor(radar_at)).item() < 0  # read alone: a solid block
    room = scene.around_radar(radar_at)
    probes = torch.tensor([[0.5, 0.0, 1.5], [2.01, 0.0, 1.0], [2.03, 0.0, 1.0]], dtype=torch.float64)
    # 1.0 m to the ceiling at 2.5; inside the 2 cm wall beyond x = 2; 1 cm outside it
    np.testing.assert_allclose(room.objects[0].sdf(probes).detach().numpy(), [1.0, -0.01, 0.01], atol=1e-9)
    assert scene.around_radar(np.array([[9.0, 0.0, 1.0]])) is scene


def test_meshes_that_are_boxes_are_written_as_analytic_boxes_with_the_same_sdf_and_free_lengths(tmp_path):
    """A room mesh around the radar (a shell), a cube turned by a to_world rotation (a solid)
    and a quad wall (a sheet) become boxes (the shell: a box less a box) whose SDF is the
    meshes' to rounding, so the primitive model can free their lengths; a mesh that is no
    box (a ball) stays a mesh, held."""
    _ply(tmp_path, "room.ply", trimesh.creation.box(extents=(4.0, 3.0, 2.5)).apply_translation((0, 0, 1.25)))
    _ply(tmp_path, "ball.ply", trimesh.creation.icosphere(radius=0.2).apply_translation((-1.0, 1.0, 1.0)))
    path = _xml(tmp_path, f"""{ITU_CONCRETE}
  <shape type="ply" id="mesh-room"><string name="filename" value="meshes/room.ply"/><ref id="c"/></shape>
  <shape type="cube" id="mesh-cabinet"><transform name="to_world"><scale x="0.3" y="0.2" z="0.5"/>
    <rotate x="1" y="1" z="0" angle="30"/><translate x="1.2" y="0.8" z="0.6"/></transform><ref id="c"/></shape>
  <shape type="rectangle" id="mesh-board"><transform name="to_world"><scale x="0.5" y="0.4"/>
    <rotate y="1" angle="90"/><translate x="-1.5" z="1.2"/></transform><ref id="c"/></shape>
  <shape type="ply" id="mesh-ball"><string name="filename" value="meshes/ball.ply"/><ref id="c"/></shape>""")
    scene = load_scene(path).around_radar(np.array([[0.0, 0.0, 1.5]]))
    analytic = analytic_spec(scene)
    assert [o.shape.type for o in analytic.objects] == ["difference", "box", "box", "mesh"]
    assert analytic.objects[1].shape.transform.rotate_rad > 0  # the cabinet's own axes
    points = torch.tensor(np.random.default_rng(0).uniform(scene.lower_m, scene.upper_m, (4000, 3)))
    exact = Scene(analytic, scene.base_dir)
    for spec, box_object in zip(scene.spec.objects, exact.objects):  # the meshes' own SDF (libigl's AABB tree)
        mesh_sdf = build_shape(spec.shape, scene.base_dir)(points)
        np.testing.assert_allclose(box_object.sdf(points).detach().numpy(), mesh_sdf.detach().numpy(), atol=1e-6)
    # the scene itself evaluates the boxes in closed form (shadow rays), and samples their meshes
    assert [o.reading.box for o in scene.objects] == [True, True, True, False]
    for obj, box_object in zip(scene.objects, exact.objects):
        np.testing.assert_allclose(obj.sdf(points).detach().numpy(), box_object.sdf(points).detach().numpy())
    summary = scene.summary()
    assert scene.objects[0].mesh is not None and "closed surface 59 m^2 read as a shell 20 mm, a box" in summary
    assert summary.endswith("read as a solid (a shell when a radar is inside)")  # the ball: no box
    model = SceneModel.from_scene(scene, 0.1, seed=0)
    assert {p.name.split(".")[0] for p in model.free} == {"room", "cabinet", "board"}
    assert model.values_in(analytic) is not None  # the truth of every free parameter
    # the room's 2 cm wall: its start moved as one piece (offsets of 10 cm drawn apart for
    # its two boxes would have taken the wall away), and meshed exactly (two boxes, 24 triangles)
    named = {p.name: np.asarray(p.start) for p in model.free}
    np.testing.assert_allclose(named["room.children[0].half_extents_m"] - named["room.children[1].half_extents_m"],
                               0.02, atol=1e-12)
    np.testing.assert_array_equal(named["room.children[0].center_m"], named["room.children[1].center_m"])
    assert model.shell_ties() == [(0, 2), (1, 3)]
    room = exact.object_meshes()[0]
    assert len(room.faces) == 24 and room.is_watertight
    assert room.area == pytest.approx(2 * (4.04 * 3.04 + 4.04 * 2.54 + 3.04 * 2.54) + 2 * (4 * 3 + 4 * 2.5 + 3 * 2.5))
    np.testing.assert_allclose(MeshSDF(room)(points).numpy(), exact.objects[0].sdf(points).detach().numpy(), atol=1e-9)
    # in the fit the outer box follows the inner one: its faces' gradient goes to the inner's lengths
    field = PrimitiveField(model)
    centre, outer_half = named["room.children[0].center_m"], named["room.children[0].half_extents_m"]
    beyond = torch.from_numpy((centre + [outer_half[0] + 0.01, 0.0, 0.0])[None])  # 1 cm outside its +x face
    field.sdf(beyond).sum().backward()
    assert field.values[0].grad is None and field.values[2].grad.tolist() == pytest.approx([-1.0, 0.0, 0.0])
    with torch.no_grad():
        field.values[2].add_(torch.tensor([0.05, -0.03, 0.0], dtype=torch.float64))
    field.clamp_()
    np.testing.assert_allclose((field.values[0] - field.values[2]).detach().numpy(), 0.02, atol=1e-12)


def test_a_turned_shell_starts_as_one_piece_and_keeps_its_placement_free():
    """A crate turned by its transform: its two boxes move by the same offsets (the 1 cm wall
    kept) and the transform's translation is free as any shape's."""
    spec = SceneSpec.model_validate({"name": "t", "bounds": {"lower_m": [-1, -1, -1], "upper_m": [1, 1, 1]}, "objects": [
        {"name": "crate", "material": "wood", "shape": {
            "type": "difference", "transform": {"translate_m": [0.1, 0.0, 0.0], "rotate_rad": 0.3},
            "children": [{"type": "box", "half_extents_m": [0.2, 0.2, 0.2]},
                         {"type": "box", "half_extents_m": [0.19, 0.19, 0.19]}]}}]})
    model = SceneModel.from_scene(Scene(spec), 0.05, seed=0)
    named = {p.name: np.asarray(p.start) for p in model.free}
    assert "crate.transform.translate_m" in named
    np.testing.assert_allclose(named["crate.children[0].half_extents_m"] - named["crate.children[1].half_extents_m"],
                               0.01, atol=1e-12)
    assert len(Scene(spec).object_meshes()[0].faces) == 24


def test_a_radar_inside_a_wall_is_one_line(tmp_path):
    path = _xml(tmp_path, f'{ITU_CONCRETE}<shape type="rectangle" id="floor"><ref id="c"/></shape>')
    with pytest.raises(RfsdfError, match=r"view 0 at \[0.0, 0.0, 0.0\] m lies inside object 'floor'"):
        load_scene(path).around_radar(np.zeros((1, 3)))


def test_a_read_wall_returns_what_the_same_wall_written_as_a_box_returns(tmp_path):
    """The XML's metal rectangle (thickness 1 cm) and the TOML box of the same slab simulate
    alike: the reading is the object, not an approximation of it."""
    path = _xml(tmp_path, """<bsdf type="itu-radio-material" id="m"><string name="type" value="metal"/>
    <float name="thickness" value="0.01"/></bsdf>
  <shape type="rectangle" id="plate"><transform name="to_world"><scale value="0.1"/>
    <translate z="0.5"/></transform><ref id="m"/></shape>""")
    toml = tmp_path / "plate.toml"
    toml.write_text('name = "plate"\n[bounds]\nlower_m = [-0.2, -0.2, 0.4]\nupper_m = [0.2, 0.2, 0.6]\n'
                    '[[objects]]\nname = "plate"\nmaterial = "metal"\n'
                    'shape = { type = "box", half_extents_m = [0.1, 0.1, 0.005], center_m = [0, 0, 0.5] }\n')
    radar = _monostatic(np.linspace(77e9, 81e9, 64))
    read, written = (simulate(load_scene(p), radar, seed=0).data.numpy().ravel() for p in (path, toml))
    correlation = abs(np.vdot(read, written)) / (np.linalg.norm(read) * np.linalg.norm(written))
    # two stratified samplings of one plate differ by a few per cent (measured: 8.36-8.85 for the
    # box alone over sampling settings); before its two big triangles were split into strata,
    # the read plate returned 21 % less: independent points on them
    assert correlation > 0.99 and np.linalg.norm(read) / np.linalg.norm(written) == pytest.approx(1.0, abs=0.06)
    peak = np.argmax(np.abs(np.fft.ifft(read)))
    spacing = 4e9 / 63 * 64
    assert peak * 3e8 / (2 * spacing) == pytest.approx(0.495, abs=3e8 / (2 * 4e9))  # the slab's near face


# Hostile files ----------------------------------------------------------------------------
BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE scene [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">]>
<scene version="2.1.0"><default name="x" value="&d;"/></scene>"""
EXTERNAL = """<?xml version="1.0"?>
<!DOCTYPE scene [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<scene version="2.1.0"><default name="x" value="&secret;"/></scene>"""


def _hostile_cases(folder: Path) -> dict[str, tuple[str, str]]:
    """name -> (XML text, a piece of the one error line it must give)."""
    _ply(folder, "quad.ply", _quad())
    shape = '<shape type="ply" id="s"><string name="filename" value="{}"/><ref id="c"/></shape>'
    (folder / "meshes" / "folder.ply").mkdir()
    huge = folder / "meshes" / "huge.ply"
    huge.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
                     b"property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                     b"end_header\n" + bytes(64))
    os.mkfifo(folder / "meshes" / "fifo.ply")
    many = "".join(shape.format("meshes/quad.ply").replace('id="s"', f'id="s{i}"') for i in range(1001))
    return {
        "entity expansion": (BILLION_LAUGHS, "refused"),
        "external entity": (EXTERNAL, "refused"),
        "not xml": ("<scene><shape></scene>", "invalid XML"),
        "unknown element": (f'{ITU_CONCRETE}<integrator type="path"/>', "line 2: <integrator type='path'>: not supported"),
        "unknown shape": (f'{ITU_CONCRETE}<shape type="bezier"><ref id="c"/></shape>', "supported shape types"),
        "unknown bsdf": ('<bsdf type="diffuse" id="d"/>', "supported bsdf types: itu-radio-material, radio-material"),
        "unknown itu name": ('<bsdf type="itu-radio-material" id="x"><string name="type" value="cheese"/></bsdf>',
                             "unknown material 'cheese'"),
        "unknown property": (f'{ITU_CONCRETE}<shape type="rectangle"><float name="blur" value="1"/><ref id="c"/></shape>',
                             "line 2: <float>: not supported inside <shape type='rectangle'>"),
        "lookat": (f'{ITU_CONCRETE}<shape type="rectangle"><transform name="to_world"><lookat origin="0,0,1" '
                   'target="0,0,0"/></transform><ref id="c"/></shape>', "supported: translate, rotate, scale, matrix"),
        "singular": (f'{ITU_CONCRETE}<shape type="rectangle"><transform name="to_world"><scale x="0"/></transform>'
                     '<ref id="c"/></shape>', "invertible"),
        "undefined default": (f'{ITU_CONCRETE}<shape type="ply"><string name="filename" value="$where"/>'
                              '<ref id="c"/></shape>', "$where has no <default"),
        "no material": ('<shape type="rectangle"/>', "has no material"),
        "missing ref": ('<shape type="rectangle"><ref id="nowhere"/></shape>', "no <bsdf id='nowhere'>"),
        "escaping path": (ITU_CONCRETE + shape.format("../outside.ply"), "leaves the scene file's folder"),
        "absolute path": (ITU_CONCRETE + shape.format("/etc/passwd"), "leaves the scene file's folder"),
        "folder as mesh": (ITU_CONCRETE + shape.format("meshes/folder.ply"), "is a folder"),
        "fifo as mesh": (ITU_CONCRETE + shape.format("meshes/fifo.ply"), "not a regular file"),
        "missing mesh": (ITU_CONCRETE + shape.format("meshes/gone.ply"), "file not found"),
        "vertices beyond the file": (ITU_CONCRETE + shape.format("meshes/huge.ply"),
                                     "declares 1,000,000,000 vertexs, more than its 64 bytes"),
        "a city": (ITU_CONCRETE + many, "1001 shapes: more than the 1000"),
        "a stadium": (f'{ITU_CONCRETE}<shape type="rectangle"><transform name="to_world"><scale value="40"/>'
                      '</transform><ref id="c"/></shape>', "spans 80 m, more than the 50 m"),
        "negative thickness": ('<bsdf type="itu-radio-material" id="c"><string name="type" value="glass"/>'
                               '<float name="thickness" value="-1"/></bsdf>', "thickness must be positive"),
        "scattering": ('<bsdf type="radio-material" id="c"><float name="scattering_coefficient" value="0.3"/></bsdf>',
                       "scattering_coefficient other than 0 is not read"),
    }


def test_every_hostile_scene_file_is_one_line_and_writes_nothing(tmp_path):
    for name, (body, expected) in _hostile_cases(tmp_path).items():
        text = body if body.startswith("<?xml") else f'<scene version="2.1.0">\n{body}\n</scene>\n'
        path = tmp_path / f"{name.replace(' ', '-')}.xml"
        path.write_text(text)
        output = _refused(["scene", "show", path, "--out", tmp_path / "slices.png"], tmp_path)
        assert expected in output and str(path) in output, (name, output)


# Writing ----------------------------------------------------------------------------------
def test_every_preset_survives_export_and_reading_back(tmp_path):
    """Chamfer between each object's exact surface and the one read back from its PLY below
    1 mm (marching cubes of the analytic SDF), and the same material."""
    for preset in scene_presets():
        scene = load_scene(preset)
        xml = export_scene(scene, tmp_path / preset)
        back = load_scene(xml)
        assert [o.name for o in back.objects] == [o.name for o in scene.objects]
        # Sionna RT names objects and materials by their ids less 'mesh-' / 'mat-' and refuses
        # a name used twice (an object named as its material was, before)
        root = ET.parse(xml).getroot()
        names = [e.get("id").removeprefix("mesh-") for e in root.iter("shape")]
        names += [e.get("id").removeprefix("mat-") for e in root.iter("bsdf")]
        assert len(set(names)) == len(names), names
        samples = scene.sample_surface(float(np.sqrt(sum(m.area for m in scene.object_meshes()) / 20_000)))
        for index, (original, read) in enumerate(zip(scene.objects, back.objects)):
            assert read.material.name == original.material.name
            on_read = torch.as_tensor(trimesh.sample.sample_surface(read.sdf.mesh, 2000, seed=0)[0])
            on_original = samples.points[samples.object_index == index].double()
            with torch.no_grad():
                chamfer = 0.5 * (original.sdf(on_read).abs().mean() + read.sdf(on_original).abs().mean())
            assert chamfer < 1e-3, (preset, original.name, float(chamfer))


def test_a_sheet_and_a_shell_are_written_as_their_surfaces_with_their_thickness(tmp_path):
    """Sionna models a wall as one surface with its material's thickness: the slab rfsdf
    makes of a sheet (two faces) would cross two walls. So a sheet is written as its open
    rectangle and a shell as its inner faces, each with its thickness, and both read back
    with the SDF they had (the shell as Sionna's rooms are: around the radar)."""
    room = trimesh.creation.box(extents=(4.0, 3.0, 2.5))
    _ply(tmp_path, "room.ply", room)
    scene = Scene(SceneSpec.model_validate({
        "name": "walls", "bounds": {"lower_m": [-2.5, -2.0, -1.5], "upper_m": [2.5, 2.0, 1.5]},
        "objects": [
            {"name": "pane", "material": "glass",
             "shape": {"type": "mesh", "builtin": "rectangle", "size_m": 0.4, "center_m": [0.5, 0.0, 0.3],
                       "reading": "sheet", "thickness_m": 0.004}},
            {"name": "room", "material": "concrete",
             "shape": {"type": "mesh", "path": "meshes/room.ply", "reading": "shell", "thickness_m": 0.1}}]}),
        base_dir=tmp_path)
    xml = export_scene(scene, tmp_path / "out")
    pane = trimesh.load(tmp_path / "out" / "meshes" / "pane.ply", process=False)
    assert not pane.is_watertight and np.ptp(pane.vertices[:, 2]) == 0  # one flat surface, not a slab
    np.testing.assert_allclose(pane.bounds, [[0.3, -0.2, 0.3], [0.7, 0.2, 0.3]], atol=1e-6)
    walls = trimesh.load(tmp_path / "out" / "meshes" / "room.ply", process=False)
    np.testing.assert_allclose(walls.extents, [4.0, 3.0, 2.5], atol=1e-6)  # the inner faces alone
    thickness = {e.get("id"): float(e.find("float[@name='thickness']").get("value")) for e in
                 ET.parse(xml).getroot().iter("bsdf")}
    assert thickness == {"mat-glass-4mm": 0.004, "mat-concrete-100mm": 0.1}
    back = load_scene(xml).around_radar(np.array([[0.0, 0.0, 0.0]]))
    probes = torch.tensor([[0.5, 0.0, 0.31], [0.5, 0.0, 0.3], [1.95, 0.0, 0.0], [2.05, 0.0, 0.0]], dtype=torch.float64)
    for original, read in zip(scene.objects, back.objects):
        np.testing.assert_allclose(read.sdf(probes).detach().numpy(), original.sdf(probes).detach().numpy(), atol=1e-6)


def test_scene_export_on_the_command_line_reads_back_and_refuses_the_input_folder(tmp_path):
    result = CliRunner().invoke(main, ["scene", "export", "sphere", "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "meshes" / "ball.ply").is_file()
    text = (tmp_path / "out" / "scene.xml").read_text()
    assert 'type="itu-radio-material"' in text and 'value="metal"' in text
    shown = CliRunner().invoke(main, ["scene", "show", str(tmp_path / "out" / "scene.xml"), "--out",
                                      str(tmp_path / "s.png")])
    assert shown.exit_code == 0 and "ball" in shown.output
    _refused(["scene", "export", tmp_path / "out" / "scene.xml", "--out", tmp_path / "out"], tmp_path)


def test_simulate_takes_a_sionna_scene_on_the_command_line(tmp_path):
    path = _xml(tmp_path, """<bsdf type="itu-radio-material" id="m"><string name="type" value="metal"/></bsdf>
  <bsdf type="itu-radio-material" id="g"><string name="type" value="glass"/>
    <float name="thickness" value="0.006"/></bsdf>
  <shape type="cube" id="mesh-block"><transform name="to_world"><scale value="0.02"/></transform><ref id="m"/></shape>
  <shape type="rectangle" id="mesh-pane"><transform name="to_world"><scale value="0.04"/><translate z="-0.04"/>
    </transform><ref id="g"/></shape>""")
    result = CliRunner().invoke(main, ["simulate", str(path), "--out", str(tmp_path / "m.h5")])
    assert result.exit_code == 0, result.output
    assert "block" in result.output and "open surface 0.0064 m^2 read as a sheet 6 mm" in result.output
    assert (tmp_path / "m.h5").is_file()


def test_a_room_scene_is_read_around_the_radar_and_the_demo_refuses_it_before_any_work(tmp_path):
    """A closed room mesh with room-28g inside: a shell, not a block the radar stands in; the
    demo (objects about a metre across) says in one line that its images would not fit,
    before simulating anything; the model demo, that a round room's mesh (no box) has
    nothing to free."""
    _ply(tmp_path, "room.ply", trimesh.creation.cylinder(radius=3.0, height=3.0).apply_translation((0, 0, 1.5)))
    path = _xml(tmp_path, f'{ITU_CONCRETE}<shape type="ply" id="mesh-room"><string name="filename" '
                          'value="meshes/room.ply"/><ref id="c"/></shape>')
    line = _refused(["demo", "--scene", path, "--radar", "room-28g", "--out", tmp_path / "demo"], tmp_path)
    assert "the demo's images of" in line and "--model primitive, hybrid or all" in line
    line = _refused(["demo", "--scene", path, "--radar", "room-28g", "--model", "primitive", "--out",
                     tmp_path / "demo"], tmp_path)
    assert "no free parameter, so nothing to fit" in line, line  # a mesh that is no box has no length to free


def test_a_toml_scene_says_how_a_surface_is_read_or_gets_one_line(tmp_path):
    _ply(tmp_path, "quad.ply", _quad(0.05))
    head = 'name = "t"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n[[objects]]\n' \
           'name = "pane"\nmaterial = "glass"\n'
    cases = {
        'shape = { type = "mesh", path = "meshes/quad.ply", reading = "sheet", thickness_m = 0.006 }': None,
        'shape = { type = "mesh", path = "meshes/quad.ply", reading = "sheet" }': "read as a sheet needs thickness_m",
        'shape = { type = "mesh", path = "meshes/quad.ply" }': "an open mesh is read as a sheet, which needs thickness_m",
        'shape = { type = "mesh", path = "meshes/quad.ply", builtin = "cube" }': "exactly one of path and builtin",
        'shape = { type = "mesh", path = "meshes/quad.ply", reading = "shell", thickness_m = 0.01 }':
            "only a closed mesh can be read as a shell",
    }
    for index, (shape, error) in enumerate(cases.items()):
        path = tmp_path / f"scene{index}.toml"
        path.write_text(head + shape + "\n")
        if error is None:
            pane = load_scene(path).objects[0]
            assert pane.sdf(torch.tensor([[0.0, 0.0, 0.01]], dtype=torch.float64)).item() == pytest.approx(0.007)
        else:
            with pytest.raises(RfsdfError, match=error):
                load_scene(path)


def test_a_sionna_scene_of_quad_walls_runs_through_the_primitive_model_demo(tmp_path):
    """Two walls drawn as Sionna draws them (one rectangle each, with room-60g between
    them): `demo --model primitive --quick` frees their box lengths and reports each one's
    start, fit and truth."""
    walls = "".join(f"""
  <bsdf type="itu-radio-material" id="mat-{name}"><string name="type" value="{material}"/>
    <float name="thickness" value="0.02"/></bsdf>
  <shape type="rectangle" id="mesh-{name}"><transform name="to_world"><scale x="0.15" y="0.3"/>
    <rotate y="1" angle="90"/><translate x="{x}" z="1.5"/></transform><ref id="mat-{name}"/></shape>"""
                    for name, material, x in (("east", "concrete", 1.2), ("west", "metal", -0.9)))
    path = _xml(tmp_path, walls)
    result = CliRunner().invoke(main, ["demo", "--scene", str(path), "--radar", "room-60g", "--model", "primitive",
                                       "--quick", "--max-samples", "60000", "--out", str(tmp_path / "demo")])
    assert result.exit_code == 0, result.output
    free = {p["name"]: p for p in json.loads((tmp_path / "demo" / "metrics.json").read_text())
            ["models"]["primitive"]["free"]}
    assert set(free) == {"east.half_extents_m", "east.center_m", "west.half_extents_m", "west.center_m"}
    np.testing.assert_allclose(free["east.center_m"]["truth"], [1.2, 0.0, 1.5], atol=1e-6)
    np.testing.assert_allclose(free["west.half_extents_m"]["truth"], [0.01, 0.3, 0.15], atol=1e-6)
