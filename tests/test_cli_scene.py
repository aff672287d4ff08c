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
