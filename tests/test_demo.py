import json
import math

from click.testing import CliRunner

from rfsdf.cli import main


def test_quick_demo_runs_end_to_end_and_resumes(tmp_path):
    runner = CliRunner()
    out = tmp_path / "demo"
    result = runner.invoke(main, ["demo", "--quick", "--out", str(out)])
    assert result.exit_code == 0, result.output
    for name in ("measurements.h5", "image.h5", "scene-slices.png", "image-mip.png", "neural.ply", "baseline.ply",
                 "recon-slices.png", "training.png", "metrics.json", "run/checkpoint.pt", "run/log.csv"):
        assert (out / name).exists(), name
    metrics = json.loads((out / "metrics.json").read_text())
    for method in ("neural", "baseline"):
        assert math.isfinite(metrics[method]["chamfer_l1_mm"]) and 0 <= metrics[method]["fscore"] <= 1
    assert metrics["baseline"]["fraction"] in map(float, metrics["baseline"]["sweep_chamfer_mm"])
    assert "GeRaF (neural)" in result.output and "Chamfer-L1" in result.output
    log_lines = (out / "run" / "log.csv").read_text().count("\n")

    again = runner.invoke(main, ["demo", "--quick", "--out", str(out)])  # the finished fit is reused
    assert again.exit_code == 0, again.output
    assert (out / "run" / "log.csv").read_text().count("\n") == log_lines
