"""Hostile input: one 'error:' line, exit code 2, and no file created or changed."""

import hashlib
import os

import pytest
from click.testing import CliRunner

from rfsdf.cli import main


def _snapshot(folder) -> dict:
    """Every file under ``folder`` and a digest of its bytes."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _refused(args, folder, *, cwd=None) -> str:
    """Run the CLI; assert one error line, exit 2 and nothing written under ``folder``."""
    before = _snapshot(folder)
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        result = CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(old)
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error: ") and result.output.count("\n") == 1, result.output
    assert _snapshot(folder) == before
    return result.output


def test_a_scene_name_cannot_escape_the_output_folder(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    (work / "s.toml").write_text(
        'name = "../escaped"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "ball"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02 }\n')
    line = _refused(["scene", "show", "s.toml"], tmp_path, cwd=work)
    assert "s.toml: name:" in line and "plain name" in line


@pytest.mark.parametrize("case", ["image", "simulate", "import", "reconstruct", "mesh"])
def test_an_output_that_is_an_input_is_refused(tmp_path, tiny_files, case):
    scene = tmp_path / "scene.toml"
    scene.write_text(
        'name = "ball"\n[bounds]\nlower_m = [-0.1, -0.1, -0.1]\nupper_m = [0.1, 0.1, 0.1]\n'
        '[[objects]]\nname = "ball"\nmaterial = "metal"\nshape = { type = "sphere", radius_m = 0.02 }\n')
    run = tmp_path / "run"
    run.mkdir()
    (run / "checkpoint.pt").write_bytes(b"not a checkpoint")
    data = tmp_path / "data.h5"
    args = {"image": ["image", data, "--out", data, "--bounds", "-0.05,-0.05,-0.05,0.05,0.05,0.05"],
            "simulate": ["simulate", scene, "--out", scene],
            "import": ["import-fmcw", data, "--out", data],
            "reconstruct": ["reconstruct", data, "--out", tmp_path / "tiny.toml", "--config", tmp_path / "tiny.toml"],
            "mesh": ["mesh", run, "--out", run / "checkpoint.pt"]}[case]
    assert "would destroy the input" in _refused(args, tmp_path)
