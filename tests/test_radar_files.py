"""HDF5 round trips, FMCW import, and the one-line errors of radar files."""

import warnings

import h5py
import numpy as np
import pytest
import torch
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.config import resolve_preset
from rfsdf.errors import RfsdfError
from rfsdf.geometry import Grid
from rfsdf.radar import (
    Acquisition, Measurements, check_radar_for_scene, fmcw_frequencies, import_fmcw, load_radar, matched_filter,
    read_image, read_measurements, write_image, write_measurements,
)
from rfsdf.scene import load_scene


def _measurements():
    g = torch.Generator().manual_seed(0)
    acq = Acquisition(torch.randn(2, 3, 3, generator=g).double(), torch.randn(2, 2, 3, generator=g).double(),
                      torch.linspace(77e9, 81e9, 4).double(), torch.tensor([[0, 0, 1.0], [0, 1.0, 0]]), 1.0, False)
    return Measurements(acq, torch.randn(2, 3, 2, 4, dtype=torch.complex64, generator=g), 0.5, {"scene": "sphere"})


def test_measurements_and_image_round_trip(tmp_path):
    m = _measurements()
    write_measurements(tmp_path / "m.h5", m)
    back = read_measurements(tmp_path / "m.h5")
    torch.testing.assert_close(back.data, m.data)
    torch.testing.assert_close(back.acquisition.tx_m, m.acquisition.tx_m)
    assert back.acquisition.pattern_exponent == 1.0 and not back.acquisition.spreading
    assert back.noise_std == 0.5 and back.metadata == {"scene": "sphere"}
    image = matched_filter(m, Grid((-1, -1, -1), (1, 1, 1), (3, 4, 5)))
    write_image(tmp_path / "i.h5", image)
    again = read_image(tmp_path / "i.h5")
    torch.testing.assert_close(again.per_view, image.per_view)
    assert again.grid == image.grid


def test_bad_files_give_clear_errors(tmp_path):
    write_measurements(tmp_path / "m.h5", _measurements())
    with h5py.File(tmp_path / "m.h5", "a") as fh:
        fh.attrs["format_version"] = 99
    with pytest.raises(RfsdfError, match="format_version.*version 99"):
        read_measurements(tmp_path / "m.h5")
    write_measurements(tmp_path / "ok.h5", _measurements())
    data = (tmp_path / "ok.h5").read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 2])
    with pytest.raises(RfsdfError, match="cut.h5"):
        read_measurements(tmp_path / "cut.h5")
    with pytest.raises(RfsdfError, match="file not found"):
        read_measurements(tmp_path / "none.h5")


def test_nan_in_data_is_rejected(tmp_path):
    write_measurements(tmp_path / "m.h5", _measurements())
    with h5py.File(tmp_path / "m.h5", "a") as fh:
        d = fh["data"][()]
        d[0, 0, 0, 0] = np.nan
        fh["data"][...] = d
    with pytest.raises(RfsdfError, match="data: contains NaN"):
        read_measurements(tmp_path / "m.h5")


def test_fmcw_import_round_trip(tmp_path):
    m_frames, n = 5, 8
    rng = np.random.default_rng(0)
    tx, rx = rng.normal(size=(m_frames, 3)), rng.normal(size=(m_frames, 3))
    adc = (rng.normal(size=(m_frames, n)) + 1j * rng.normal(size=(m_frames, n))).astype(np.complex64)
    with h5py.File(tmp_path / "cap.h5", "w") as fh:
        fh["tx_m"], fh["rx_m"], fh["adc"] = tx, rx, adc
        fh.attrs.update(start_frequency_hz=77e9, slope_hz_per_s=60e12, sample_rate_hz=10e6)
    m = import_fmcw(tmp_path / "cap.h5", conjugate=True)
    assert m.acquisition.shape == (m_frames, 1, 1, n)
    np.testing.assert_allclose(m.acquisition.frequencies_hz.numpy(), fmcw_frequencies(77e9, 60e12, 10e6, n))
    np.testing.assert_allclose(m.acquisition.frequencies_hz[1] - m.acquisition.frequencies_hz[0], 60e12 / 10e6)
    np.testing.assert_allclose(m.data.numpy().reshape(m_frames, n), np.conj(adc))
    np.testing.assert_allclose(m.acquisition.tx_m[:, 0].numpy(), tx)
    result = CliRunner().invoke(main, ["import-fmcw", str(tmp_path / "cap.h5"), "--out", str(tmp_path / "m.h5")])
    assert result.exit_code == 0, result.output
    assert read_measurements(tmp_path / "m.h5").acquisition.shape == (m_frames, 1, 1, n)


def _radar_file(tmp_path, **changes):
    text = resolve_preset("near-77g", "rfsdf.presets.radars", "radar").read_text()
    for old, new in changes.items():
        text = text.replace(old, new)
    path = tmp_path / "radar.toml"
    path.write_text(text)
    return path


def test_radar_config_checks(tmp_path):
    scene = load_scene("objects")
    check_radar_for_scene(load_radar("near-77g"), scene.lower_m, scene.upper_m)
    sparse = load_radar(_radar_file(tmp_path, **{"elements_per_edge = 24": "elements_per_edge = 8"}))
    with pytest.raises(RfsdfError, match="array: virtual element spacing .* grating lobes"):
        check_radar_for_scene(sparse, scene.lower_m, scene.upper_m, source="radar.toml")
    few = load_radar(_radar_file(tmp_path, **{"subcarriers = 16": "subcarriers = 4"}))
    with pytest.raises(RfsdfError, match="unambiguous range"):
        check_radar_for_scene(few, scene.lower_m, scene.upper_m)
    with pytest.raises(RfsdfError, match=r"radar.toml: waveform: ofdm waveform needs subcarriers"):
        load_radar(_radar_file(tmp_path, **{"subcarriers = 16": ""}))
    with warnings.catch_warnings():  # no overflow on the way to the error (numpy warned twice)
        warnings.simplefilter("error")
        with pytest.raises(RfsdfError, match="radar position and target are not a finite distance apart"):
            load_radar(_radar_file(tmp_path, **{"distance_m = 0.75": "distance_m = 1e308"}))


def test_cli_simulate_rejects_aliasing_radar_in_one_line(tmp_path):
    path = _radar_file(tmp_path, **{"elements_per_edge = 24": "elements_per_edge = 8"})
    result = CliRunner().invoke(main, ["simulate", "objects", "--radar", str(path), "--out", str(tmp_path / "m.h5")])
    assert result.exit_code == 2 and "grating lobes" in result.output
    assert result.output.strip().count("\n") == 0 and not (tmp_path / "m.h5").exists()
