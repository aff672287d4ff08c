"""Coherent imaging of a planar scan by FFT convolution: the exact operator's adjoint (to float
precision), and a point target imaged to the closed-form resolutions, cross-range
0.886 lambda R / (2 D) and range 0.886 c / (2 B); views that are one board's positions found
to be a raster and imaged as one coherent view, by the library and by `rfsdf image`."""

import numpy as np
import pytest
import torch

from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.geometry import Grid
from rfsdf.radar import write_measurements
from rfsdf.radar.acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from rfsdf.radar.boards import board, board_positions
from rfsdf.radar.operator import SensingOperator
from rfsdf.radar.scan_imaging import PlanarScan, planar_scan, scan_image, scan_matched_filter, scan_voxels


def _scan(shape, step, tx, rx, frequencies, depth=0.2):
    """A raster of ``shape`` positions ``step`` apart, centred on x = y = 0, ``depth`` in front of
    the origin; its acquisition as one view per position (the exact operator's reference)."""
    origin = np.array([-(shape[0] - 1) * step / 2, -(shape[1] - 1) * step / 2, -depth])
    scan = PlanarScan(origin, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), (step, step), shape,
                      np.repeat(tx, len(rx), 0), rx, frequencies)
    positions = scan.positions_m().reshape(-1, 3)
    acquisition = Acquisition(torch.from_numpy(positions[:, None] + tx[None]),
                              torch.from_numpy(positions[:, None] + rx[None]), torch.from_numpy(frequencies),
                              torch.tensor([[0, 0, 1.0]]).repeat(len(positions), 1), 0.0, True)
    return scan, SensingOperator(acquisition)


def test_the_fft_image_of_a_scan_is_the_exact_operators_adjoint():
    tx, rx = board_positions(board("iwr1443"), np.zeros((1, 3)), np.array([0, 0, 1.0]), np.array([0, -1.0, 0]))
    scan, operator = _scan((16, 12), 4e-3, tx[0], rx[0], 77e9 + np.arange(24) * 4e9 / 24)
    targets = torch.tensor([[0.0, 0.0, 0.0], [0.01, 0.005, 0.02]], dtype=torch.float64)
    y = operator.forward(targets, torch.tensor([1.0, 0.7j], dtype=torch.complex128))
    first, count, depths = (2, -3), (10, 9), np.linspace(0.17, 0.23, 7)  # voxels beyond the raster too
    voxels = scan_voxels(scan, first, count, depths)
    exact = operator.adjoint(y, torch.from_numpy(voxels.reshape(-1, 3))).reshape(voxels.shape[:3])
    image = scan_image(scan, y.reshape(16, 12, 4, 24), first, count, depths)
    assert float((image - exact).norm() / exact.norm()) < 1e-9


def _half_power_width(values: np.ndarray, step: float) -> float:
    power = np.abs(values) ** 2 / np.max(np.abs(values) ** 2)
    above = np.nonzero(power >= 0.5)[0]
    lo, hi = above[0], above[-1]  # interpolated linearly at both crossings
    left = lo - 1 + (0.5 - power[lo - 1]) / (power[lo] - power[lo - 1])
    right = hi + (power[hi] - 0.5) / (power[hi] - power[hi + 1])
    return (right - left) * step


def test_a_point_target_is_imaged_to_the_closed_form_resolutions():
    """128 positions 0.5 mm apart (D = 64 mm), 0.2 m from a point, 32 frequencies over 4 GHz."""
    n, step, depth = 128, 0.5e-3, 0.2
    frequencies = np.linspace(77e9, 81e9, 32)
    scan, operator = _scan((n, 1), step, np.zeros((1, 3)), np.zeros((1, 3)), frequencies, depth)
    y = operator.forward(torch.zeros(1, 3, dtype=torch.float64), torch.ones(1, dtype=torch.complex128))
    data = y.reshape(n, 1, 1, -1)
    across = scan_image(scan, data, (0, 0), (n, 1), np.array([depth]))[:, 0, 0].numpy()
    wavelength = SPEED_OF_LIGHT / frequencies.mean()
    assert _half_power_width(across, step) == pytest.approx(0.886 * wavelength * depth / (2 * n * step), rel=0.05)
    assert abs(np.argmax(np.abs(across)) - (n - 1) / 2) <= 0.5
    depths = np.linspace(0.1, 0.3, 401)
    along = scan_image(scan, data, ((n - 1) // 2, 0), (1, 1), depths)[0, 0].numpy()
    bandwidth = len(frequencies) * (frequencies[1] - frequencies[0])  # K samples Delta f apart
    assert _half_power_width(along, depths[1] - depths[0]) == pytest.approx(
        0.886 * SPEED_OF_LIGHT / (2 * bandwidth), rel=0.05)
    assert abs(depths[np.argmax(np.abs(along))] - depth) < 0.005  # the 1/d^2 weights pull the peak a few mm in


def test_a_scan_refuses_what_it_cannot_image():
    ok = dict(origin_m=np.zeros(3), axis_x=np.array([1.0, 0, 0]), axis_y=np.array([0, 1.0, 0]), steps_m=(1e-3, 1e-3),
              shape=(4, 4), tx_offsets_m=np.zeros((1, 3)), rx_offsets_m=np.zeros((1, 3)), frequencies_hz=np.array([77e9]))
    for bad, message in (({"axis_y": np.array([1.0, 1.0, 0])}, "orthonormal"),
                         ({"rx_offsets_m": np.zeros((2, 3))}, r"\(P, 3\)"), ({"steps_m": (0.0, 1e-3)}, "steps_m > 0")):
        with pytest.raises(ValueError, match=message):
            PlanarScan(**{**ok, **bad})
    with pytest.raises(ValueError, match=r"data must be \(nx, ny, P, K\)"):
        scan_image(PlanarScan(**ok), torch.zeros(4, 4, 2, 1, dtype=torch.complex64), (0, 0), (4, 4), np.array([0.1]))


def _serpentine_views(nx=12, nz=10, step=2e-3, jitter=0.0, drop=0):
    """An IWR1443 scanned serpentine-wise over an x-z raster at y = -0.2 m, looking along +y,
    stepping along -x first; one view per position (as `rfsdf import` makes them)."""
    a, b = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    b = np.where(a % 2 == 1, nz - 1 - b, b)
    positions = np.stack([0.01 - a.ravel() * step, np.full(a.size, -0.2), -0.01 + b.ravel() * step], 1)
    positions = positions[drop:] + jitter * np.random.default_rng(0).standard_normal((a.size - drop, 3))
    tx, rx = board_positions(board("iwr1443"), positions, np.array([0, 1.0, 0]), np.array([0, 0, 1.0]))
    boresight = torch.tensor([[0, 1.0, 0]]).repeat(len(positions), 1)
    return Acquisition(torch.from_numpy(tx), torch.from_numpy(rx), torch.linspace(77e9, 81e9, 16, dtype=torch.float64),
                       boresight, pattern_exponent=1.0)


def test_views_on_a_raster_are_imaged_as_one_coherent_view_exactly():
    acquisition = _serpentine_views()
    scan, index = planar_scan(acquisition)
    assert scan.shape == (10, 12) and scan.steps_m == pytest.approx((2e-3, 2e-3))
    assert np.allclose(scan.axis_z, [0, 1, 0])  # facing the boresight
    assert sorted(map(tuple, index)) == [(i, j) for i in range(10) for j in range(12)]
    operator = SensingOperator(acquisition)
    targets = torch.tensor([[0.0, 0.0, 0.0], [0.004, 0.01, -0.003]], dtype=torch.float64)
    y = operator.forward(targets, torch.tensor([1.0, 0.5j], dtype=torch.complex128))
    image = scan_matched_filter(Measurements(acquisition, y.to(torch.complex64)),
                                Grid((-0.01, -0.02, -0.01), (0.012, 0.02, 0.01), (11, 8, 10)))
    assert image.per_view.shape[0] == 1 and image.grid.voxel_m[[0, 2]] == pytest.approx([2e-3, 2e-3])
    points = image.grid.points(dtype=torch.float64)
    exact = (operator.adjoint(y, points) / operator.column_norms_sq(points)).reshape(image.grid.shape)
    assert float((image.per_view[0].to(torch.complex128) - exact).norm() / exact.norm()) < 1e-6
    assert float((image.column_norms_sq[0].double() - operator.column_norms_sq(points).reshape(image.grid.shape)).abs().max()
                 / operator.column_norms_sq(points).max()) < 1e-6


@pytest.mark.parametrize("change, message", [
    ({"drop": 1}, "do not fill a 10 x 12 raster: 1 missing"),
    ({"jitter": 5e-4}, "mm off"),
])
def test_views_that_are_not_a_raster_are_refused_with_the_reason(change, message):
    with pytest.raises(ValueError, match=message):
        planar_scan(_serpentine_views(**change))


def test_views_of_different_boards_are_not_a_scan():
    acquisition = _serpentine_views()
    rx = acquisition.rx_m.clone()
    rx[3, 0, 0] += 1e-3
    moved = Acquisition(acquisition.tx_m, rx, acquisition.frequencies_hz, acquisition.boresight)
    with pytest.raises(ValueError, match="not one board moved"):
        planar_scan(moved)


def test_rfsdf_image_images_a_scan_coherently_and_refuses_scan_imaging_of_other_views(tmp_path):
    acquisition = _serpentine_views()
    y = SensingOperator(acquisition).forward(torch.zeros(1, 3, dtype=torch.float64), torch.ones(1, dtype=torch.complex128))
    write_measurements(tmp_path / "scan.h5", Measurements(acquisition, y.to(torch.complex64)))
    bounds = "--bounds=-0.01,-0.02,-0.01,0.012,0.02,0.01"
    run = CliRunner().invoke(main, ["image", str(tmp_path / "scan.h5"), "--out", str(tmp_path / "image.h5"), bounds])
    assert run.exit_code == 0, run.output
    assert "10 x 12 raster scan" in run.output and (tmp_path / "image.mip.png").exists()
    several = _serpentine_views(nx=3, nz=1, step=0.05)
    tilted = Acquisition(several.tx_m, several.rx_m, several.frequencies_hz,
                         torch.tensor([[0, 1.0, 0], [0.6, 0.8, 0], [0, 0.8, 0.6]], dtype=torch.float64))
    y = torch.zeros(tilted.shape, dtype=torch.complex64)
    write_measurements(tmp_path / "views.h5", Measurements(tilted, y))
    run = CliRunner().invoke(main, ["image", str(tmp_path / "views.h5"), "--out", str(tmp_path / "v.h5"), bounds,
                                    "--method", "scan"])
    assert run.exit_code == 2 and run.output.strip().splitlines() == [
        "error: --method scan: the views are not one board moved: their boresights differ"]
