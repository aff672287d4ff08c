import io
import json
import math
import re

import numpy as np
import pydantic
import pytest
import trimesh
from click.testing import CliRunner
from matplotlib.image import imread

from rfsdf.cli import main
from rfsdf.material_estimates import READOUT_CEILING

METHODS = ("neural", "neural_warm_start", "mf_threshold", "clean_threshold", "clean_detection")


@pytest.fixture(scope="module")
def quick_demo(tmp_path_factory):
    """A quick demo's folder and the CLI result that made it (run once for this module)."""
    out = tmp_path_factory.mktemp("quick") / "demo"
    return out, CliRunner().invoke(main, ["demo", "--quick", "--out", str(out)])


def test_quick_demo_runs_end_to_end_and_resumes(quick_demo):
    runner = CliRunner()
    out, result = quick_demo
    assert result.exit_code == 0, result.output
    for name in ("measurements.h5", "image.h5", "scene-slices.png", "image-mip.png", "clean-mip.png", "neural.ply",
                 "neural-warm-start.ply",
                 "mf-threshold.ply", "clean-threshold.ply", "clean-detection.ply", "recon-slices.png", "training.png",
                 "metrics.json", "run/checkpoint.pt", "run/log.csv", "demo-settings.json", "report.html",
                 "object-slices.png"):
        assert (out / name).exists(), name
    assert f"report (open in a browser): {out / 'report.html'}" in result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["methods"]) == set(METHODS)
    for method in METHODS:
        scores = metrics["methods"][method]
        assert math.isfinite(scores["full"]["chamfer_l1_mm"]) and 0 <= scores["full"]["fscore"] <= 1
        assert set(scores["objects"]) == {"metal_ball", "wood_block", "glass_jar", "concrete_ring", "notched_block"}
        assert 0 < scores["observed_fraction"] < 1
    baseline = metrics["methods"]["mf_threshold"]
    assert baseline["fraction"] in map(float, baseline["sweep_chamfer_mm"])
    assert metrics["fit_steps"] == 6 and metrics["seconds_per_step"] > 0
    assert "GeRaF (neural)" in result.output and "recall metal_ball" in result.output
    materials = metrics["materials"]
    assert [o["name"] for o in materials["objects"]] == list(scores["objects"])
    for estimate in materials["objects"]:
        assert sum(estimate["probabilities"].values()) == pytest.approx(1.0, abs=1e-6)
        assert estimate["predicted"] in estimate["probabilities"] and 0 <= estimate["observed_fraction"] <= 1
        # the class is the closed-form readout's where it reads a passive surface, else the head's
        assert (estimate["source"] == "data") is (estimate["readout"] is not None
                                                  and 0 < estimate["readout"] <= READOUT_CEILING), estimate
    assert {o["true"] for o in materials["objects"]} == {"metal", "wood", "glass", "concrete", "plasterboard"}
    # the default scene names its metal ball as the calibration reference
    assert len(materials["components"]) >= 1 and materials["calibration"].startswith("reference metal_ball=metal")
    assert [o["name"] for o in materials["objects"] if o["reference"]] == ["metal_ball"]
    vertices = trimesh.load(out / "neural.ply", force="mesh").metadata["_ply_raw"]["vertex"]["data"]
    assert {"material_class", "reflectivity", "eps_real"} <= set(vertices.dtype.names)
    assert vertices["material_class"].max() < 5 and ((vertices["reflectivity"] >= 0) & (vertices["reflectivity"] <= 1)).all()
    table = runner.invoke(main, ["materials", str(out)])
    assert table.exit_code == 0 and "concrete_ring" in table.output and "calibration: reference" in table.output
    log = result.stderr  # not a terminal, as in a batch job's log: no redraws, few lines
    assert "\r" not in log and log.count("\n") < 200, log[:2000]

    # a rerun into the folder reuses the finished fit: tests/test_sweep.py (a sweep's rerun);
    # another scene into it is refused before anything is written
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    other = runner.invoke(main, ["demo", "--quick", "--scene", "sphere", "--out", str(out)])
    assert other.exit_code == 2 and other.output.count("\n") == 1, other.output
    assert "holds a demo of other settings (scene: 'objects' -> 'sphere')" in other.output
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == before  # nothing written


def test_the_demo_report_holds_every_section_and_no_network_reference(quick_demo):
    out, _ = quick_demo
    page = (out / "report.html").read_text()
    for key in ("summary", "images", "slices", "training", "metrics", "materials", "views3d"):
        assert f'<section id="{key}">' in page, key
    for name in ("metal_ball", "notched_block", "GeRaF (neural)", "CLEAN detection", "signed distance",
                 "observed", "range resolution c/2B = 37.5 mm", "lambda R / 2D = 11.9 mm at R = 0.75 m", "Tx", "Rx"):
        assert name in page, name
    assert page.count('class="plotly-graph-div"') == 5  # errors of two meshes, materials, observed, views
    assert "coloured by the class nearest its fitted |Gamma|" in page and "accuracy" in page
    assert re.search(r"<(script|link|img)[^>]*(src|href)=\"?https?:", page) is None  # all inline: no network


def test_the_demo_report_draws_in_a_real_browser(quick_demo, browser, tmp_path):
    """Headless Chromium opens the report without console errors, and the first 3-D view
    draws a canvas whose pixels are not all background; the screenshots are kept."""
    out, _ = quick_demo
    page = browser.new_page(viewport={"width": 1300, "height": 900})
    problems = []
    page.on("console", lambda message: problems.append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: problems.append(str(error)))
    page.goto((out / "report.html").as_uri())
    canvas = page.locator(".js-plotly-plot .gl-container canvas").first
    canvas.wait_for(timeout=30_000)
    page.wait_for_timeout(1500)  # let WebGL draw
    pixels = imread(io.BytesIO(canvas.screenshot(path=str(tmp_path / "view3d.png"))))[..., :3]
    page.screenshot(path=str(tmp_path / "report.png"), full_page=True)
    colours, counts = np.unique((pixels * 255).astype(np.uint8).reshape(-1, 3), axis=0, return_counts=True)
    background = colours[counts.argmax()].astype(float)
    drawn = (np.abs(pixels * 255 - background).sum(-1) > 30).mean()
    assert problems == []
    assert drawn > 0.02, f"the 3-D view is blank ({drawn:.2%} of its pixels differ from the background)"


def test_demo_refuses_bad_scene_and_radar_names_in_one_line(tmp_path):
    runner = CliRunner()
    for option, name in (("--scene", "no-such-scene"), ("--radar", "no-such-radar")):
        result = runner.invoke(main, ["demo", "--quick", option, name, "--out", str(tmp_path / "d")])
        assert result.exit_code == 2 and result.output.startswith("error: no-such-") and result.output.count("\n") == 1
        assert not (tmp_path / "d").exists()


def test_the_demo_calibrates_by_the_scenes_reference_unless_told_otherwise():
    """The default scene names its metal ball: the demo's config renders it as metal; not
    with ``relative``, not over a reference already given, not without a material head; with a
    known gain the config carries it (given after the relative fit) and no reference; both in one
    config are refused in one line."""
    import dataclasses

    from rfsdf.demo import DemoSettings, with_calibration
    from rfsdf.recon import ReconConfig
    from rfsdf.scene import load_scene

    scene, settings, config = load_scene("objects"), DemoSettings(), ReconConfig()
    assert with_calibration(config, scene, settings).calibration.reference == "metal_ball=metal"
    assert with_calibration(config, scene, dataclasses.replace(settings, relative=True)).calibration.reference is None
    given = ReconConfig.model_validate({"calibration": {"reference": "glass_jar=glass"}})
    assert with_calibration(given, scene, settings).calibration.reference == "glass_jar=glass"
    headless = ReconConfig.model_validate({"field": {"materials": []}})
    assert with_calibration(headless, scene, settings).calibration.reference is None
    assert with_calibration(config, load_scene("sphere"), settings).calibration.reference is None
    known = with_calibration(config, scene, dataclasses.replace(settings, gain=1.0)).calibration
    assert (known.gain, known.reference) == (1.0, None)
    with pytest.raises(pydantic.ValidationError, match="one calibration, not both"):
        ReconConfig.model_validate({"calibration": {"reference": "glass_jar=glass", "gain": 1.0}})


def test_a_folder_stamped_before_a_setting_existed_takes_its_default(tmp_path):
    """A run folder whose settings stamp lacks a setting added since (a model demo's
    ``beams``) is the same run when that setting is at its default, another run when not."""
    import dataclasses

    from rfsdf.demo import SETTINGS_NAME, claim_folder
    from rfsdf.errors import RfsdfError
    from rfsdf.model_demo import ModelDemoSettings

    settings = ModelDemoSettings()
    claim_folder(tmp_path, settings)
    stamp = json.loads((tmp_path / SETTINGS_NAME).read_text())
    del stamp["beams"]
    (tmp_path / SETTINGS_NAME).write_text(json.dumps(stamp))
    claim_folder(tmp_path, settings)  # the same run
    with pytest.raises(RfsdfError, match="beams: False -> True"):
        claim_folder(tmp_path, dataclasses.replace(settings, beams=True))
