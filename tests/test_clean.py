"""CLEAN finds a weak point target that the strong one's sidelobes hide from the MF threshold."""

import numpy as np
import pytest
import torch

from rfsdf.geometry import Grid
from rfsdf.radar import Acquisition, Measurements, SensingOperator, matched_filter
from rfsdf.radar.clean import clean_image

STRONG, WEAK = (0.0, 0.0, 0.40), (0.021, 0.0, 0.46)  # both on voxel centres of the grid below
WEAK_AMPLITUDE = 0.1  # 20 dB below the strong target


def _scene():
    x = np.linspace(-0.03, 0.03, 10)
    elements = torch.tensor([[v, 0.0, 0.0] for v in x], dtype=torch.float64)[None]
    acq = Acquisition(elements, elements.clone(), torch.linspace(77e9, 81e9, 16, dtype=torch.float64),
                      torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))
    points = torch.tensor([STRONG, WEAK], dtype=torch.float32)
    y = SensingOperator(acq).forward(points, torch.tensor([1.0, WEAK_AMPLITUDE], dtype=torch.complex64))
    grid = Grid((-0.0615, -0.0015, 0.3385), (0.0585, 0.0045, 0.5185), (40, 2, 60))  # 3 mm voxels
    return Measurements(acq, y), grid


def _far_from_targets(grid, distance_m):
    p = grid.points().numpy()
    return np.all([np.linalg.norm(p - np.asarray(t), axis=1) > distance_m for t in (STRONG, WEAK)], axis=0)


def _value_at(grid, image, point):
    index = int(np.argmin(np.linalg.norm(grid.points().numpy() - np.asarray(point), axis=1)))
    return float(image.flatten()[index])


def test_clean_recovers_a_target_20_db_below_a_stronger_one():
    data, grid = _scene()
    far = _far_from_targets(grid, 0.015)
    mf = matched_filter(data, grid).power(coherent=False).numpy()
    # The MF threshold cannot keep the weak target without keeping the strong one's sidelobes.
    assert _value_at(grid, mf, WEAK) < mf.flatten()[far].max()

    result = clean_image(data, grid, gain=0.2, stop_fraction=0.01, window_m=0.2, major_every=10)
    power = result.power.numpy()
    assert _value_at(grid, power, WEAK) > 3 * power.flatten()[far].max()
    points = grid.points()[result.component_index[0]].numpy()
    # The line array does not resolve y, so the weak point's components share its voxel and the
    # neighbours within one voxel; their magnitudes add up to its amplitude.
    near_weak = np.linalg.norm(points - np.asarray(WEAK), axis=1) < 0.0045
    found = result.component_amplitude[0][torch.from_numpy(near_weak)].abs().sum()
    assert float(found) == pytest.approx(WEAK_AMPLITUDE, rel=0.2)


def test_residual_floor_is_what_clean_left_and_falls_as_clean_goes_deeper():
    data, grid = _scene()
    floors = {}
    for stop in (0.3, 0.03):
        result = clean_image(data, grid, gain=0.2, stop_fraction=stop, window_m=0.2, major_every=10)
        # Independent computation: 99th percentile over voxels of the rms residual over views,
        # over the peak restored amplitude.
        rms = np.sqrt((np.abs(result.residual.numpy()) ** 2).mean(0))
        expected = np.sort(rms.ravel())[int(round(0.99 * (rms.size - 1)))] / np.sqrt(result.power.numpy().max())
        floors[stop] = result.residual_floor()
        assert floors[stop] == pytest.approx(expected, rel=0.05)
        # The residual stays below the stop level of the dirty peak; the restored peak is a little
        # lower than the dirty one (a target's components spread over neighbouring voxels).
        assert floors[stop] <= 1.2 * stop
    assert floors[0.03] < 0.5 * floors[0.3]
