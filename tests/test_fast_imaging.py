"""Range-profile back-projection against the exact adjoint (the sensing operator's)."""

import numpy as np
import pytest
import torch

from rfsdf.geometry import Grid
from rfsdf.radar import Acquisition, Measurements, SensingOperator, load_radar, matched_filter, simulate
from rfsdf.radar.fast_imaging import fast_adjoint
from rfsdf.radar.imaging import imaging_method
from rfsdf.scene import load_scene


def _relative_error(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).norm() / b.norm())


@pytest.fixture(scope="module")
def small_acquisition() -> Acquisition:
    """Two views of the demo radar with 1/4 of its Tx and Rx."""
    return load_radar("near-77g").acquisition().view(slice(0, 2)).thinned(2)


def test_fast_adjoint_matches_exact_and_its_error_falls_as_oversampling_squared(small_acquisition):
    generator = torch.Generator().manual_seed(0)
    shape = small_acquisition.shape
    y = torch.complex(torch.randn(shape, generator=generator), torch.randn(shape, generator=generator))
    points = 0.3 * torch.rand(500, 3, generator=generator) - 0.15
    exact = SensingOperator(small_acquisition).adjoint(y, points, per_view=True)
    errors = {n: _relative_error(fast_adjoint(small_acquisition, y, points, oversampling=n), exact) for n in (8, 16)}
    assert errors[16] < 3e-3
    # Linear interpolation of a band-limited profile: error ~ (pi / oversampling)^2 / 8.
    assert errors[8] / errors[16] == pytest.approx(4.0, rel=0.25)


def test_fast_adjoint_handles_patterns_no_spreading_and_uneven_frequencies():
    generator = torch.Generator().manual_seed(1)
    tx = 0.05 * torch.rand(1, 6, 3, generator=generator, dtype=torch.float64)
    rx = 0.05 * torch.rand(1, 5, 3, generator=generator, dtype=torch.float64)
    freqs = torch.tensor([77.0e9, 77.3e9, 78.1e9, 78.2e9, 79.5e9, 80.9e9], dtype=torch.float64)
    acq = Acquisition(tx, rx, freqs, torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64),
                      pattern_exponent=2.0, spreading=False)
    y = torch.complex(torch.randn(acq.shape, generator=generator), torch.randn(acq.shape, generator=generator))
    points = torch.rand(300, 3, generator=generator) * torch.tensor([0.2, 0.2, 0.3]) + torch.tensor([-0.1, -0.1, 0.3])
    exact = SensingOperator(acq).adjoint(y, points, per_view=True)
    assert _relative_error(fast_adjoint(acq, y, points, oversampling=32), exact) < 2e-3


def test_fast_image_of_a_simulated_scene_matches_exact_with_the_same_peak():
    scene = load_scene("sphere")
    radar = load_radar("near-77g")
    measurements = simulate(scene, radar, seed=0, spacing_m=0.0015)  # coarse points: a fast, not a converged, simulation
    measurements = Measurements(measurements.acquisition.view(slice(0, 3)), measurements.data[:3])
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, 0.01)
    exact = matched_filter(measurements, grid, method="exact")
    fast = matched_filter(measurements, grid, method="fast")
    assert _relative_error(fast.per_view, exact.per_view) < 3e-3
    assert int(fast.power().argmax()) == int(exact.power().argmax())
    torch.testing.assert_close(fast.column_norms_sq, exact.column_norms_sq)


def test_imaging_method_auto_and_unknown_names(small_acquisition):
    assert imaging_method(small_acquisition, "auto") == "exact"  # 16 frequencies
    many = Acquisition(small_acquisition.tx_m, small_acquisition.rx_m,
                       torch.linspace(77e9, 81e9, 64, dtype=torch.float64), small_acquisition.boresight)
    assert imaging_method(many, "auto") == "fast"
    one_frequency = Acquisition(small_acquisition.tx_m, small_acquisition.rx_m,
                                small_acquisition.frequencies_hz[:1], small_acquisition.boresight)
    assert imaging_method(one_frequency, "auto") == "exact"
    assert imaging_method(one_frequency, "fast") == "fast"
    with pytest.raises(ValueError, match="known: auto, exact, fast"):
        imaging_method(small_acquisition, "sar")


def test_the_cli_offers_exactly_the_imaging_methods():
    """The CLI lists the names itself (importing the imaging module would load torch on every
    command's start): the two lists must not drift apart. "scan" is the command's own: views
    that form a raster imaged as one (rfsdf.radar.scan_imaging)."""
    from rfsdf.cli import image_cmd
    from rfsdf.radar.imaging import IMAGING_METHODS

    method = next(p for p in image_cmd.params if p.name == "method")
    assert tuple(method.type.choices) == (*IMAGING_METHODS, "scan")


def test_range_profile_of_one_point_peaks_at_its_path_length():
    from rfsdf.radar.fast_imaging import range_profiles

    freqs = np.linspace(77e9, 81e9, 16, endpoint=False)
    path = 1.234
    k = 2 * np.pi * freqs / 299_792_458.0
    data = np.exp(-1j * k * path).reshape(1, 1, -1)  # one pair, one point at bistatic path 1.234 m
    profiles, step = range_profiles(data, freqs, 1.0, 1.5, oversampling=16)
    paths = 1.0 - step + step * np.arange(profiles.shape[-1])
    assert abs(paths[np.abs(profiles[0, 0]).argmax()] - path) <= step / 2 + 1e-12
    assert np.abs(profiles[0, 0]).max() == pytest.approx(16, rel=1e-3)
