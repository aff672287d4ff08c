"""Point-target resolution against c/2B and lambda R / D; noise level; simulator sanity."""

import numpy as np
import pytest
import torch

from rfsdf.geometry import Grid
from rfsdf.radar import (
    SPEED_OF_LIGHT, Acquisition, half_power_width, load_radar, point_spread, range_resolution_m, simulate,
)
from rfsdf.radar.simulate import add_noise
from rfsdf.scene import load_scene


def _monostatic(xs_m, freqs_hz, *, spreading=True):
    """Co-located Tx and Rx positions along x at z = 0, one view, boresight +z."""
    pos = torch.tensor([[x, 0.0, 0.0] for x in xs_m], dtype=torch.float64)[None]
    return Acquisition(pos, pos.clone(), torch.as_tensor(freqs_hz, dtype=torch.float64),
                       torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64), spreading=spreading)


def test_point_target_range_width_matches_c_over_2b():
    freqs = np.linspace(77e9, 81e9, 64, endpoint=False)
    bandwidth = 64 * (freqs[1] - freqs[0])
    grid = Grid((-0.001, -0.001, 0.40), (0.001, 0.001, 0.60), (2, 2, 400))
    z = grid.axes()[2]
    # Without spreading the range response is the pure Dirichlet kernel of the K frequencies.
    profile = point_spread(_monostatic([0.0], freqs, spreading=False), (0.0, 0.0, 0.5), grid).power()[0, 0].numpy()
    assert abs(z[profile.argmax()] - 0.5) <= grid.voxel_m[2] / 2 + 1e-9  # peak on the target's voxel
    assert half_power_width(z, profile) == pytest.approx(0.886 * range_resolution_m(bandwidth), rel=0.10)
    # With 1/d^2 spreading, column normalisation weights voxel q by d_q^2 / d_p^2, which tilts
    # the main lobe outward: a bias of a few millimetres, well inside one resolution cell.
    spread = point_spread(_monostatic([0.0], freqs), (0.0, 0.0, 0.5), grid).power()[0, 0].numpy()
    assert 0 <= z[spread.argmax()] - 0.5 < 0.1 * range_resolution_m(bandwidth)


def test_cross_range_width_scales_as_lambda_r_over_d():
    freqs = [79e9]
    widths = []
    for aperture in (0.05, 0.10):
        xs = np.linspace(-aperture / 2, aperture / 2, 81)
        grid = Grid((-0.03, -0.0005, 0.4995), (0.03, 0.0005, 0.5005), (600, 2, 2))
        profile = point_spread(_monostatic(xs, freqs), (0.0, 0.0, 0.5), grid).power()[:, 0, 0].numpy()
        widths.append(half_power_width(grid.axes()[0], profile))
    wavelength = SPEED_OF_LIGHT / 79e9
    assert widths[0] / widths[1] == pytest.approx(2.0, rel=0.1)
    # Every Tx pairs with every Rx, so the midpoint (virtual) aperture is a uniform line
    # convolved with itself: a triangular taper, whose -3 dB width is 1.28 lambda R / (2 D)
    # (a uniform aperture would give 0.886).
    assert widths[1] == pytest.approx(1.28 * wavelength * 0.5 / (2 * 0.10), rel=0.05)


def test_noise_meets_requested_snr():
    y = torch.randn(200_000, dtype=torch.complex64)
    noisy, sigma = add_noise(y, 10.0, torch.Generator().manual_seed(0))
    measured = 10 * np.log10(float((y.abs() ** 2).mean()) / float(((noisy - y).abs() ** 2).mean()))
    assert measured == pytest.approx(10.0, abs=0.1)
    assert sigma**2 == pytest.approx(float((y.abs() ** 2).mean()) / 10, rel=1e-5)


def test_simulated_sphere_images_brightest_at_the_sphere():
    scene = load_scene("sphere")
    radar = load_radar("near-77g")
    radar = type(radar)(**{**radar.__dict__, "rotations": radar.rotations[:2], "positions_m": radar.positions_m[:2],
                           "tx_m": radar.tx_m[::6], "rx_m": radar.rx_m[::6]})
    m1 = simulate(scene, radar, seed=3, spacing_m=0.002)
    m2 = simulate(scene, radar, seed=3, spacing_m=0.002)
    torch.testing.assert_close(m1.data, m2.data)  # reproducible
    grid = Grid(scene.lower_m, scene.upper_m, (24, 24, 24))
    from rfsdf.radar import matched_filter

    power = matched_filter(m1, grid).power()
    peak = grid.points()[power.argmax()]
    assert abs(peak.norm().item() - 0.02) < 0.012  # the return comes from the sphere's surface


def test_in_front_of_ridges_marks_the_radar_side_half_of_a_range_blob():
    """A blob 3 cm deep along z, centred at z = 0, seen by a view on +z: the voxels above the
    ridge (nearer the radar) are marked, the ridge and the far half are not; a second view,
    from the side, that sees nothing marks nothing."""
    from rfsdf.radar.detection import in_front_of_ridges

    grid = Grid((-0.06,) * 3, (0.06,) * 3, (20,) * 3)  # 6 mm voxels, centres at +-3 mm, ...
    x, y, z = grid.points().double().numpy().T.reshape(3, *grid.shape)
    blob = np.exp(-(x**2 + y**2) / (2 * 0.006**2) - z**2 / (2 * 0.015**2))
    side = np.zeros(grid.shape)
    front = in_front_of_ridges(np.stack([blob, side]), np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), grid,
                               threshold=0.06, local_threshold=0.5, window_m=0.03)
    column = front[9, 9]  # the voxel column nearest the axis
    assert column[z[9, 9] > 0.004].any() and not column[z[9, 9] < 0].any()
    bright = blob[9, 9] >= 0.5
    assert column[bright & (z[9, 9] > 0.004)].all()  # the blob's near half, down to the ridge
    assert not front[np.abs(x) > 0.03].any()  # outside the blob nothing is marked


def test_range_peaks_place_a_point_between_voxel_centres_to_a_fraction_of_a_millimetre():
    """A point 2.8 mm off the nearest 6 mm voxel centre along the range, seen by a monostatic
    planar array on its axis: the detection's brightest ridge voxel is that far off the
    point's range, its refined peak within 0.1 mm of it; ridges whose peak lies beyond the
    span are dropped."""
    from rfsdf.radar import Measurements, matched_filter
    from rfsdf.radar.operator import SensingOperator
    from rfsdf.radar.range_peaks import range_peaks

    xs = np.linspace(-0.019, 0.019, 21)  # lambda / 2 apart: no grating lobes
    pos = torch.tensor([[x, y, 0.0] for x in xs for y in xs], dtype=torch.float64)[None]
    acq = Acquisition(pos, pos.clone(), torch.linspace(77e9, 81e9, 16, dtype=torch.float64),
                      torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))
    target = torch.tensor([[0.0011, -0.0007, 0.1078]], dtype=torch.float64)  # voxel centres at z = 0.105, 0.111
    data = SensingOperator(acq).forward(target, torch.ones(1, dtype=torch.complex128))
    measurements = Measurements(acq, data)
    grid = Grid((-0.03, -0.03, 0.072), (0.03, 0.03, 0.132), (10, 10, 10))
    per_view = (matched_filter(measurements, grid).per_view.abs() ** 2).numpy()
    peaks = range_peaks(measurements, per_view, grid, threshold=0.3, local_threshold=0.5, window_m=0.03)
    brightest = peaks.points[peaks.amplitude.argmax()]
    voxel = grid.points().double().numpy()[np.argmin(np.linalg.norm(grid.points().double().numpy()
                                                                     - target.numpy(), axis=1))]
    target_range = float(target.norm())
    assert abs(np.linalg.norm(voxel) - target_range) > 0.002  # the voxel's own error
    assert abs(np.linalg.norm(brightest) - target_range) < 1e-4
    assert np.allclose(peaks.towards[peaks.amplitude.argmax()], -brightest / np.linalg.norm(brightest), atol=0.05)
    assert peaks.amplitude.max() == 1.0 and (peaks.view == 0).all()
    narrow = range_peaks(measurements, per_view, grid, threshold=0.3, local_threshold=0.5, window_m=0.03,
                         span_m=0.0005, step_m=0.0005)
    assert len(narrow.points) < len(peaks.points)  # ridges whose peak is over 0.5 mm away are dropped


def test_a_glints_apex_is_the_strongest_peak_of_its_own_view_within_a_radius():
    """Two glints of view 0 along a line (peaks 2 mm apart, their amplitude falling off each
    side of a centre at 0 and at 40 mm), and view 1 with a weaker peak where view 0's centre
    is: each view's apexes within 12 mm are the centres (view 1's own peak among them, another
    view being no competitor); within 50 mm only the stronger glint's; ties are both kept."""
    from rfsdf.radar.range_peaks import RangePeaks

    x = np.arange(-0.006, 0.0461, 0.002)
    amplitude = np.maximum(np.exp(-(x / 0.004) ** 2), 0.8 * np.exp(-((x - 0.04) / 0.004) ** 2))
    points = np.stack([x, np.zeros_like(x), np.full_like(x, 0.3)], 1)
    peaks = RangePeaks(np.concatenate([points, [[0.0, 0.0, 0.3]]]), np.concatenate([amplitude, [0.5]]),
                       np.concatenate([np.zeros(len(x), int), [1]]), np.tile([0.0, 0.0, -1.0], (len(x) + 1, 1)))
    centres = np.flatnonzero(peaks.apexes(0.012))
    assert np.allclose(peaks.points[centres[:2], 0], [0.0, 0.04]) and centres[2] == len(x)
    assert np.flatnonzero(peaks.apexes(0.05)).tolist() == [3, len(x)]
    twins = RangePeaks(points[:2], np.ones(2), np.zeros(2, int), np.tile([0.0, 0.0, -1.0], (2, 1)))
    assert twins.apexes(0.012).all()


def test_range_sidelobes_match_the_dirichlet_kernel():
    """K uniform frequencies: the range profile is |sin(K x) / (K sin x)|, x = 2 pi delta_f d / c,
    its first null at c / 2B and its peak sidelobe (computed here from that closed form on a
    fine grid) 0.22 for K = 16, tending to the sinc's 2 / (3 pi) as K grows."""
    from rfsdf.radar.waveform import ofdm_frequencies, range_response, range_sidelobes

    for k in (16, 64):
        freqs = ofdm_frequencies(79e9, 4e9, k)
        step = freqs[1] - freqs[0]
        d = np.linspace(1e-4, SPEED_OF_LIGHT / (4 * step), 200_001)  # up to half the unambiguous range
        x = 2 * np.pi * step * d / SPEED_OF_LIGHT
        dirichlet = np.abs(np.sin(k * x) / (k * np.sin(x)))
        assert np.allclose(range_response(freqs, d[::997]), dirichlet[::997], atol=1e-9)
        null, level = range_sidelobes(freqs)
        assert null == pytest.approx(range_resolution_m(4e9), rel=1e-3)
        assert level == pytest.approx(dirichlet[d > 1.01 * null].max(), rel=1e-3)
    assert level == pytest.approx(2 / (3 * np.pi), rel=0.03)
    assert range_sidelobes([79e9]) == (float("inf"), 1.0)


def test_sidelobes_are_what_a_views_glints_explain_by_their_point_spread():
    """Data of a bright point and a weaker one 3 cm beside it and 5 cm behind, seen by a planar
    array on the bright one's axis; handed as peaks: the bright point (the glint), a peak at
    its first range sidelobe on its axis (1.43 range resolutions behind, where nothing is),
    a peak in its main lobe 5 mm behind it, and the weaker point. Only the range sidelobe is
    marked: the glint's response there is all the data show; the weaker point returns far more
    than the glint's sidelobes reach, and the main lobe is not tested. Of a detection in the
    data's image, the voxels at that sidelobe are marked, none at the two points."""
    from rfsdf.radar import Measurements, matched_filter
    from rfsdf.radar.glint_sidelobes import sidelobe_peaks, sidelobe_voxels
    from rfsdf.radar.operator import SensingOperator
    from rfsdf.radar.range_peaks import RangePeaks

    xs = np.linspace(-0.019, 0.019, 21)
    pos = torch.tensor([[x, y, 0.0] for x in xs for y in xs], dtype=torch.float64)[None]
    acq = Acquisition(pos, pos.clone(), torch.linspace(77e9, 81e9, 16, dtype=torch.float64),
                      torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))
    targets = torch.tensor([[0.0, 0.0, 0.15], [0.03, 0.0, 0.20]], dtype=torch.float64)
    data = SensingOperator(acq).forward(targets, torch.tensor([1.0, 0.3], dtype=torch.complex128))
    sidelobe_m = 0.15 + 1.43 * range_resolution_m(4e9)
    points = np.array([[0.0, 0.0, 0.15], [0.0, 0.0, sidelobe_m], [0.0, 0.0, 0.155], [0.03, 0.0, 0.20]])
    peaks = RangePeaks(points, np.array([1.0, 0.2, 0.4, 0.3]), np.zeros(4, int), np.tile([0.0, 0.0, -1.0], (4, 1)))
    marked = sidelobe_peaks(Measurements(acq, data), peaks)
    assert marked.tolist() == [False, True, False, False]
    assert not sidelobe_peaks(Measurements(acq, data), peaks.select([0, 2])).any()  # nothing beyond the main lobe
    kept = peaks.select(~marked)
    assert np.allclose(kept.points, points[[0, 2, 3]]) and kept.amplitude.tolist() == [1.0, 0.4, 0.3]
    # the same peak where a face as bright as the glint returns is kept
    with_face = SensingOperator(acq).forward(torch.tensor([[0.0, 0.0, sidelobe_m]], dtype=torch.float64),
                                             torch.tensor([1.0], dtype=torch.complex128)) + data
    assert not sidelobe_peaks(Measurements(acq, with_face), peaks)[1]
    # a detection of the data's own image: the voxels around the sidelobe are marked, none at the points
    grid = Grid((-0.045, -0.045, 0.105), (0.045, 0.045, 0.285), (15, 15, 30))  # 6 mm voxels
    measurements = Measurements(acq, data)
    per_view = (matched_filter(measurements, grid).per_view.abs() ** 2).numpy()
    voxels = sidelobe_voxels(measurements, peaks, per_view, grid, threshold=0.1, local_threshold=0.5, window_m=0.03)
    centres = grid.points().double().numpy()
    nearest = lambda p: np.linalg.norm(centres - p, axis=1).argmin()  # noqa: E731
    assert voxels.ravel()[nearest(points[1])] and voxels.any()
    assert not voxels.ravel()[[nearest(points[0]), nearest(points[3])]].any()
    assert voxels.sum() < 0.1 * voxels.size


def test_on_range_sidelobes_marks_a_weak_copy_on_a_bright_glints_line_of_sight():
    """A bright blob at the origin seen from +z, and a blob 0.1 as bright one range resolution
    (37.5 mm) nearer the array: the weak one is a sidelobe (marked), the bright one is not.
    The same weak blob beside the line of sight, or as bright as 0.5 (above the -13 dB
    sidelobe level), or also seen by a second view in which nothing brighter is on its line
    of sight, is genuine (not marked)."""
    from rfsdf.radar.detection import on_range_sidelobes
    from rfsdf.radar.waveform import ofdm_frequencies

    grid = Grid((-0.12,) * 3, (0.12,) * 3, (40,) * 3)  # 6 mm voxels
    x, y, z = grid.points().double().numpy().T.reshape(3, *grid.shape)
    freqs = ofdm_frequencies(79e9, 4e9, 16)

    def blob(cx, cz, amplitude):
        return amplitude * np.exp(-((x - cx) ** 2 + y**2 + (z - cz) ** 2) / (2 * 0.006**2))

    def marked(views, centres):
        power = np.stack(views) ** 2
        return on_range_sidelobes(power, np.array(centres), freqs, grid, threshold=0.01, local_threshold=0.5,
                                  window_m=0.03)

    above = [0.0, 0.0, 1.0]
    near_weak = (np.abs(x) < 0.007) & (np.abs(y) < 0.007) & (np.abs(z - 0.0375) < 0.007)
    near_bright = (np.abs(x) < 0.007) & (np.abs(y) < 0.007) & (np.abs(z) < 0.007)
    lobe = marked([blob(0, 0, 1.0) + blob(0, 0.0375, 0.1)], [above])
    assert lobe[near_weak].all() and not lobe[near_bright].any()
    assert not lobe[np.abs(z - 0.0375) > 0.02].any()  # nothing else is marked
    assert not marked([blob(0, 0, 1.0) + blob(0.06, 0.0375, 0.1)], [above]).any()  # off the line of sight
    assert not marked([blob(0, 0, 1.0) + blob(0, 0.0375, 0.5)], [above]).any()  # brighter than a sidelobe
    # ... unless the level asks any detection under 0.6 of a brighter voxel on its line of sight to go
    half = np.stack([blob(0, 0, 1.0) + blob(0, 0.0375, 0.5)]) ** 2
    rule = dict(threshold=0.01, local_threshold=0.5, window_m=0.03)
    assert on_range_sidelobes(half, np.array([above]), freqs, grid, level=0.6, **rule)[near_weak].all()
    assert not on_range_sidelobes(half, np.array([above]), freqs, grid, level=0.4, **rule).any()
    side_view = blob(0, 0.0375, 0.1)  # seen from +x with nothing in its way
    assert not marked([blob(0, 0, 1.0) + blob(0, 0.0375, 0.1), side_view], [above, [1.0, 0.0, 0.0375]]).any()
    # a copy 18 cm (4.8 range resolutions) behind the glint is beyond the default reach of four, not beyond ten
    far = np.stack([blob(0, 0.09, 1.0) + blob(0, -0.09, 0.1)]) ** 2
    near_far = (np.abs(x) < 0.007) & (np.abs(y) < 0.007) & (np.abs(z + 0.09) < 0.007)
    assert not on_range_sidelobes(far, np.array([above]), freqs, grid, **rule)[near_far].any()
    assert on_range_sidelobes(far, np.array([above]), freqs, grid, reach=10.0, **rule)[near_far].all()


def test_specular_normals_are_the_power_weighted_mean_bisector():
    """Against a slow per-voxel reference, and a closed form: four monostatic views on a cone
    of half-angle a around n0 with equal power give m = cos(a) n0 (the sideways parts cancel);
    a voxel only one view sees gets that view's bisector, of unit length."""
    from rfsdf.radar.specular import specular_normals

    grid = Grid((-0.01,) * 3, (0.01,) * 3, (2, 2, 2))
    rng = np.random.default_rng(0)
    tx, rx = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    power = rng.random((3, *grid.shape))
    power[1:, 0, 0, 0] = 0.0
    mean = specular_normals(power, tx, rx, grid)
    for (i, j, k), point in zip(np.ndindex(grid.shape), grid.points().double().numpy()):
        unit = lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True)  # noqa: E731
        bisectors = unit(unit(tx - point) + unit(rx - point))
        expected = (power[:, i, j, k, None] * bisectors).sum(0) / power[:, i, j, k].sum()
        np.testing.assert_allclose(mean[:, i, j, k], expected, rtol=1e-5, atol=1e-6)
    assert np.linalg.norm(mean[:, 0, 0, 0]) == pytest.approx(1.0, rel=1e-5)

    centre = grid.points().double().numpy()[0]
    n0, a = np.array([0.0, 0.6, 0.8]), np.deg2rad(25)
    side = np.cross(n0, [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    other = np.cross(n0, side)
    views = np.array([centre + 5.0 * (np.cos(a) * n0 + np.sin(a) * (np.cos(t) * side + np.sin(t) * other))
                      for t in np.arange(4) * np.pi / 2])
    cone = specular_normals(np.ones((4, *grid.shape)), views, views, grid)[:, 0, 0, 0]
    np.testing.assert_allclose(cone, np.cos(a) * n0, atol=1e-6)
