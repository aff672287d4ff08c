"""Scene models side by side: the hybrid field's bounded residual, its mesh, and the room
demo (`rfsdf demo --model primitive|hybrid|all`) end to end at quick size."""

import json

import pytest
import tomli_w
import torch
import trimesh
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.demo import DemoSettings, load_scene_and_radar, require_demo_images
from rfsdf.errors import RfsdfError
from rfsdf.recon.hybrid import HybridField, project_mesh
from rfsdf.scene_model import SceneModel

_BALL = {"name": "ball", "bounds": {"lower_m": [-0.5, -0.5, -0.5], "upper_m": [0.5, 0.5, 0.5]},
         "objects": [{"name": "ball", "material": "metal",
                      "shape": {"type": "sphere", "radius_m": {"start": 0.2, "bounds_m": 0.05}}}]}


def _hybrid(amplitude_m: float = 0.04) -> HybridField:
    return HybridField(SceneModel.from_table(_BALL, "ball"), amplitude_m, [-0.5] * 3, [0.5] * 3)


def test_the_hybrid_starts_at_its_primitive_model_and_its_residual_stays_within_its_bound():
    """The residual's last layer starts at zero: f is the sphere's exact SDF. With weights
    blown up 1000-fold the residual saturates, and still |f - f_model| < the amplitude
    (4 cm) everywhere in the box, while reaching 99 % of it somewhere."""
    field = _hybrid()
    points = torch.rand(20_000, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) - 0.5
    with torch.no_grad():
        assert torch.allclose(field.sdf(points), points.norm(dim=1) - 0.2, atol=1e-12)
        for parameter in field.residual_parameters():
            parameter.normal_(0.0, 1000.0)
        residual = field.residual(points)
        assert torch.allclose(field.sdf(points) - residual, points.norm(dim=1) - 0.2, atol=1e-12)
    assert float(residual.abs().max()) <= 0.04
    assert float(residual.abs().max()) > 0.99 * 0.04


def test_the_hybrid_mesh_is_the_primitive_mesh_moved_onto_the_hybrid_zero_set():
    """With a constant residual a tanh(b), the hybrid's zero set is a sphere of radius
    0.2 - a tanh(b): the projected icosphere's vertices lie on it to 1e-9 m, and its faces
    are the primitive mesh's."""
    field = _hybrid()
    with torch.no_grad():
        field.network[-1].bias.fill_(0.5)
    expected = 0.2 - 0.04 * torch.tanh(torch.tensor(0.5, dtype=torch.float64))
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    moved = project_mesh(field.frozen_sdf(), sphere)
    radii = torch.as_tensor(moved.vertices).norm(dim=1)
    assert float((radii - expected).abs().max()) < 1e-9
    assert (moved.faces == sphere.faces).all()


def test_a_room_is_refused_by_the_neural_demo_with_the_models_named():
    """l-room at the GeRaF demo's 6 mm voxel does not fit in memory: one line that names
    the scene models instead (the model demo records it as the neural model's reason)."""
    inputs = load_scene_and_radar("l-room", "room-60g")
    with pytest.raises(RfsdfError, match="--model primitive, hybrid or all"):
        require_demo_images(inputs, DemoSettings(scene="l-room", radar="room-60g"))


def _walls(tmp_path) -> str:
    """Two 30 cm walls (concrete, metal) 1.2 and 0.9 m from room-60g's views."""
    wall = lambda name, material, half, centre: {  # noqa: E731
        "name": name, "material": material, "shape": {"type": "box", "half_extents_m": half, "center_m": centre}}
    table = {"name": "two-room-walls", "bounds": {"lower_m": [-1.6, -1.6, 0.8], "upper_m": [1.6, 1.6, 2.2]},
             "objects": [wall("east", "concrete", [0.01, 0.15, 0.15], [1.2, 0.0, 1.5]),
                         wall("south", "metal", [0.15, 0.01, 0.15], [0.0, -0.9, 1.5])]}
    path = tmp_path / "walls.toml"
    path.write_text(tomli_w.dumps(table))
    return str(path)


def test_the_room_demo_runs_each_model_into_one_folder_and_reports_them_side_by_side(tmp_path):
    """`demo --model primitive --quick`, then `--model all` into the same folder: the data
    are simulated once, the model already there is read back and the hybrid and neural ones
    added, metrics.json holds the three with the issue's keys (each free
    parameter's start, fit and truth for the scene models; the network's size and levels,
    the finest at the range resolution, for the neural one), and report.html shows them side
    by side."""
    scene, out = _walls(tmp_path), tmp_path / "demo"
    written = {}
    for model in ("primitive", "all"):
        result = CliRunner().invoke(main, ["demo", "--scene", scene, "--radar", "room-60g", "--model", model,
                                           "--quick", "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert "F at 10.7 mm (half the range resolution)" in result.output
        written[model] = {p.name: p.stat().st_mtime_ns for p in (out / "measurements.h5", out / "primitive" / "model.json")}
    assert written["all"] == written["primitive"]  # neither simulated nor fitted again
    assert "simulate_s" in json.loads((out / "metrics.json").read_text())["timings_s"]
    metrics = json.loads((out / "metrics.json").read_text())
    assert list(metrics["models"]) == ["primitive", "hybrid", "neural"]
    assert metrics["f_threshold_m"] == pytest.approx(299_792_458.0 / 7e9 / 4)
    for name in ("primitive", "hybrid"):
        row = metrics["models"][name]
        assert {"chamfer_l1_mm", "f_score", "normal_consistency", "parameters", "fit_s", "free"} <= set(row)
        names = {p["name"]: p for p in row["free"]}
        assert names["east.center_m"]["truth"] == [1.2, 0.0, 1.5]
        assert set(names["east.center_m"]) == {"name", "unit", "start", "fitted", "truth"}
        assert row["seen_surface"]["foot_points"] > 0
    assert metrics["models"]["hybrid"]["residual_amplitude_m"] == pytest.approx(2 * 299_792_458.0 / 7e9 / 2)
    neural = metrics["models"]["neural"]
    assert {"chamfer_l1_mm", "f_score", "normal_consistency", "parameters", "fit_s", "seen_surface"} <= set(neural)
    encoded = 3 + 6 * neural["levels"]  # QUICK's network: width 32, depth 3, the input re-fed before layer 1
    assert neural["steps"] == 4 and neural["parameters"] == (encoded + 1) * 32 + (32 + encoded + 1) * 32 + 32 + 1
    assert 3.2 / 2 ** neural["levels"] <= 299_792_458.0 / 7e9 / 2 < 3.2 / 2 ** (neural["levels"] - 1)
    assert (out / "neural" / "mesh.ply").is_file()
    page = (out / "report.html").read_text()
    assert 'id="models"' in page and 'id="free-primitive"' in page and 'id="free-hybrid"' in page
    assert "neural model, coloured by its signed distance" in page


@pytest.mark.parametrize("args, message", [
    (["--model", "primitive", "--no-materials"], "--no-materials: only with --model neural"),
    (["--seed", "3"], "--seed: only with --model primitive, hybrid or all"),
    (["--transmission"], "--transmission: only with --model primitive, hybrid or all"),
    (["--beams"], "--beams: only with --model primitive, hybrid or all"),
])
def test_options_of_one_kind_of_model_are_refused_for_the_other(tmp_path, args, message):
    result = CliRunner().invoke(main, ["demo", "--out", str(tmp_path / "o"), *args])
    assert result.exit_code == 2 and message in result.output, result.output
    assert not (tmp_path / "o").exists()
