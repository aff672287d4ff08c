"""Every tutorial's commands run as written: a fenced block with a title (```toml
title="shelf.toml"```) is written to that file, and each ```bash``` block runs, in page order, in
one folder per page, under ``bash -euo pipefail`` with this environment's ``rfsdf`` and
``python`` first on the PATH. ```text``` blocks are shown, not run (a full-size run, a cluster
address).
"""

import json
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))
FENCE = re.compile(r'^```(\w+)(?: title="([^"]+)")?\n(.*?)^```$', re.MULTILINE | re.DOTALL)
# what each tutorial must leave behind, beyond its commands' exit status
OUTPUTS = {
    "own-measurements.md": ["data.h5", "image.h5", "run/checkpoint.pt", "ball.ply"],
    "own-radar.md": ["ball.h5", "ball-image.h5", "ball-image.mip.png"],
    "own-scene.md": ["shelf-slices.png", "shelf-demo/metrics.json", "shelf-demo/report.html"],
    "room.md": ["corner-demo/metrics.json", "corner-fit/primitive.json", "corner-fit/fitted-scene.toml"],
    "sweep.md": ["seeds/summary.csv", "seeds/summary.png"],
    "ti-capture.md": ["capture/adc_data.bin", "data.h5", "image.h5", "image.mip.png", "run/mesh.ply"],
}


def test_every_tutorial_is_in_the_test_below():
    assert {page.name for page in TUTORIALS} == set(OUTPUTS)


@pytest.mark.parametrize("page", TUTORIALS, ids=lambda page: page.stem)
def test_a_tutorials_commands_run_as_written(page, tmp_path, tool_environment):
    ran = 0
    for language, title, body in FENCE.findall(page.read_text(encoding="utf-8")):
        if title:
            (tmp_path / title).write_text(body)
        elif language == "bash":
            result = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=tmp_path, env=tool_environment,
                                    capture_output=True, text=True)
            assert result.returncode == 0, f"{page.name}: {body}\n{result.stdout}\n{result.stderr}"
            ran += 1
    assert ran > 0
    missing = [name for name in OUTPUTS[page.name] if not (tmp_path / name).is_file()]
    assert not missing, f"{page.name} did not write {missing}"
    if page.name == "own-scene.md":  # the demo scored the scene file's own objects, by name
        metrics = json.loads((tmp_path / "shelf-demo" / "metrics.json").read_text())
        assert set(metrics["methods"]["neural"]["objects"]) == {"can", "block", "pane"}
    if page.name == "room.md":  # as the page says: both walls within a centimetre from 10 cm off
        for parameter in json.loads((tmp_path / "corner-fit" / "primitive.json").read_text())["free"]:
            errors = [abs(fitted - truth) for fitted, truth in zip(parameter["fitted"], parameter["truth"])]
            assert max(errors) < 0.01, parameter
