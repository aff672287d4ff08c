"""Coherent imaging of a planar scan by FFT convolution: the exact operator's adjoint (to float
precision), and a point target imaged to the closed-form resolutions, cross-range
0.886 lambda R / (2 D) and range 0.886 c / (2 B)."""

import numpy as np
import pytest
import torch

from rfsdf.radar.acquisition import SPEED_OF_LIGHT, Acquisition
from rfsdf.radar.boards import board, board_positions
from rfsdf.radar.operator import SensingOperator
from rfsdf.radar.scan_imaging import PlanarScan, scan_image, scan_voxels


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
