"""The documentation site: it builds with no warning, its reference lists every CLI option and
every file-format key, and every tutorial's commands run as written.

A tutorial page runs like this: a fenced block with a title (```toml title="shelf.toml"```) is
written to that file, and each ```bash``` block runs, in page order, in one folder per page,
under ``bash -euo pipefail`` with this environment's ``rfsdf`` and ``python`` first on the
PATH. ```text``` blocks are shown, not run (a full-size run, a cluster address).
"""

import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest

from rfsdf.cli import main
from rfsdf.scene_model import _KEYS as FREE_PARAMETER_KEYS

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))
FORMATS = [("rfsdf.scene_spec", "SceneSpec"), ("rfsdf.radar.system", "RadarSpec"),
           ("rfsdf.recon.config", "ReconConfig"), ("rfsdf.sweep", "SweepSpec"), ("rfsdf.sweep", "JobSpec")]
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


def _environment() -> dict:
    bin_dir = str(Path(sys.executable).parent)
    return {**os.environ, "PATH": bin_dir + os.pathsep + os.environ.get("PATH", ""), "NO_MKDOCS_2_WARNING": "1"}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built once with ``mkdocs build --strict`` (a warning fails the build)."""
    out = tmp_path_factory.mktemp("site")
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                            cwd=ROOT, env=_environment(), capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return out


def _text(page: Path) -> str:
    return page.read_text(encoding="utf-8")


def _commands(group: click.Group, path=()):
    for name, command in group.commands.items():
        yield (*path, name), command
        if isinstance(command, click.Group):
            yield from _commands(command, (*path, name))


def test_the_cli_reference_lists_every_command_and_option(site):
    page = _text(site / "reference" / "cli" / "index.html")
    missing = [f"rfsdf {' '.join(path)} {option}" for path, command in _commands(main)
               for parameter in command.params if isinstance(parameter, click.Option)
               for option in parameter.opts if option not in page]
    missing += [f"rfsdf {' '.join(path)}" for path, _ in _commands(main) if f"rfsdf {' '.join(path)}" not in page]
    assert not missing, f"not in the CLI reference: {missing}"


def test_the_format_reference_lists_every_key_of_every_file(site):
    hooks = _hooks()
    page = _text(site / "reference" / "formats" / "index.html")
    missing = []
    for module, name in FORMATS:
        models: list = []
        hooks._collect(getattr(importlib.import_module(module), name), models)
        missing += [f"{model.__name__}.{key}" for model in models for key in model.model_fields
                    if f"<code>{key}</code>" not in page or f"<code>{model.__name__}</code>" not in page]
    missing += [f"scene model {key}" for key in FREE_PARAMETER_KEYS if f"<code>{key}</code>" not in page]
    assert not missing, f"not in the file-format reference: {missing}"


def test_the_api_reference_documents_the_public_layers(site):
    page = _text(site / "reference" / "api" / "index.html")
    names = ("geometry.sphere_trace", "materials.fresnel", "radar.simulate.simulate", "radar.matched_filter",
             "scene.Scene", "scene_model.SceneModel", "recon.Trainer", "metrics.compare_meshes", "demo.run_demo")
    missing = [name for name in names if f'id="rfsdf.{name}"' not in page]
    assert not missing, f"not in the API reference: {missing}"


def test_every_measured_result_names_the_commit_that_wrote_it(site):
    """The results page lists each file under benchmarks/results/ and the figures with a commit
    hash, read from git (the suite runs in a checkout)."""
    page = _text(site / "results" / "benchmarks" / "index.html")
    files = [*(ROOT / "benchmarks" / "results").glob("*.json"), *(ROOT / "docs" / "figures").glob("*.png")]
    rows = {name: re.search(rf"<code>{re.escape(name)}</code></td>\s*<td><code>([0-9a-f]{{7,}})</code>", page)
            for name in (path.relative_to(ROOT).as_posix() for path in files)}
    assert files and not [name for name, row in rows.items() if row is None]


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_tutorial_is_in_the_test_below():
    assert {page.name for page in TUTORIALS} == set(OUTPUTS)


@pytest.mark.parametrize("page", TUTORIALS, ids=lambda page: page.stem)
def test_a_tutorials_commands_run_as_written(page, tmp_path):
    ran = 0
    for language, title, body in FENCE.findall(_text(page)):
        if title:
            (tmp_path / title).write_text(body)
        elif language == "bash":
            result = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=tmp_path, env=_environment(),
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
