"""TI captures: the DCA1000 .bin layouts byte for byte as TI documents them, mmWave Studio's and
the DCA1000 CLI's JSON, pose files, the board's antennas, and a capture written from modelled
data read back to the same measurements; every bad input one error line."""

import json
import pathlib
import pickle
import re

import numpy as np
import pytest
import torch

from rfsdf.errors import RfsdfError
from rfsdf.radar.acquisition import SPEED_OF_LIGHT
from rfsdf.radar.boards import board, board_positions
from rfsdf.radar.formats.dca1000 import AdcLayout, read_bin, read_cf_json, write_bin, write_cf_json
from rfsdf.radar.formats.mmwave_studio import ChirpConfig, read_mmwave_json, read_setup_json, write_mmwave_json
from rfsdf.radar.formats.poses import read_poses, write_poses
from rfsdf.radar.formats.ti_capture import CaptureGeometry, import_ti_capture, write_ti_capture
from rfsdf.radar.operator import SensingOperator

# GeRaF's capture (IWR1443, one Tx, four Rx, one chirp a frame every 3 ms), with 16 samples
CHIRP = ChirpConfig(start_hz=77e9, slope_hz_per_s=70.15e12, sample_rate_hz=10e6, samples=16, adc_start_s=6e-6,
                    idle_s=7e-6, ramp_end_s=57.14e-6, rx_mask=0xF, tx_mask=0x1, complex=True, chirps_per_loop=1,
                    loops=1, frames=0, frame_period_s=3e-3, lanes=4)


def _refused_in_one_line(args, message, out):
    """``rfsdf ARGS`` exits 2 with one line matching ``message`` and writes no ``out``."""
    from click.testing import CliRunner

    from rfsdf.cli import main

    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2 and result.output.count("\n") == 1, result.output
    assert re.search(message, result.output), result.output
    assert not out.exists()


def _int16(path, values):
    np.asarray(values, dtype="<i2").tofile(path)


def test_the_four_lane_complex_layout_interleaves_the_rx_of_each_time_sample(tmp_path):
    """xWR14xx: each time sample is [I0 I1 I2 I3 Q0 Q1 Q2 Q3]; samples, then chirps."""
    layout = AdcLayout(lanes=4, complex=True, rx=4, samples=2, chirps=2)
    expected = np.zeros((1, 2, 4, 2), complex)
    values = []
    for chirp in range(2):
        for n in range(2):
            i = [100 * chirp + 10 * n + k for k in range(4)]
            q = [-(100 * chirp + 10 * n + k) - 1 for k in range(4)]
            values += i + q
            expected[0, chirp, :, n] = np.array(i) + 1j * np.array(q)
    _int16(tmp_path / "a.bin", values)
    assert np.array_equal(read_bin(tmp_path / "a.bin", layout), expected)


def test_the_two_lane_complex_layout_pairs_samples_of_each_rx_in_turn(tmp_path):
    """xWR16xx/18xx/68xx: each chirp holds Rx0's samples, then Rx1's, as [I(n) I(n+1) Q(n) Q(n+1)]."""
    layout = AdcLayout(lanes=2, complex=True, rx=2, samples=4, chirps=1)
    values = [1, 2, -1, -2, 3, 4, -3, -4,  # Rx0: samples 0, 1 then 2, 3
              5, 6, -5, -6, 7, 8, -7, -8]  # Rx1
    _int16(tmp_path / "a.bin", values)
    expected = np.array([[1 - 1j, 2 - 2j, 3 - 3j, 4 - 4j], [5 - 5j, 6 - 6j, 7 - 7j, 8 - 8j]])
    assert np.array_equal(read_bin(tmp_path / "a.bin", layout)[0, 0], expected)


def test_real_layouts_store_one_value_a_sample(tmp_path):
    _int16(tmp_path / "four.bin", [0, 1, 2, 3, 10, 11, 12, 13])  # two time samples of four lanes
    four = read_bin(tmp_path / "four.bin", AdcLayout(lanes=4, complex=False, rx=4, samples=2, chirps=1))
    assert np.array_equal(four[0, 0], [[0, 10], [1, 11], [2, 12], [3, 13]])
    _int16(tmp_path / "two.bin", [0, 1, 2, 10, 11, 12])  # Rx0's three samples, then Rx1's
    two = read_bin(tmp_path / "two.bin", AdcLayout(lanes=2, complex=False, rx=2, samples=3, chirps=1))
    assert np.array_equal(two[0, 0], [[0, 1, 2], [10, 11, 12]]) and two.dtype == np.float32


@pytest.mark.parametrize("lanes, complex_", [(4, True), (4, False), (2, True), (2, False)])
def test_every_layout_reads_back_what_it_wrote(tmp_path, lanes, complex_):
    layout = AdcLayout(lanes=lanes, complex=complex_, rx=4, samples=8, chirps=3)
    rng = np.random.default_rng(0)
    cube = rng.integers(-32768, 32768, (5, 3, 4, 8)).astype(float)
    if complex_:
        cube = cube + 1j * rng.integers(-32768, 32768, cube.shape)
    write_bin(tmp_path / "a.bin", cube, layout)
    assert (tmp_path / "a.bin").stat().st_size == cube.size * (4 if complex_ else 2)
    assert np.array_equal(read_bin(tmp_path / "a.bin", layout), cube)


def test_a_bin_that_is_not_whole_frames_or_a_bad_layout_is_one_line(tmp_path):
    layout = AdcLayout(lanes=2, complex=True, rx=4, samples=8, chirps=1)
    _int16(tmp_path / "a.bin", np.zeros(4 * 8 * 2 + 2))
    with pytest.raises(RfsdfError, match=r"a\.bin: size 132 bytes is not a whole number of frames of 128 bytes"):
        read_bin(tmp_path / "a.bin", layout)
    with pytest.raises(RfsdfError, match="cannot read"):
        read_bin(tmp_path / "missing.bin", layout)
    for bad in ({"lanes": 3}, {"lanes": 4, "rx": 2}, {"samples": 7}):
        with pytest.raises(ValueError):
            AdcLayout(**{"lanes": 2, "complex": True, "rx": 4, "samples": 8, "chirps": 1, **bad})
    with pytest.raises(ValueError, match="int16 range"):
        write_bin(tmp_path / "b.bin", np.full((1, 1, 4, 8), 40_000 + 0j), layout)
    assert not (tmp_path / "b.bin").exists()


def test_the_mmwave_json_gives_the_chirp_and_each_sample_its_frequency(tmp_path):
    write_mmwave_json(tmp_path / "a.mmwave.json", CHIRP)
    chirp = read_mmwave_json(tmp_path / "a.mmwave.json")
    for name in CHIRP.__dataclass_fields__:
        assert getattr(chirp, name) == pytest.approx(getattr(CHIRP, name), rel=1e-12), name
    f = chirp.frequencies_hz()  # the first sample at f0 + S t_adc, then S / f_s apart
    assert f[0] == pytest.approx(77e9 + 70.15e12 * 6e-6) and np.diff(f) == pytest.approx(70.15e12 / 10e6)
    assert (chirp.rx, chirp.chirps) == (4, 1)
    document = json.loads((tmp_path / "a.mmwave.json").read_text())
    document["mmWaveDevices"] = document["mmWaveDevices"][0]  # some versions write one device as an object
    (tmp_path / "b.mmwave.json").write_text(json.dumps(document))
    assert read_mmwave_json(tmp_path / "b.mmwave.json") == chirp


@pytest.mark.parametrize("edit, message", [
    (lambda rf: rf["rlProfiles"][0]["rlProfileCfg_t"].pop("numAdcSamples"),
     r"mmWaveDevices\[0\]\.rfConfig\.rlProfiles\[0\]\.rlProfileCfg_t\.numAdcSamples: missing"),
    (lambda rf: rf["rlProfiles"][0]["rlProfileCfg_t"].update(digOutSampleRate="fast"), "digOutSampleRate: 'fast' is not"),
    (lambda rf: rf["rlProfiles"][0]["rlProfileCfg_t"].update(freqSlopeConst_MHz_usec=0), "must be > 0"),
    (lambda rf: rf["rlAdcOutCfg_t"]["fmt"].update(b2AdcBits=1), "b2AdcBits: 1; only 16-bit"),
    (lambda rf: rf["rlFrameCfg_t"].update(chirpStartIdx=2), "chirpEndIdx: 0 is before chirpStartIdx 2"),
])
def test_a_bad_mmwave_json_names_its_field(tmp_path, edit, message):
    write_mmwave_json(tmp_path / "a.mmwave.json", CHIRP)
    document = json.loads((tmp_path / "a.mmwave.json").read_text())
    edit(document["mmWaveDevices"][0]["rfConfig"])
    (tmp_path / "a.mmwave.json").write_text(json.dumps(document))
    with pytest.raises(RfsdfError, match=message):
        read_mmwave_json(tmp_path / "a.mmwave.json")
    (tmp_path / "b.json").write_text("{not json")
    with pytest.raises(RfsdfError, match="b.json: not JSON"):
        read_mmwave_json(tmp_path / "b.json")


def test_the_dca1000_cli_config_gives_the_lanes(tmp_path):
    for lanes in (2, 4):
        assert read_cf_json(write_cf_json(tmp_path / f"cf{lanes}.json", lanes)) == lanes
    (tmp_path / "bad.json").write_text(json.dumps({"DCA1000Config": {"lvdsMode": 2, "dataFormatMode": 1}}))
    with pytest.raises(RfsdfError, match="dataFormatMode: 1; only 16-bit"):
        read_cf_json(tmp_path / "bad.json")
    (tmp_path / "none.json").write_text(json.dumps({"DCA1000Config": {"dataFormatMode": 3}}))
    with pytest.raises(RfsdfError, match="DCA1000Config.lvdsMode: missing"):
        read_cf_json(tmp_path / "none.json")


def test_poses_per_frame_or_by_time_interpolated_at_the_frames(tmp_path):
    positions = np.column_stack([np.linspace(0, 0.1, 6), np.zeros(6), np.full(6, -0.2)])
    write_poses(tmp_path / "p.csv", positions)
    assert np.array_equal(read_poses(tmp_path / "p.csv", 4), positions[:4])
    # an arm's log every 10 ms, moving 1 m/s along x; frames every 3 ms
    times = 5.0 + np.arange(6) * 0.01
    write_poses(tmp_path / "t.csv", np.column_stack([times - 5.0, np.ones(6), np.zeros(6)]), times)
    frames = read_poses(tmp_path / "t.csv", 17, frame_period_s=3e-3)
    assert frames[:, 0] == pytest.approx(np.arange(17) * 3e-3) and (frames[:, 1] == 1).all()


@pytest.mark.parametrize("text, frames, message", [
    ("x_m,y_m,z_m\n0,0,0\n", 2, "1 poses for 2 frames: the pose file is shorter"),
    ("time_s,x_m,y_m,z_m\n0,0,0,0\n0.01,0,0,0\n", 5, "the poses end at 0.01 s, the 5 frames at 0.012 s"),
    ("x_m,y_m,z_m\n0,0,0\nnan,0,0\n", 2, "row 3: NaN or Inf"),
    ("x_m,y_m\n0,0\n", 1, "header: no column z_m"),
    ("x_m,y_m,z_m\n0,zero,0\n", 1, "row 2: expected numbers"),
])
def test_a_bad_pose_file_is_one_line(tmp_path, text, frames, message):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(RfsdfError, match=message):
        read_poses(tmp_path / "p.csv", frames, frame_period_s=3e-3)


def test_the_iwr1443_rx_lie_on_a_line_from_its_tx():
    """Rx k at 5 mm + (3 - k) lambda/2 from Tx0 (79 GHz) along the Rx axis, whichever way it points."""
    iwr1443 = board("IWR1443")
    half = SPEED_OF_LIGHT / 79e9 / 2
    tx0 = np.array([[0.1, 0.2, 0.3]])
    tx, rx = board_positions(iwr1443, tx0, np.array([0, 0, 1.0]), np.array([1.0, 0, 0.5]), tx_mask=0b111)
    assert rx[0] - tx0 == pytest.approx(np.array([[0.005 + (3 - k) * half, 0, 0] for k in range(4)]))
    assert tx[0, 2] - tx0[0] == pytest.approx([-4 * half, 0, 0]) and abs(tx[0, 1, 1] - 0.2) == pytest.approx(half)
    with pytest.raises(RfsdfError, match="unknown chip 'awr9999'; known: iwr1443, awr1843, iwr6843"):
        board("awr9999")
    with pytest.raises(RfsdfError, match="txChannelEn: 0x8 enables antennas the iwr1443 lacks"):
        board_positions(iwr1443, tx0, np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), tx_mask=0x8)


@pytest.mark.parametrize("name, design_hz", [("awr1843", 79e9), ("iwr6843", 62e9)])
def test_the_three_tx_boards_form_tis_virtual_array(name, design_hz):
    """TI's 2 x 8 virtual array: Tx0's and Tx2's pairs continue one another in a line of eight,
    lambda/2 apart as seen by the phase (midpoints lambda/4 apart); Tx1's four sit over the
    middle four, lambda/4 (midpoint) across; two LVDS lanes."""
    chip = board(name)
    half = SPEED_OF_LIGHT / design_hz / 2
    tx, rx = board_positions(chip, np.zeros((1, 3)), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), tx_mask=0b111)
    centres = (tx[0, :, None] + rx[0, None]) / 2  # (3 Tx, 4 Rx, 3) phase centres
    line = np.sort(np.concatenate([centres[0, :, 0], centres[2, :, 0]]))
    assert np.diff(line) == pytest.approx(np.full(7, half / 2))
    assert np.sort(centres[1, :, 0]) == pytest.approx(line[2:6])
    assert abs(centres[1, :, 1]) == pytest.approx(np.full(4, half / 2)) and centres[[0, 2], :, 1] == pytest.approx(0)
    assert chip.lanes == 2 and chip.conjugate


def _scan(rows=3, cols=4, step=0.97e-3):
    """A raster of Tx0 positions 0.2 m in front of the origin (GeRaF's lambda/4 steps)."""
    x, y = np.meshgrid(np.arange(cols) * step, np.arange(rows) * step, indexing="xy")
    return np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -0.2)])


def test_a_written_capture_imports_as_the_measurements_it_came_from(tmp_path):
    geometry = CaptureGeometry(board("iwr1443"))
    write_poses(tmp_path / "poses.csv", _scan())
    acquisition = geometry.acquisition(CHIRP, _scan())
    points = torch.tensor([[0.0, 0.0, 0.0], [0.01, -0.02, 0.03]], dtype=torch.float64)
    data = SensingOperator(acquisition).forward(points, torch.tensor([1.0, 0.5j], dtype=torch.complex128))
    from rfsdf.radar.acquisition import Measurements

    scale = write_ti_capture(tmp_path, Measurements(acquisition, data), CHIRP, geometry)
    back = import_ti_capture(tmp_path / "adc_data.bin", read_mmwave_json(tmp_path / "capture.mmwave.json"),
                             geometry, tmp_path / "poses.csv", lanes=read_cf_json(tmp_path / "cf.json"))
    assert torch.equal(back.acquisition.tx_m, acquisition.tx_m) and torch.equal(back.acquisition.rx_m, acquisition.rx_m)
    # in counts: within the int16 rounding, half a count in I and in Q
    assert (back.data.to(torch.complex128) - data * scale).abs().max() <= 0.5 * 2 ** 0.5 + 1e-2


def test_a_ti_if_signal_imports_as_the_operators_model(tmp_path):
    """A point target's dechirped IF written the way a TI board records it, exp(+j 2 pi f (d_tx +
    d_rx + 0.15 m) / c) / (d_tx d_rx), independently of rfsdf's writer: imported, it is the
    operator's model of the same target up to one real scale."""
    geometry = CaptureGeometry(board("iwr1443"), boresight=(0, 0, 1), rx_axis=(0, -1, 0))
    tx0 = _scan()
    tx, rx = board_positions(geometry.board, tx0, np.array([0, 0, 1.0]), np.array([0, -1.0, 0]))
    target = np.array([0.004, -0.003, 0.01])
    d_tx, d_rx = np.linalg.norm(tx - target, axis=2), np.linalg.norm(rx - target, axis=2)  # (M, 1), (M, 4)
    path = (d_tx[:, :, None] + d_rx[:, None, :])[..., None] + 0.15  # (M, 1, 4, 1)
    f = CHIRP.frequencies_hz()
    raw = np.exp(2j * np.pi * f * path / SPEED_OF_LIGHT) / (d_tx[:, :, None] * d_rx[:, None, :])[..., None]
    write_bin(tmp_path / "adc.bin", raw * 3e4 / np.abs(raw).max(), AdcLayout(4, True, 4, CHIRP.samples, 1))
    write_poses(tmp_path / "poses.csv", tx0)
    imported = import_ti_capture(tmp_path / "adc.bin", CHIRP, geometry, tmp_path / "poses.csv").data.to(torch.complex128)
    model = SensingOperator(geometry.acquisition(CHIRP, tx0)).forward(
        torch.from_numpy(target[None]), torch.ones(1, dtype=torch.complex128))
    ratio = (imported / model).flatten()
    scale = ratio.abs().mean()
    assert float((ratio - scale).abs().max() / scale) < 1e-3  # one real, positive scale for every sample


def test_a_real_sampled_capture_is_refused_on_import(tmp_path):
    real = ChirpConfig(**{**CHIRP.__dict__, "complex": False})
    write_bin(tmp_path / "a.bin", np.zeros((1, 1, 4, 16)), AdcLayout(4, False, 4, 16, 1))
    with pytest.raises(RfsdfError, match="real-sampled capture"):
        import_ti_capture(tmp_path / "a.bin", real, CaptureGeometry(board("iwr1443")), tmp_path / "none.csv")


def _written_capture(folder):
    """A capture of two point targets written as an IWR1443 and a DCA1000 record it, with its pose file."""
    from rfsdf.radar.acquisition import Measurements

    geometry = CaptureGeometry(board("iwr1443"))
    acquisition = geometry.acquisition(CHIRP, _scan())
    points = torch.tensor([[0.0, 0.0, 0.0], [0.01, -0.02, 0.03]], dtype=torch.float64)
    data = SensingOperator(acquisition).forward(points, torch.tensor([1.0, 0.5j], dtype=torch.complex128))
    write_ti_capture(folder, Measurements(acquisition, data), CHIRP, geometry)
    write_poses(folder / "poses.csv", _scan())
    return import_ti_capture(folder / "adc_data.bin", CHIRP, geometry, folder / "poses.csv")


def test_rfsdf_import_reads_a_dca1000_capture(tmp_path):
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.radar import read_measurements

    expected = _written_capture(tmp_path)
    args = ["import", str(tmp_path / "adc_data.bin"), "--config", str(tmp_path / "capture.mmwave.json"),
            "--config", str(tmp_path / "cf.json"), "--chip", "iwr1443", "--poses", str(tmp_path / "poses.csv"),
            "--out", str(tmp_path / "data.h5")]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert "12 views of 1 Tx x 4 Rx, 16 samples over 77.421-77.526 GHz" in result.output
    imported = read_measurements(tmp_path / "data.h5")
    assert torch.equal(imported.data, expected.data) and torch.equal(imported.acquisition.rx_m, expected.acquisition.rx_m)
    assert imported.acquisition.scans is None  # each frame a view
    result = CliRunner().invoke(main, args[:-1] + [str(tmp_path / "scan.h5"), "--one-view"])
    assert result.exit_code == 0 and "1 view(s) of 12 frames of 1 Tx x 4 Rx" in result.output, result.output
    scan = read_measurements(tmp_path / "scan.h5")
    assert scan.acquisition.num_views == 1 and torch.equal(scan.data, expected.data)


@pytest.mark.parametrize("change, message", [
    (lambda a, d: a.remove("--chip") or a.remove("iwr1443"), "needs --chip .its setup names no device"),
    (lambda a, d: a.__setitem__(a.index("iwr1443"), "awr9999"), "--chip: unknown chip 'awr9999'"),
    (lambda a, d: (d / "adc_data.bin").write_bytes((d / "adc_data.bin").read_bytes()[:-2]),
     "adc_data.bin: size .* is not a whole number of frames"),
    (lambda a, d: (d / "poses.csv").write_text("x_m,y_m,z_m\n0,0,0\n"), "poses.csv: 1 poses for 12 frames"),
    (lambda a, d: (d / "cf.json").write_text('{"other": 1}'), "cf.json: neither an mmWave Studio"),
    (lambda a, d: a.__setitem__(1, str(d / "capture.setup.json")) or (d / "adc_data.bin").unlink(),
     r"capture.setup.json: capturedFiles.files\[0\]: none of \['adc_data.bin'\]"),
    (lambda a, d: a.__setitem__(1, str(d / "capture.setup.json")) or (d / "capture.mmwave.json").rename(d / "x.json"),
     "capture.setup.json: configUsed: 'capture.mmwave.json' is neither there nor beside"),
    (lambda a, d: a.__setitem__(a.index("0,-1,0"), "0,0,2"), "--rx-axis: must not be parallel to --boresight"),
    (lambda a, d: a.__setitem__(a.index("0,-1,0"), "0,nan,1"), "--rx-axis: expected three finite numbers"),
])
def test_rfsdf_import_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, change, message):
    _written_capture(tmp_path)
    args = ["import", str(tmp_path / "adc_data.bin"), "--config", str(tmp_path / "capture.mmwave.json"),
            "--config", str(tmp_path / "cf.json"), "--chip", "iwr1443", "--poses", str(tmp_path / "poses.csv"),
            "--rx-axis", "0,-1,0", "--out", str(tmp_path / "data.h5")]
    change(args, tmp_path)
    _refused_in_one_line(args, message, tmp_path / "data.h5")


def test_rfsdf_import_reads_a_capture_through_its_setup_json(tmp_path):
    """mmWave Studio's setup.json names the config, the .bin and the device: nothing else but
    the poses is needed, and the record split in two files (as the DCA1000 splits large ones)
    reads as one."""
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.radar import read_measurements

    expected = _written_capture(tmp_path)
    record = (tmp_path / "adc_data.bin").read_bytes()
    (tmp_path / "adc_data_Raw_0.bin").write_bytes(record[:1000])
    (tmp_path / "adc_data_Raw_1.bin").write_bytes(record[1000:])
    setup = json.loads((tmp_path / "capture.setup.json").read_text())
    setup["configUsed"] = "C:\\ti\\mmwave_studio\\JSONSampleFiles\\capture.mmwave.json"  # the capturing PC's path
    setup["capturedFiles"] = {"fileBasePath": "C:\\ti\\PostProc", "numFilesCollected": 2,
                              "files": [{"rawFileName": f"adc_data_Raw_{k}.bin"} for k in range(2)]}
    (tmp_path / "capture.setup.json").write_text(json.dumps(setup))
    (tmp_path / "adc_data.bin").unlink()
    result = CliRunner().invoke(main, ["import", str(tmp_path / "capture.setup.json"), "--poses",
                                       str(tmp_path / "poses.csv"), "--out", str(tmp_path / "data.h5")])
    assert result.exit_code == 0, result.output
    imported = read_measurements(tmp_path / "data.h5")
    assert torch.equal(imported.data, expected.data) and torch.equal(imported.acquisition.tx_m, expected.acquisition.tx_m)
    setup["DCA1000Config"]["dataLoggingMode"] = "multi"
    (tmp_path / "capture.setup.json").write_text(json.dumps(setup))
    with pytest.raises(RfsdfError, match="dataLoggingMode: 'multi'; only raw captures"):
        read_setup_json(tmp_path / "capture.setup.json")


@pytest.mark.parametrize("name", ["awr1843", "iwr6843"])
def test_a_three_tx_two_lane_capture_reads_back_with_the_lanes_its_mmwave_json_records(tmp_path, name):
    """TDM MIMO over three Tx, two LVDS lanes: the lanes come from the *.mmwave.json
    (rawDataCaptureConfig.rlDevLaneEnable_t.laneEn), with no cf.json."""
    from rfsdf.radar.acquisition import Measurements

    start = 77e9 if name == "awr1843" else 60e9
    chirp = ChirpConfig(**{**CHIRP.__dict__, "start_hz": start, "tx_mask": 0b111, "chirps_per_loop": 3, "lanes": 2})
    geometry = CaptureGeometry(board(name))
    acquisition = geometry.acquisition(chirp, _scan())
    assert acquisition.shape == (12, 3, 4, 16)
    data = SensingOperator(acquisition).forward(torch.zeros(1, 3, dtype=torch.float64), torch.ones(1, dtype=torch.complex128))
    scale = write_ti_capture(tmp_path, Measurements(acquisition, data), chirp, geometry)
    (tmp_path / "cf.json").unlink()
    config = read_mmwave_json(tmp_path / "capture.mmwave.json")
    assert config.lanes == 2 and read_setup_json(tmp_path / "capture.setup.json").device == name
    back = import_ti_capture(tmp_path / "adc_data.bin", config, geometry, write_poses(tmp_path / "poses.csv", _scan()))
    assert (back.data.to(torch.complex128) - data * scale).abs().max() <= 0.5 * 2 ** 0.5 + 1e-2


def test_an_mmwave_json_written_by_hand_as_mmwave_studio_lays_it_out_is_read(tmp_path):
    """Not through rfsdf's writer: mmWave Studio's field names and units, hex masks as strings,
    two profiles (the first is read), three chirps a loop."""
    document = {"mmWaveDevices": [{"mmWaveDeviceId": 0, "rfConfig": {
        "rlChanCfg_t": {"rxChannelEn": "0xF", "txChannelEn": "0x7", "cascading": 0},
        "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": 2, "b8FullScaleReducFctr": 0, "b2AdcOutFmt": 1}},
        "rlProfiles": [{"rlProfileCfg_t": {"profileId": 0, "startFreqConst_GHz": 77.0, "idleTimeConst_usec": 100.0,
                                           "adcStartTimeConst_usec": 6.0, "rampEndTime_usec": 60.0,
                                           "freqSlopeConst_MHz_usec": 70.295, "numAdcSamples": 256,
                                           "digOutSampleRate": 5000.0, "rxGain_dB": "0x1E"}},
                       {"rlProfileCfg_t": {"profileId": 1, "startFreqConst_GHz": 60.0}}],
        "rlFrameCfg_t": {"chirpStartIdx": 0, "chirpEndIdx": 2, "numLoops": 16, "numFrames": 8,
                         "framePeriodicity_msec": 40.0}}}]}
    (tmp_path / "studio.mmwave.json").write_text(json.dumps(document))
    chirp = read_mmwave_json(tmp_path / "studio.mmwave.json")
    assert (chirp.samples, chirp.rx, chirp.chirps_per_loop, chirp.loops, chirp.chirps, chirp.frames) == (256, 4, 3, 16, 48, 8)
    assert (chirp.rx_mask, chirp.tx_mask, chirp.complex, chirp.lanes) == (0xF, 0x7, True, None)
    assert chirp.slope_hz_per_s == pytest.approx(70.295e12) and chirp.sample_rate_hz == pytest.approx(5e6)
    assert chirp.frame_period_s == pytest.approx(0.04) and chirp.idle_s == pytest.approx(100e-6)
    assert chirp.frequencies_hz()[0] == pytest.approx(77e9 + 70.295e12 * 6e-6)
    assert chirp.frequencies_hz()[-1] == pytest.approx(77e9 + 70.295e12 * (6e-6 + 255 / 5e6))


def test_a_cf_json_and_pose_files_written_by_hand_are_read(tmp_path):
    (tmp_path / "cf.json").write_text(json.dumps({"DCA1000Config": {
        "dataLoggingMode": "raw", "dataTransferMode": "LVDSCapture", "dataCaptureMode": "ethernetStream",
        "lvdsMode": 1, "dataFormatMode": 3, "packetDelay_us": 25,
        "ethernetConfig": {"DCA1000IPAddress": "192.168.33.180", "DCA1000ConfigPort": 4096, "DCA1000DataPort": 4098}}}))
    assert read_cf_json(tmp_path / "cf.json") == 4
    (tmp_path / "frames.csv").write_text("z_m, x_m, y_m\n0.5,0.1,0.2\n0.5,0.2,0.2\n")  # columns in any order
    assert np.array_equal(read_poses(tmp_path / "frames.csv", 2), [[0.1, 0.2, 0.5], [0.2, 0.2, 0.5]])
    (tmp_path / "arm.csv").write_text("time_s,x_m,y_m,z_m\n10.0,0,0,0\n10.1,0.1,0,0.2\n")
    frames = read_poses(tmp_path / "arm.csv", 3, frame_period_s=0.05)
    assert frames == pytest.approx(np.array([[0, 0, 0], [0.05, 0, 0.1], [0.1, 0, 0.2]]))


def _turn(angle_rad):
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_geraf_view_folders_read_back_what_was_written(tmp_path):
    """Two turntable angles of an IWR1443 raster written as GeRaF's view folders (rows of one
    Tx and one Rx, positions in the radar's frame, TI's 0.15 m added) read back as the
    measurements, to the precision of their complex64 samples."""
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.formats.geraf import read_geraf, write_geraf

    geometry = CaptureGeometry(board("iwr1443"))
    turns = np.stack([_turn(0.0), _turn(np.pi / 3)])
    tx0 = np.concatenate([_scan() @ turns[0], _scan() @ turns[1]])  # in the object's frame
    acquisition = geometry.acquisition(CHIRP, tx0)
    bore = np.concatenate([np.tile(turn.T @ [0, 0, 1.0], (12, 1)) for turn in turns])
    acquisition = type(acquisition)(acquisition.tx_m, acquisition.rx_m, acquisition.frequencies_hz,
                                    torch.from_numpy(bore), 0.0, True)
    data = SensingOperator(acquisition).forward(torch.tensor([[0.01, 0.0, 0.02]], dtype=torch.float64),
                                                torch.ones(1, dtype=torch.complex128))
    folders = write_geraf(tmp_path / "capture", Measurements(acquisition, data), turns)
    assert [f.name for f in folders] == ["view_000", "view_001"]
    assert np.load(folders[0] / "tpos.npy").shape == (48, 3) and np.load(folders[0] / "adcr.npy").shape == (48, 16)
    back = read_geraf(tmp_path / "capture", CHIRP.frequencies_hz())
    assert back.acquisition.scans.tolist() == [0] * 12 + [1] * 12  # a view folder is a view, as GeRaF's
    for name in ("tx_m", "rx_m", "boresight"):
        assert torch.allclose(getattr(back.acquisition, name), getattr(acquisition, name), rtol=0, atol=1e-12), name
    assert torch.allclose(back.data, data.to(back.data.dtype), rtol=1e-6, atol=0)  # complex64 data


def test_a_geraf_view_written_by_hand_imports_as_the_operators_model(tmp_path):
    """Not through rfsdf's writer: a point target on a turntable turned by 40 degrees, recorded
    as GeRaF's back-projection expects, exp(-j 2 pi f (d_tx + d_rx + 0.15 m) / c) / (d_tx d_rx),
    each row one Rx; read in the object's frame, it is the operator's model of the unturned
    target."""
    from rfsdf.radar.formats.geraf import read_geraf

    turn = _turn(np.radians(40))
    target = np.array([0.004, -0.003, 0.01])
    tx, rx = board_positions(board("iwr1443"), _scan(), np.array([0, 0, 1.0]), np.array([0, -1.0, 0]))
    tpos, rpos = np.repeat(tx[:, 0], 4, axis=0), rx.reshape(-1, 3)  # rows: position-major, then Rx
    seen = turn @ target  # where the turned target is in the radar's frame
    d_tx, d_rx = np.linalg.norm(tpos - seen, axis=1), np.linalg.norm(rpos - seen, axis=1)
    f = CHIRP.frequencies_hz()
    adc = np.exp(-2j * np.pi * f * (d_tx + d_rx + 0.15)[:, None] / SPEED_OF_LIGHT) / (d_tx * d_rx)[:, None]
    view = tmp_path / "angle_40"
    view.mkdir()
    for name, value in (("tpos", tpos), ("rpos", rpos), ("adcr", adc.real), ("adci", adc.imag),
                        ("rotation", np.radians(40))):
        np.save(view / f"{name}.npy", value)
    imported = read_geraf(view, f)
    assert imported.acquisition.shape == (12, 1, 4, 16)
    (tmp_path / "radar.toml").write_text(  # the same chirp as an rfsdf radar's FMCW waveform, through the CLI
        f"name = 'geraf'\n[waveform]\nkind = 'fmcw'\nstart_hz = {float(f[0])!r}\nslope_hz_per_s = {CHIRP.slope_hz_per_s!r}\n"
        f"sample_rate_hz = {CHIRP.sample_rate_hz!r}\nsamples = {CHIRP.samples}\n[array]\nkind = 'ti_3tx4rx'\n"
        "[views]\ndistance_m = 0.2\nazimuths_per_ring = [1]\nelevations_rad = [0.0]\n")
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.radar import read_measurements

    result = CliRunner().invoke(main, ["import", str(view), "--config", str(tmp_path / "radar.toml"),
                                       "--out", str(tmp_path / "data.h5")])
    assert result.exit_code == 0, result.output
    assert torch.allclose(read_measurements(tmp_path / "data.h5").acquisition.frequencies_hz,
                          imported.acquisition.frequencies_hz, rtol=1e-12, atol=0)
    model = SensingOperator(imported.acquisition).forward(torch.from_numpy(target[None]),
                                                          torch.ones(1, dtype=torch.complex128))
    assert float(((imported.data - model).abs() / model.abs()).max()) < 1e-6  # complex64 data


@pytest.mark.parametrize("change, message", [
    (lambda v: np.save(v / "tpos.npy", np.full((48, 3), np.nan)), "tpos.npy: contains NaN or Inf"),
    (lambda v: np.save(v / "adcr.npy", np.zeros((48, 8))), r"adcr.npy and adci.npy must be \(M, K\) = \(48, 16\)"),
    (lambda v: (v / "rotation.npy").unlink(), "rotation.npy: cannot read as a numeric .npy"),
    (lambda v: np.save(v / "rotation.npy", np.eye(2)), "rotation.npy: expected a 3 x 3 rotation matrix"),
    (lambda v: np.save(v / "tpos.npy", np.repeat(np.arange(9.0), [4, 4, 4, 4, 4, 4, 4, 4, 16])[:, None] * [1, 0, 0]),
     r"tpos.npy: frames \(rows sharing a Tx\) hold 4 to 16 rows"),
])
def test_rfsdf_import_refuses_a_bad_geraf_view_in_one_line(tmp_path, change, message):
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.formats.geraf import write_geraf

    acquisition = CaptureGeometry(board("iwr1443")).acquisition(CHIRP, _scan())
    data = torch.ones(acquisition.shape, dtype=torch.complex128)
    view = write_geraf(tmp_path / "capture", Measurements(acquisition, data), _turn(0.0)[None])[0]
    write_mmwave_json(tmp_path / "capture.mmwave.json", CHIRP)
    args = ["import", str(tmp_path / "capture"), "--config", str(tmp_path / "capture.mmwave.json"),
            "--out", str(tmp_path / "data.h5")]
    assert CliRunner().invoke(main, args).exit_code == 0
    (tmp_path / "data.h5").unlink()
    change(view)
    _refused_in_one_line(args, message, tmp_path / "data.h5")


def test_a_geraf_capture_larger_than_memory_is_refused_before_it_is_read(tmp_path, monkeypatch):
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.formats.geraf import read_geraf, write_geraf

    acquisition = CaptureGeometry(board("iwr1443")).acquisition(CHIRP, _scan())
    write_geraf(tmp_path, Measurements(acquisition, torch.ones(acquisition.shape, dtype=torch.complex128)),
                _turn(0.0)[None])
    monkeypatch.setattr("rfsdf.limits.available_memory_bytes", lambda: 1000)
    with pytest.raises(RfsdfError, match=r"the capture \(1 views, 48 rows x 16 samples\) need about"):
        read_geraf(tmp_path, CHIRP.frequencies_hz())


# UT Dallas' 3-D MIMO-SAR example capture (IWR1443, three Tx, four Rx), with 16 samples
UTD_CHIRP = ChirpConfig(start_hz=77e9, slope_hz_per_s=63.343e12, sample_rate_hz=9121e3, samples=16,
                        adc_start_s=6e-6, idle_s=0.0, ramp_end_s=0.0, rx_mask=0xF, tx_mask=0b111, complex=True,
                        chirps_per_loop=3, loops=1, frames=6, frame_period_s=8e-3)
UTD_TARGET = np.array([0.004, 0.006, 0.25])  # 25 cm in front of the scan plane (their frame: z depth)


def _utd_parameters(num_tx=3, steps=(0.9e-3, 1.9e-3)) -> dict:
    """sensorParams and sarParams as their MATLAB structs (a 2 x 3 raster: two rows, three columns)."""
    return {"sensorParams": {"Start_Freq_GHz": 77.0, "Slope_MHzperus": 63.343, "Sampling_Rate_ksps": 9121.0,
                             "Adc_Start_Time_us": 6.0, "Samples_per_Chirp": 16, "Num_TX": num_tx,
                             "RxToEnable": np.array([1.0, 2, 3, 4]), "Frame_Repetition_Period_ms": 8.0},
            "sarParams": {"Num_horizontalScan": 3, "Num_verticalScan": 2, "Vertical_stepSize_mm": steps[1] * 1e3,
                          "Platform_Speed_mmps": steps[0] * 1e3 / 8e-3}}


def _utd_by_hand(folder, *, raw=None, hdf5=False, **parameters):
    """A capture of UTD_TARGET as UT Dallas' files hold it, not through rfsdf's writer: their
    antenna positions (getAntennaLocations.m: Rx k at (0, k lambda/2, 0), Tx1 at (0, 3 lambda/2
    + 5 mm, 0), Tx2 lambda/2 left of and lambda above it, Tx3 2 lambda above it; lambda at 79
    GHz) moved so that Tx1 sits at the frame's position (h dx, v dy, 0), and TI's IF,
    exp(+j 2 pi f (d_tx + d_rx + 0.15 m) / c) / (d_tx d_rx), channel Tx t Rx r at t 4 + r.
    ``hdf5``: the files as MATLAB's v7.3 saves them (HDF5, axes reversed, complex compound).
    Returns the Tx (V, 3, 3) and Rx (V, 4, 3) positions and the target's model data."""
    import h5py
    import scipy.io

    variables = _utd_parameters(**parameters)
    lam = SPEED_OF_LIGHT / 79e9
    rx0 = np.array([[0.0, k * lam / 2, 0.0] for k in range(4)])
    tx0 = np.array([[0.0, 1.5 * lam + 5e-3, 0.0], [-lam / 2, 2.5 * lam + 5e-3, 0.0], [0.0, 3.5 * lam + 5e-3, 0.0]])
    sar = variables["sarParams"]
    dx, dy = sar["Platform_Speed_mmps"] * 8e-6, sar["Vertical_stepSize_mm"] * 1e-3
    v, h = np.meshgrid(np.arange(2), np.arange(3), indexing="ij")
    frames = np.column_stack([h.ravel() * dx, v.ravel() * dy, np.zeros(6)])[:, None] - tx0[0]
    tx, rx = frames + tx0, frames + rx0  # (6, 3, 3), (6, 4, 3)
    d_tx = np.linalg.norm(tx - UTD_TARGET, axis=-1)[:, :, None, None]
    d_rx = np.linalg.norm(rx - UTD_TARGET, axis=-1)[:, None, :, None]
    f = UTD_CHIRP.frequencies_hz()
    model = np.exp(-2j * np.pi * f * (d_tx + d_rx) / SPEED_OF_LIGHT) / (d_tx * d_rx)  # (V, T, R, K)
    recorded = np.conj(model * np.exp(-2j * np.pi * f * 0.15 / SPEED_OF_LIGHT))
    variables["rawData"] = recorded.transpose(1, 2, 0, 3).reshape(12, 2, 3, 16) if raw is None else raw
    folder.mkdir(parents=True, exist_ok=True)
    for name, value in variables.items():
        if not hdf5:
            scipy.io.savemat(folder / f"{name}.mat", {name: value})
            continue
        with h5py.File(folder / f"{name}.mat", "w") as fh:
            if isinstance(value, dict):
                group = fh.create_group(name)
                for key, item in value.items():
                    group[key] = np.atleast_2d(np.asarray(item, float)).T
            else:
                compound = np.empty(value.shape[::-1], dtype=[("real", "<f8"), ("imag", "<f8")])
                compound["real"], compound["imag"] = value.real.T, value.imag.T
                fh[name] = compound
    return tx, rx, model


@pytest.mark.parametrize("hdf5", [False, True], ids=["v5", "v7.3"])
def test_a_utd_capture_written_by_hand_imports_as_the_operators_model(tmp_path, hdf5):
    """UT Dallas' layout, their antenna positions and TI's IF sign and delay, in MATLAB's v5 and
    v7.3 files: read back, each frame a view of three Tx and four Rx at their positions, and the
    data the operator's model of the target."""
    from rfsdf.radar.formats.utd_mat import read_utd

    tx, rx, model = _utd_by_hand(tmp_path / "capture", hdf5=hdf5)
    imported = read_utd(tmp_path / "capture")
    acq = imported.acquisition
    assert acq.shape == (6, 3, 4, 16)
    assert np.allclose(acq.tx_m.numpy(), tx, rtol=0, atol=1e-9) and np.allclose(acq.rx_m.numpy(), rx, rtol=0, atol=1e-9)
    assert torch.allclose(acq.frequencies_hz, torch.from_numpy(UTD_CHIRP.frequencies_hz()), rtol=1e-12, atol=0)
    operator = SensingOperator(acq).forward(torch.from_numpy(UTD_TARGET[None]), torch.ones(1, dtype=torch.complex128))
    assert float(((imported.data - operator).abs() / operator.abs()).max()) < 1e-6  # complex64 data
    assert np.allclose(imported.data.numpy(), model, rtol=1e-6, atol=0)


def test_a_utd_capture_reads_back_what_was_written_with_its_calibration(tmp_path):
    """rfsdf's writer, with a per-channel complex gain and delay offset undone in the raw data:
    applying calData.mat and delayOffset.mat as calibrateDataFunction.m does recovers the
    measurements (no fixed delay is undone on top of a delayOffset); without those files the
    raw data differ by exactly that calibration."""
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.formats.utd_mat import read_utd, write_utd

    frames = np.column_stack([np.tile(np.arange(3) * 0.9e-3, 2), np.repeat(np.arange(2) * 1.9e-3, 3), np.zeros(6)])
    acquisition = CaptureGeometry(board("iwr1443")).acquisition(UTD_CHIRP, frames)
    data = SensingOperator(acquisition).forward(torch.from_numpy(UTD_TARGET[None]), torch.ones(1, dtype=torch.complex128))
    rng = np.random.default_rng(0)
    gains = rng.uniform(0.5, 2, 12) * np.exp(2j * np.pi * rng.uniform(size=12))
    delays = rng.uniform(0.5e-9, 1.5e-9, 12)  # [s], about the 0.15 m path's 1 ns
    write_utd(tmp_path, Measurements(acquisition, data), UTD_CHIRP, (2, 3), (0.9e-3, 1.9e-3), calibration=(gains, delays))
    back = read_utd(tmp_path)
    for name in ("tx_m", "rx_m", "boresight", "frequencies_hz"):
        assert torch.allclose(getattr(back.acquisition, name), getattr(acquisition, name), rtol=1e-12, atol=1e-12), name
    assert torch.allclose(back.data, data.to(back.data.dtype), rtol=1e-6, atol=0)  # complex64 data
    for name in ("calData.mat", "delayOffset.mat"):
        (tmp_path / name).unlink()
    raw = read_utd(tmp_path, range_delay_m=0.0)
    beat = np.arange(16) * UTD_CHIRP.slope_hz_per_s / UTD_CHIRP.sample_rate_hz
    calibration = (gains[:, None] * np.exp(-2j * np.pi * delays[:, None] * beat)).reshape(3, 4, 16)
    assert np.allclose(raw.data.numpy() * np.conj(calibration), data.numpy(), rtol=1e-6, atol=0)


@pytest.mark.parametrize("change, message", [
    (lambda f: (f / "sarParams.mat").unlink(), r"sarParams.mat: missing"),
    (lambda f: _utd_by_hand(f, raw=np.zeros((12, 2, 3, 8))), r"rawData has shape \(12, 2, 3, 8\); .* = \(12, 2, 3, 16\)"),
    (lambda f: _utd_by_hand(f, raw=np.full((12, 2, 3, 16), np.nan)), "rawData contains NaN or Inf"),
    (lambda f: _utd_by_hand(f, num_tx=2), "Num_TX 2: which of the IWR1443's Tx fired"),
    (lambda f: _utd_by_hand(f, steps=(0.9e-3, 0.0)), "the raster's steps must not be zero"),
    (lambda f: (f / "calData.mat").write_bytes(b"not a MAT file"), "calData.mat: cannot read as a MATLAB file"),
])
def test_rfsdf_import_refuses_a_bad_utd_capture_in_one_line(tmp_path, change, message):
    from click.testing import CliRunner

    from rfsdf.cli import main

    folder = tmp_path / "capture"
    _utd_by_hand(folder)
    args = ["import", str(folder), "--out", str(tmp_path / "data.h5")]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0 and "6 views of 3 Tx x 4 Rx, 16 samples" in result.output, result.output
    (tmp_path / "data.h5").unlink()
    change(folder)
    _refused_in_one_line(args, message, tmp_path / "data.h5")


def _mito_capture(folder, scan=None):
    """Two point targets below a raster (MITO's arm looks down, its Rx offset along y), written
    as a MITO capture folder (rows of four frames) beside its params.json; returns the
    measurements it holds."""
    from rfsdf.radar.acquisition import Measurements
    from rfsdf.radar.formats.mito import write_mito, write_mito_params

    scan = _scan() * [1, 1, -1] if scan is None else scan  # 0.2 m above the targets
    acquisition = CaptureGeometry(board("iwr1443"), (0, 0, -1), (0, -1, 0)).acquisition(CHIRP, scan)
    points = torch.tensor([[0.0, 0.0, 0.0], [0.01, -0.02, 0.03]], dtype=torch.float64)
    data = SensingOperator(acquisition).forward(points, torch.tensor([1.0, 0.5j], dtype=torch.complex128))
    measurements = Measurements(acquisition, data)
    write_mito(folder / "77_ghz", measurements, CHIRP, rx_offset="y", frames_per_row=4)
    write_mito_params(folder / "params.json", CHIRP)
    return measurements


def test_rfsdf_import_reads_a_mito_capture_as_one_scan_with_its_params_json(tmp_path):
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.radar import read_measurements

    written = _mito_capture(tmp_path)
    result = CliRunner().invoke(main, ["import", str(tmp_path / "77_ghz"), "--config", str(tmp_path / "params.json"),
                                       "--out", str(tmp_path / "data.h5")])
    assert result.exit_code == 0 and "1 view(s) of 12 frames of 1 Tx x 4 Rx, 16 samples" in result.output, result.output
    back = read_measurements(tmp_path / "data.h5")
    for name in ("tx_m", "rx_m", "frequencies_hz", "boresight"):
        assert torch.allclose(getattr(back.acquisition, name), getattr(written.acquisition, name), rtol=0, atol=1e-9)
    assert back.acquisition.num_views == 1
    ratio = back.data.to(torch.complex128) / written.data  # one real scale to int16 counts, then their rounding
    assert float((ratio / ratio.abs().mean() - 1).abs().max()) < 2e-3


def test_a_mito_record_written_by_hand_imports_as_the_operators_model(tmp_path):
    """Not through rfsdf's writer: a point target's IF as the IWR1443 records it, exp(+j 2 pi f
    (d_tx + d_rx + 0.15 m) / c) / (d_tx d_rx), its Rx 5 mm + (3 - k) lambda/2 from the Tx on
    the negative x side (rx offset "x"), in one record over a track logged at 1 ms; imported,
    the operator's model of the same target up to one real scale."""
    from rfsdf.radar.formats.mito import read_mito

    capture = tmp_path / "77_ghz"
    (capture / "radar_data").mkdir(parents=True)
    period, created = 3e-3, 1000.0
    tx = np.column_stack([np.arange(6) * 0.97e-3, np.zeros(6), np.full(6, 0.2)])  # frame j at created + j period
    half = SPEED_OF_LIGHT / 79e9 / 2
    rx = tx[:, None] - (0.005 + (3 - np.arange(4))[:, None] * half) * np.array([1.0, 0, 0])  # (F, 4, 3)
    target = np.array([0.003, 0.004, 0.0])
    d_tx, d_rx = np.linalg.norm(tx - target, axis=1), np.linalg.norm(rx - target, axis=2)
    f = CHIRP.frequencies_hz()
    path = (d_tx[:, None] + d_rx + 0.15)[..., None]  # (F, 4, 1)
    raw = np.exp(2j * np.pi * f * path / SPEED_OF_LIGHT) / (d_tx[:, None] * d_rx)[..., None]
    write_bin(capture / "radar_data" / "adc_data1700000000.bin", 3e4 * raw[:, None] / np.abs(raw).max(),
              AdcLayout(4, True, 4, 16, 1))
    (capture / "continuous_0.pkl").write_bytes(pickle.dumps({"all_radar_filenames": ["1700000000"],
                                                            "all_radar_created_ts": [created]}))
    track_times = created - 0.01 + np.arange(40) * 1e-3
    along = np.interp(track_times, created + np.arange(6) * period, tx[:, 0])  # moving at 0.97 mm / 3 ms
    np.savez(capture / "antenna_0.npz", times_77=track_times,
             tx_77_locs=np.column_stack([along, np.zeros(40), np.full(40, 0.2), np.zeros(40)]))  # + an orientation
    (tmp_path / "experiment_info.json").write_text('{"rx offset": "x", "aperture size": "normal"}')  # in exp<N>
    imported = read_mito(capture, CHIRP)
    assert imported.acquisition.shape == (6, 1, 4, 16)
    assert np.allclose(imported.acquisition.rx_m.numpy(), rx, atol=1e-12)
    model = SensingOperator(imported.acquisition).forward(torch.from_numpy(target[None]),
                                                          torch.ones(1, dtype=torch.complex128))
    ratio = (imported.data.to(torch.complex128) / model).flatten()
    assert float((ratio / ratio.abs().mean() - 1).abs().max()) < 2e-3  # int16 rounding


def test_frames_of_a_mito_row_where_the_arm_stood_still_are_dropped(tmp_path):
    from rfsdf.radar.formats.mito import mito_chirp, read_mito

    scan = _scan() * [1, 1, -1]
    scan[1] = scan[0] + [1e-4, 0, 0]  # the second frame of the first row a tenth of a millimetre from the first
    _mito_capture(tmp_path, scan)
    back = read_mito(tmp_path / "77_ghz", mito_chirp(tmp_path / "params.json", tmp_path / "77_ghz"))
    assert back.acquisition.shape[0] == 11
    assert torch.allclose(back.acquisition.tx_m[:, 0], torch.from_numpy(np.delete(scan, 1, axis=0)), atol=1e-12)


@pytest.mark.parametrize("change, message", [
    (lambda c, a: (c / "radar_data" / "adc_data1700000010.bin").unlink(),
     r"radar_data: no adc_data1700000010\*.bin, which the arm's log lists"),
    (lambda c, a: (c / "experiment_info.json").write_text('{"rx offset": "z", "aperture size": "normal"}'),
     r"experiment_info.json: 'rx offset': 'z'; expected one of 'x', 'y'"),
    (lambda c, a: (c / "experiment_info.json").unlink(), r"no experiment_info.json in it or the four folders above"),
    (lambda c, a: (c / "continuous.pkl").write_bytes(pickle.dumps(pathlib.PurePosixPath("x"))),
     r"continuous.pkl: cannot read as the arm's log .*pathlib.PurePosixPath is not part of a robot log"),
    (lambda c, a: np.savez(c / "antenna.npz", times_77=np.arange(3.0), tx_77_locs=np.zeros((3, 3))),
     "no frame lies within the track's times"),
    (lambda c, a: np.savez(c / "antenna.npz", times_77=np.array([0.0, 0.0]), tx_77_locs=np.zeros((2, 3))),
     "times_77 needs two or more samples in increasing order"),
    (lambda c, a: (c / "radar_data" / "adc_data1700000000.bin").write_bytes(b"\0" * 100),
     "size 100 bytes is not a whole"),
    (lambda c, a: a.extend(["--config", a[3]]), "a MITO capture needs one --config"),
    (lambda c, a: a.__setitem__(3, str(c.parent / "missing.json")), "missing.json: cannot read"),
])
def test_rfsdf_import_refuses_a_bad_mito_capture_in_one_line(tmp_path, change, message):
    from click.testing import CliRunner

    from rfsdf.cli import main

    _mito_capture(tmp_path)
    capture = tmp_path / "77_ghz"
    args = ["import", str(capture), "--config", str(tmp_path / "params.json"), "--out", str(tmp_path / "data.h5")]
    assert CliRunner().invoke(main, args).exit_code == 0
    (tmp_path / "data.h5").unlink()
    change(capture, args)
    _refused_in_one_line(args, message, tmp_path / "data.h5")
