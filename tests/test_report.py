"""The HTML report and 3-D views: the figures' colours against closed-form distances, the
pages' sections, one-line refusals, and (in test_demo) the demo's report in a real browser."""

import json
import re

import numpy as np
import trimesh
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.geometry import Sphere
from rfsdf.viz.scene3d import decimated, error_figure, observed_figure

RADIUS = 0.02


def _face_values(figure, trace=0) -> np.ndarray:
    return np.asarray(figure.data[trace].intensity, float)


def test_error_colours_are_the_signed_distance_to_the_truth_in_mm():
    grown = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS + 0.002)
    figure = error_figure(grown, Sphere(RADIUS), "a sphere grown by 2 mm")
    # face centres sit slightly inside the circumscribed sphere: 2 mm minus the chord sag
    sag_mm = (RADIUS + 0.002 - np.linalg.norm(grown.triangles_center, axis=1)) * 1e3
    np.testing.assert_allclose(_face_values(figure), 2.0 - sag_mm, atol=1e-4)
    assert figure.data[0].colorbar.title.text.endswith("[mm]")
    shrunk = error_figure(trimesh.creation.icosphere(4, radius=RADIUS - 0.003), Sphere(RADIUS), "shrunk")
    assert (_face_values(shrunk) < -2.9).all()


def test_observed_colours_follow_the_mask_and_the_title_gives_its_area():
    box = trimesh.creation.box(extents=(0.04, 0.04, 0.02))  # top: 16 of 64 cm^2
    top = lambda points, normals: normals[:, 2] > 0.5  # noqa: E731
    figure = observed_figure(box, top, "top face")
    np.testing.assert_array_equal(_face_values(figure), (box.face_normals[:, 2] > 0.5).astype(float))
    assert "(25% of its area observed)" in figure.layout.title.text


def test_big_meshes_are_decimated_to_the_face_budget():
    mesh = trimesh.creation.icosphere(subdivisions=5)  # 20480 faces
    small = decimated(mesh, 2000)
    assert len(small.faces) <= 2000 and small.is_watertight
    assert decimated(mesh, 10**6) is mesh


def test_view_writes_a_self_contained_page_for_a_ply(tmp_path):
    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=3, radius=0.021).export(path)
    runner = CliRunner()
    plain = runner.invoke(main, ["view", str(path)])
    assert plain.exit_code == 0, plain.output
    page = (tmp_path / "ball.html").read_text()
    assert "<!DOCTYPE html>" in page and 'id="views3d"' in page and "Mesh3d".lower() in page.lower()
    assert re.search(r"<script[^>]*src=", page) is None  # plotly.js is inline: the page opens with no network
    scored = runner.invoke(main, ["view", str(path), "--scene", "sphere", "--out", str(tmp_path / "v.html")])
    assert scored.exit_code == 0, scored.output
    assert "signed distance" in (tmp_path / "v.html").read_text()


def test_report_of_a_reconstruction_run(tmp_path, tiny_files):
    run = tmp_path / "run"
    runner = CliRunner()
    fit = runner.invoke(main, ["reconstruct", str(tiny_files / "data.h5"), "--out", str(run), "--image",
                               str(tiny_files / "image.h5"),
                               "--config", str(tiny_files / "tiny.toml")])
    assert fit.exit_code == 0, fit.output
    result = runner.invoke(main, ["report", str(run)])
    assert result.exit_code == 0, result.output
    page = (run / "report.html").read_text()
    for key in ("summary", "slices", "training", "views3d"):
        assert f'id="{key}"' in page, key
    assert "data:image/png;base64," in page and "[field]" in page


def test_report_refuses_bad_folders_in_one_line(tmp_path):
    runner = CliRunner()
    neither = runner.invoke(main, ["report", str(tmp_path)])
    assert neither.exit_code == 2 and neither.output.count("\n") == 1
    assert "neither a demo folder" in neither.output
    (tmp_path / "demo-settings.json").write_text(json.dumps({"scene": "objects", "radar": "near-77g"}))
    unfinished = runner.invoke(main, ["report", str(tmp_path)])
    assert unfinished.exit_code == 2 and "has not finished" in unfinished.output
    (tmp_path / "metrics.json").write_text(json.dumps({"methods": {"neural": {"label": "x"}}}))
    crafted = runner.invoke(main, ["report", str(tmp_path)])
    assert crafted.exit_code == 2 and crafted.output.count("\n") == 1, crafted.output
    assert "metrics.json: methods.neural.full: Field required" in crafted.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo-settings.json", "metrics.json"]  # nothing written
    not_a_mesh = tmp_path / "x.ply"
    not_a_mesh.write_text("ply\nformat nonsense\n")
    bad = runner.invoke(main, ["view", str(not_a_mesh)])
    assert bad.exit_code == 2 and bad.output.count("\n") == 1 and "x.ply" in bad.output, bad.output
