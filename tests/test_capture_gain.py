"""The radar gain from a separate capture of a known target (`rfsdf calibrate`), and
`reconstruct --gain` reading materials with it: a known gain recovered, a misplaced target
and a capture of another radar refused in one line."""

import dataclasses
import json
import re

import pytest
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.errors import RfsdfError
from rfsdf.radar import Measurements, simulate, write_measurements
from rfsdf.radar.capture_gain import acquisition_digest, capture_gain, read_capture_gain
from rfsdf.recon.checkpoint import CHECKPOINT_NAME, read_checkpoint
from rfsdf.scene import load_scene

GAIN = 3.7  # the radar's, unknown to the calibration


def _sphere_scene(tmp_path, centre=(0.0, 0.0, 0.0)) -> str:
    path = tmp_path / f"sphere-{centre[0]:g}.toml"
    path.write_text('name = "cal-sphere"\n[bounds]\nlower_m = [-0.06, -0.06, -0.06]\nupper_m = [0.06, 0.06, 0.06]\n'
                    '[[objects]]\nname = "ball"\nmaterial = "metal"\n'
                    f'shape = {{ type = "sphere", radius_m = 0.02, center_m = {list(centre)} }}\n')
    return str(path)


def _capture(tmp_path, radar) -> Measurements:
    """The metal ball captured by ``radar`` with the radar's gain and noise: the physics, so
    samples lambda/12 apart (another sampling than the reference's)."""
    measured = simulate(load_scene(_sphere_scene(tmp_path)), radar, seed=5, samples_per_wavelength=12)
    return dataclasses.replace(measured, data=measured.data * GAIN)


def test_a_capture_of_a_metal_sphere_gives_the_gain_and_a_misplaced_one_is_refused(tmp_path, tiny_radar):
    """The gain comes back within 2 % (measured: 3.68 for 3.7; two samplings of the ball and
    the radar's 40 dB noise differ by about that); the ball 1 cm from where the scene puts it
    explains too little."""
    capture = _capture(tmp_path, tiny_radar)
    measured = capture_gain(capture, load_scene(_sphere_scene(tmp_path)))
    assert measured.gain == pytest.approx(GAIN, rel=0.02) and measured.explained > 0.95
    assert measured.acquisition == acquisition_digest(tiny_radar.acquisition())
    with pytest.raises(ValueError, match=r"explains \d+% of the capture's energy \(at least 50% needed\)"):
        capture_gain(capture, load_scene(_sphere_scene(tmp_path, (0.0, 0.0, 0.01))))


def test_calibrate_then_reconstruct_with_the_gain_and_refuse_another_radars_data(tmp_path, tiny_radar, tiny_files):
    """`rfsdf calibrate` writes the gain file; `reconstruct --gain` fits relative (no gain held)
    with that gain in its config, which `rfsdf materials` reads the materials in; data of another
    radar are one error line, and nothing is written."""
    write_measurements(tmp_path / "capture.h5", _capture(tmp_path, tiny_radar))
    runner = CliRunner()
    result = runner.invoke(main, ["calibrate", str(tmp_path / "capture.h5"), "--scene", _sphere_scene(tmp_path),
                                  "--out", str(tmp_path / "gain.json")])
    assert result.exit_code == 0, result.output
    assert "explains" in result.output
    gain = json.loads((tmp_path / "gain.json").read_text())["gain"]
    assert gain == pytest.approx(GAIN, rel=0.02)

    data = simulate(load_scene("sphere"), tiny_radar, seed=1)
    write_measurements(tmp_path / "sphere-data.h5", data)
    result = runner.invoke(main, ["reconstruct", str(tmp_path / "sphere-data.h5"), "--gain", str(tmp_path / "gain.json"),
                                  "--config", str(tiny_files / "tiny.toml"), "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    state = read_checkpoint(tmp_path / "run" / CHECKPOINT_NAME, "cpu")
    assert state["gain"] is None and state["config"]["calibration"]["gain"] == gain
    result = runner.invoke(main, ["materials", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert f"calibration: known radar gain {gain:g}, given after the relative fit (its own gain" in result.output

    result = runner.invoke(main, ["reconstruct", str(tiny_files / "data.h5"), "--gain", str(tmp_path / "gain.json"),
                                  "--config", str(tiny_files / "tiny.toml"), "--out", str(tmp_path / "other")])
    assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
    assert "acquisition: the gain was measured with another radar" in result.output
    assert not (tmp_path / "other").exists()


@pytest.mark.parametrize("content, message", [
    ("not json", "not a gain file (JSON) from rfsdf calibrate"),
    ("[1, 2]", "expected an object"),
    ('{"gain": -1, "explained": 0.9, "acquisition": "0123456789abcdef", "capture": "c", "scene": "s"}',
     "gain: Input should be greater than 0"),
    ('{"gain": 2, "explained": 0.9, "acquisition": "xyz", "capture": "c", "scene": "s"}', "acquisition: String"),
])
def test_a_bad_gain_file_is_one_line(tmp_path, content, message):
    path = tmp_path / "gain.json"
    path.write_text(content)
    with pytest.raises(RfsdfError, match=re.escape(message)):
        read_capture_gain(path)
