import numpy as np
import pytest
import trimesh

from rfsdf.baseline import best_threshold_mesh, detection_mesh, threshold_mesh
from rfsdf.geometry import Grid

WIDTH = 0.02  # [m] of the Gaussian 'MF power' blob below


def _blob():
    """Power exp(-|p|^2 / 2 w^2): its level set at fraction a of the peak is the sphere of
    radius w sqrt(-2 ln a), a closed form for the baseline's geometry."""
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (48, 48, 48))
    r2 = (grid.points().numpy() ** 2).sum(1)
    return np.exp(-r2 / (2 * WIDTH**2)).reshape(grid.shape), grid


def test_threshold_mesh_is_the_closed_form_level_sphere():
    power, grid = _blob()
    mesh = threshold_mesh(power, grid, 0.5)
    radii = np.linalg.norm(mesh.vertices, axis=1)
    assert radii.mean() == pytest.approx(WIDTH * np.sqrt(2 * np.log(2)), abs=2e-4)
    assert np.dot(mesh.face_normals[0], mesh.triangles_center[0]) > 0  # normals point outward


def test_sweep_keeps_the_fraction_nearest_the_truth():
    power, grid = _blob()
    truth = trimesh.creation.icosphere(subdivisions=4, radius=WIDTH * np.sqrt(-2 * np.log(0.1)))
    result = best_threshold_mesh(power, grid, truth, fractions=(0.01, 0.1, 0.5), samples=50_000)
    assert result.fraction == 0.1
    assert result.metrics.chamfer_l1_mm < 0.5  # well below the 2.5 mm voxel (sample spacing ~0.7 mm)
    assert set(result.sweep) == {0.01, 0.1, 0.5} and min(result.sweep.values()) == result.metrics.chamfer_l1_mm
    with pytest.raises(ValueError, match="no threshold"):
        best_threshold_mesh(power, grid, truth, fractions=(1.5,))


def test_detection_cuts_each_bump_at_its_own_half_amplitude():
    """Two Gaussian power bumps, one 20 dB weaker: a global threshold at half the strong one's
    amplitude loses the weak one; the local rule cuts both at their own half-amplitude
    sphere, radius w sqrt(4 ln 2) for power exp(-r^2 / 2 w^2), when the window reaches the peak."""
    width = 0.008
    grid = Grid((-0.08, -0.04, -0.04), (0.08, 0.04, 0.04), (96, 48, 48))
    p = grid.points().numpy()
    centres, heights = np.array([[-0.04, 0, 0], [0.04, 0, 0]]), (1.0, 0.01)
    power = sum(h * np.exp(-((p - c) ** 2).sum(1) / (2 * width**2)) for c, h in zip(centres, heights))
    power = power.reshape(grid.shape)
    mesh = detection_mesh(power, grid, threshold=0.02, local_threshold=0.5, window_m=0.04)
    radii = np.linalg.norm(mesh.vertices[:, None] - centres[None], axis=2)
    nearest = radii.argmin(1)
    assert set(nearest) == {0, 1}  # both bumps detected
    for bump in (0, 1):
        assert radii[nearest == bump, bump].mean() == pytest.approx(width * np.sqrt(4 * np.log(2)), abs=3e-4)
    with pytest.raises(ValueError):
        threshold_mesh(power, grid, 1.5)
    assert len(threshold_mesh(power, grid, 0.25).split()) == 1  # the global rule keeps only the strong bump
    weak_side = (np.linalg.norm(p - centres[1], axis=1) < 0.02).reshape(grid.shape)
    kept = detection_mesh(power, grid, threshold=0.02, local_threshold=0.5, window_m=0.04, exclude=weak_side)
    assert (np.linalg.norm(kept.vertices - centres[0], axis=1) < 0.03).all()  # the excluded bump is gone
    assert len(kept.vertices) == pytest.approx((nearest == 0).sum(), rel=0.05)
