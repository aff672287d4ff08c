"""The documentation site: it builds with no warning, and its reference lists every CLI option,
every file-format key and every measured result's commit. The tutorials' commands run in
test_tutorials.py (their own units for the test workers: none needs the site).
"""

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import click
import pytest

from rfsdf.cli import main
from rfsdf.scene_model import _KEYS as FREE_PARAMETER_KEYS

ROOT = Path(__file__).resolve().parents[1]
FORMATS = [("rfsdf.scene_spec", "SceneSpec"), ("rfsdf.radar.system", "RadarSpec"),
           ("rfsdf.recon.config", "ReconConfig"), ("rfsdf.sweep", "SweepSpec"), ("rfsdf.sweep", "JobSpec")]


@pytest.fixture(scope="module")
def site(tmp_path_factory, tool_environment) -> Path:
    """The site, built once with ``mkdocs build --strict`` (a warning fails the build)."""
    out = tmp_path_factory.mktemp("site")
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                            cwd=ROOT, env=tool_environment, capture_output=True, text=True)
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
