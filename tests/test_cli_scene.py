"""The CLI: scene show writes a picture; bad input is one line and exit code 2."""

from click.testing import CliRunner

from rfsdf.cli import main


def test_scene_show_writes_png(tmp_path):
    out = tmp_path / "s.png"
    result = CliRunner().invoke(main, ["scene", "show", "sphere", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "ball" in result.output and out.read_bytes()[:4] == b"\x89PNG"


def test_scene_show_bad_input_is_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [\n")
    result = CliRunner().invoke(main, ["scene", "show", str(bad)])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "bad.toml" in result.output
    assert "Traceback" not in result.output


def test_version_names_the_package_and_the_checkouts_commit():
    """`rfsdf --version`: the package version, and from a git checkout the commit it runs
    (git describe, -dirty with uncommitted changes), so a result can be traced to its code."""
    import subprocess
    from pathlib import Path

    from rfsdf import __version__

    result = CliRunner().invoke(main, ["--version"])
    assert result.exit_code == 0 and result.output.startswith(f"rfsdf {__version__}"), result.output
    root = Path(__file__).resolve().parents[1]
    head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                          text=True, check=False).stdout.strip()
    if head:  # a checkout (CI clones one)
        assert f"(commit {head}" in result.output, result.output
