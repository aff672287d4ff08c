"""Views that are whole scans: a board moved over a raster at each turntable angle, every
position a frame of its own Tx and Rx, the frames of one pose imaged as one coherent view
(preset ``sar-77g``). The radar lays the frames out, the simulator measures them as it would
frame by frame, the HDF5 file keeps which scan each frame belongs to, and the matched filter
sums a scan's frames: exactly (the sum of their back-projections), by range profiles and by
FFT on the raster's lattice alike; the preset resolves a point to the closed forms; and the
fit's renderer takes a scan as one view."""

import dataclasses

import numpy as np
import pytest
import torch

from rfsdf.errors import RfsdfError
from rfsdf.geometry import Grid
from rfsdf.radar import load_radar, matched_filter, read_measurements, write_measurements
from rfsdf.radar.acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
import rfsdf.radar.clean as clean_module
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.radar.operator import SensingOperator
from rfsdf.radar.scan_imaging import lattice_grid, planar_scan, scan_image, scan_views_matched_filter
from rfsdf.radar.simulate import SIMULATED_GAIN, simulate
from rfsdf.recon.render import CoherentRenderer
from rfsdf.scene import load_scene

_SMALL_SAR = """
name = "small-sar"
[waveform]
kind = "fmcw"
start_hz = 77.5e9
slope_hz_per_s = 58.61e12
sample_rate_hz = 0.3125e6
samples = 8
[array]
kind = "board"
board = "iwr1443"
scan_steps = [4, 3]
scan_step_m = 0.004
scan_capture = "frames"
[views]
distance_m = 0.2
azimuths_per_ring = [2]
elevations_rad = [0.0]
"""


class _Ball(torch.nn.Module):
    """The sphere scene's 2 cm ball as a field: f = |p| - r, a free reflectivity 1."""

    def sdf(self, points):
        return points.norm(dim=1) - 0.02

    def reflectivity(self, points):
        return torch.ones(len(points))


@pytest.fixture()
def small_sar(tmp_path):
    path = tmp_path / "small-sar.toml"
    path.write_text(_SMALL_SAR)
    return load_radar(path)


def test_the_sar_preset_makes_every_position_a_frame_and_each_turntable_angle_a_view():
    radar = load_radar("sar-77g")
    acq = radar.acquisition()
    assert acq.shape == (4 * 33 * 33, 1, 4, 64) and acq.num_views == 4 and radar.num_views == 4
    half = SPEED_OF_LIGHT / 79e9 / 2
    for view in range(4):
        frames = acq.frames(view)
        assert len(frames) == 33 * 33
        scan, _ = planar_scan(acq.coherent_view(view))
        assert scan.shape == (33, 33) and scan.steps_m == pytest.approx((0.003, 0.003))
        # the raster's plane is 0.2 m from the turntable's axis, facing it
        assert float(scan.origin_m @ scan.axis_z) == pytest.approx(-0.2)
        # the IWR1443: Rx k 5 mm + (3 - k) lambda/2 from Tx0 along the board
        gaps = (acq.rx_m[frames[0], :, :] - acq.tx_m[frames[0], 0]).norm(dim=1).numpy()
        assert gaps == pytest.approx([0.005 + (3 - k) * half for k in range(4)])
    assert "4 views" in radar.summary() and "a scan of 1089 frames" in radar.summary()


def test_scans_number_the_views_and_survive_a_file(tmp_path, small_sar):
    acq = small_sar.acquisition()
    assert acq.scans.tolist() == [0] * 12 + [1] * 12
    assert acq.view(torch.arange(10, 20)).scans.tolist() == [0, 0] + [1] * 8  # renumbered in order
    data = torch.randn(acq.shape, dtype=torch.complex64)
    back = read_measurements(write_measurements(tmp_path / "m.h5", Measurements(acq, data)))
    assert torch.equal(back.acquisition.scans, acq.scans) and torch.equal(back.data, data)
    with pytest.raises(ValueError, match="every number used"):
        dataclasses.replace(acq, scans=acq.scans * 2)
    with pytest.raises(ValueError, match="integers"):
        dataclasses.replace(acq, scans=acq.scans.double())


def test_bad_scanned_radars_are_refused_in_one_line(tmp_path):
    for change, message in ((('board = "iwr1443"', 'board = "iwr9999"'), "unknown board 'iwr9999'"),
                            (("scan_step_m = 0.004\n", ""), "needs scan_step_m"),
                            (('board = "iwr1443"', 'board = "iwr1443"\ntx_mask = 8'), "tx_mask 0x8 enables Tx")):
        path = tmp_path / "bad.toml"
        path.write_text(_SMALL_SAR.replace(*change))
        with pytest.raises(RfsdfError, match=message):
            load_radar(path)


def test_a_scan_is_simulated_as_its_frames_one_by_one(small_sar):
    """A convex scene shadows nothing but what faces away, so the scan's shared shadows (from
    its centre) change nothing: its frames' data are those of the same frames as views."""
    scene = load_scene("sphere")
    radar = dataclasses.replace(small_sar, snr_db=None)
    scanned = simulate(scene, radar)
    framed = simulate(scene, dataclasses.replace(radar, scans=None))
    assert framed.acquisition.scans is None and scanned.acquisition.scans is not None
    assert float((scanned.data - framed.data).norm() / framed.data.norm()) < 1e-5


def test_a_scans_image_is_the_coherent_sum_of_its_frames_by_every_method(small_sar):
    scene = load_scene("sphere")
    data = simulate(scene, dataclasses.replace(small_sar, snr_db=None))
    acq = data.acquisition
    grid = lattice_grid(acq, (-0.03, -0.03, -0.03), (0.03, 0.03, 0.03))
    assert grid.voxel_m == pytest.approx([0.004] * 3)
    exact = matched_filter(data, grid, method="exact")
    assert exact.per_view.shape == (2, *grid.shape)
    points = grid.points()
    for view in range(2):  # the reference: one operator over the scan's frames, summed
        op = SensingOperator(acq.coherent_view(view))
        y = data.data[acq.frames(view)]
        reference = (op.adjoint(y, points) / op.column_norms_sq(points)).reshape(grid.shape)
        assert float((exact.per_view[view] - reference).norm() / reference.norm()) < 1e-5
    fast = matched_filter(data, grid, method="fast")
    assert float((fast.per_view - exact.per_view).norm() / exact.per_view.norm()) < 1e-2
    by_fft = scan_views_matched_filter(data, grid)
    assert float((by_fft.per_view - exact.per_view).norm() / exact.per_view.norm()) < 1e-4
    assert torch.equal(matched_filter(data, grid).per_view, by_fft.per_view)  # "auto" takes the FFT where it can
    off_lattice = Grid((-0.03,) * 3, (0.03,) * 3, (10, 10, 10))
    with pytest.raises(ValueError, match="does not put its lattice on the grid"):
        scan_views_matched_filter(data, off_lattice)
    auto = matched_filter(data, off_lattice)  # ... and back-projects where it cannot
    assert torch.allclose(auto.per_view, matched_filter(data, off_lattice, method="exact").per_view, rtol=1e-4,
                          atol=1e-4 * float(auto.per_view.abs().max()))


def _half_power_width(values: np.ndarray, step: float) -> float:
    power = np.abs(values) ** 2 / np.max(np.abs(values) ** 2)
    above = np.nonzero(power >= 0.5)[0]
    lo, hi = above[0], above[-1]
    left = lo - 1 + (0.5 - power[lo - 1]) / (power[lo] - power[lo - 1])
    right = hi + (power[hi] - 0.5) / (power[hi] - power[hi + 1])
    return (right - left) * step


def test_the_sar_preset_resolves_a_point_to_the_closed_forms():
    """A point on the turntable's axis, seen by the first scan: across the raster, 0.886
    lambda R / (2 D) for the raster's span D (the board's own 1 cm adds to it: within 10 %);
    along the range from the middle frame alone, 0.886 c / (2 B). (The whole scan resolves
    range finer: its oblique paths widen the band of round-trip wavenumbers along z.)"""
    acq = load_radar("sar-77g").acquisition().coherent_view(0)
    scan, index = planar_scan(acq)
    y = SensingOperator(acq).forward(torch.zeros(1, 3, dtype=torch.float64), torch.ones(1, dtype=torch.complex128))
    data = torch.zeros(*scan.shape, len(scan.tx_offsets_m), y.shape[-1], dtype=torch.complex128)
    data[index[:, 0], index[:, 1]] = y.reshape(len(index), -1, y.shape[-1])
    span, depth = (scan.shape[0] - 1) * scan.steps_m[0], 0.2
    middle = (scan.shape[0] - 1) // 2
    across = scan_image(scan, data, (0, middle), (scan.shape[0], 1), np.array([depth]))[:, 0, 0].numpy()
    wavelength = SPEED_OF_LIGHT / float(acq.frequencies_hz.mean())
    assert _half_power_width(across, scan.steps_m[0]) == pytest.approx(0.886 * wavelength * depth / (2 * span), rel=0.1)
    # the middle frame's correlation with a point moved along its boresight: no 1/d^2 weights
    frame = acq.view(int(np.flatnonzero((index == middle).all(1))[0]))
    along_axis = torch.from_numpy(np.outer(np.linspace(-0.15, 0.15, 301), -scan.axis_z))
    op = SensingOperator(frame)
    along = (op.adjoint(op.forward(torch.zeros(1, 3, dtype=torch.float64), torch.ones(1, dtype=torch.complex128)),
                        along_axis) / op.column_norms_sq(along_axis).sqrt()).numpy()
    assert _half_power_width(along, 0.001) == pytest.approx(0.886 * SPEED_OF_LIGHT / (2 * acq.bandwidth_hz), rel=0.05)


def test_the_fit_renders_a_scan_as_one_view_that_matches_its_data(small_sar):
    """The renderer's view is the scan: its frames' predicted data summed coherently into one
    image (the samples' lobes seen from the scan's centre), which for the true ball matches
    the data's image of the whole scan; thinned, 1/n^2 of each scan's frames, alike."""
    data = simulate(load_scene("sphere"), dataclasses.replace(small_sar, snr_db=None))
    grid = Grid((-0.04,) * 3, (0.04,) * 3, (24,) * 3)
    ball = _Ball()
    for step, frames in ((1, 12), (2, 3)):
        renderer = CoherentRenderer(data, grid, element_step=step)
        assert renderer.num_views == 2 and [len(f) for f in renderer.frames] == [frames, frames]
        renderer.refresh(ball.sdf, torch.Generator().manual_seed(0))
        predicted = renderer(ball, torch.arange(2), torch.arange(len(renderer.voxels)))
        observed = renderer.observed
        correlation = (predicted.conj() * observed).sum(1).abs() / (predicted.norm(dim=1) * observed.norm(dim=1))
        assert correlation.min() > 0.999


def test_a_wide_scan_is_rendered_as_bright_as_its_data_each_frame_from_its_own_phase_centre(tmp_path):
    """A scan 8 cm wide at 0.2 m sees the metal ball from frames 11 degrees apart, each with
    its own glint: scattered towards each frame's own phase centres (as the simulator does)
    the true ball's prediction has the data's amplitude; towards the scan's centre alone
    it was some 15 % dimmer (``benchmarks/scan_model.py``: 12-19 % on sar-77g)."""
    path = tmp_path / "wide-sar.toml"
    path.write_text(_SMALL_SAR.replace("scan_steps = [4, 3]\nscan_step_m = 0.004", "scan_steps = [9, 9]\nscan_step_m = 0.01"))
    data = simulate(load_scene("sphere"), load_radar(path))
    renderer = CoherentRenderer(data, Grid((-0.04,) * 3, (0.04,) * 3, (24,) * 3))
    ball = _Ball()
    renderer.refresh(ball.sdf, torch.Generator().manual_seed(0))
    predicted = renderer(ball, torch.arange(2), torch.arange(len(renderer.voxels))) * (SIMULATED_GAIN
                                                                                      / renderer.observed_peak)
    observed = renderer.observed
    gain = (predicted.conj() * observed).sum(1).abs() / predicted.norm(dim=1) ** 2  # observed / predicted, per view
    assert gain.numpy() == pytest.approx([1.0, 1.0], abs=0.02)


def test_clean_and_the_observed_surface_take_a_scan_as_one_view(small_sar):
    data = simulate(load_scene("sphere"), dataclasses.replace(small_sar, snr_db=None))
    grid = Grid((-0.04,) * 3, (0.04,) * 3, (16,) * 3)
    clean = clean_image(data, grid, method="exact", max_components=5)
    assert clean.per_view_power.shape == (2, *grid.shape) and all(len(i) == 5 for i in clean.component_index)
    # each scan's CLEAN starts at the peak of that scan's coherent image, and leaves less
    dirty = matched_filter(data, grid, method="exact").per_view.abs()
    for view, index in enumerate(clean.component_index):
        assert int(index[0]) == int(dirty[view].argmax())
        assert float(clean.residual[view].abs().max()) < float(dirty[view].max())
    centres = data.acquisition.view_centres()[0]
    # the ball's points facing either scan are observed, those facing neither are not
    directions = torch.nn.functional.normalize(torch.randn(500, 3, dtype=torch.float64), dim=1)
    seen = observed_mask(0.02 * directions, directions, data.acquisition, load_scene("sphere").sdf)
    facing = torch.stack([directions @ torch.nn.functional.normalize(c, dim=0) for c in centres]).max(0).values
    assert bool(seen[facing > 0.99].all()) and not bool(seen[facing < 0].any())


def test_clean_of_a_scan_on_its_lattice_finds_what_the_exact_operator_does(small_sar, monkeypatch):
    """On a grid on the scans' lattice, CLEAN images every component of a scan by FFT, its
    kernels' spectra kept (``ScanLattice``): the same components, amplitudes and residual as
    the exact operator's point responses and back-projections, its slow reference."""
    data = simulate(load_scene("sphere"), dataclasses.replace(small_sar, snr_db=None))
    grid = lattice_grid(data.acquisition, (-0.03,) * 3, (0.03,) * 3)
    assert all(clean_module._scan_lattice(data, view, grid, None) is not None for view in range(2))
    options = {"method": "exact", "max_components": 12, "major_every": 5}
    lattice = clean_image(data, grid, **options)
    with monkeypatch.context() as short:  # spectra beyond the memory: refused, not hours on the general path
        short.setattr("rfsdf.limits.available_memory_bytes", lambda: 1e6)
        with pytest.raises(RfsdfError, match="the kernels' spectra of a 3 x 4 scan on 17 depths need"):
            clean_image(data, grid, **options)
    monkeypatch.setattr(clean_module, "_scan_lattice", lambda *args: None)
    exact = clean_image(data, grid, **options)
    for view in range(2):
        assert torch.equal(lattice.component_index[view], exact.component_index[view])
        assert torch.allclose(lattice.component_amplitude[view], exact.component_amplitude[view], rtol=1e-4)
        scale = float(exact.residual[view].abs().max())
        assert float((lattice.residual[view] - exact.residual[view]).abs().max()) < 1e-4 * scale


def test_the_renderer_keeps_every_nth_frequency_where_the_range_stays_unambiguous(small_sar):
    """Every 2nd of 8 frequencies 47 MHz apart: the same band, 3.2 m -> 1.6 m of unambiguous
    path, still longer than the grid's; the prediction at the truth still matches the data.
    On the default radar (16 frequencies 250 MHz apart) every 2nd would fold the scene's
    paths (0.6 m unambiguous against about 1 m of paths): refused, saying why."""
    data = simulate(load_scene("sphere"), dataclasses.replace(small_sar, snr_db=None))
    grid = Grid((-0.04,) * 3, (0.04,) * 3, (24,) * 3)
    renderer = CoherentRenderer(data, grid, frequency_step=2)
    assert renderer.po_spectrum.shape == (4,)
    ball = _Ball()
    renderer.refresh(ball.sdf, torch.Generator().manual_seed(0))
    predicted = renderer(ball, torch.arange(2), torch.arange(len(renderer.voxels)))
    correlation = (predicted.conj() * renderer.observed).sum(1).abs() / (predicted.norm(dim=1) * renderer.observed.norm(dim=1))
    assert correlation.min() > 0.999
    near = load_radar("near-77g")
    measurements = Measurements(near.acquisition(), torch.zeros(near.acquisition().shape, dtype=torch.complex64))
    with pytest.raises(ValueError, match="frequency_step 2: the unambiguous path length 0.6 m is shorter than"):
        CoherentRenderer(measurements, Grid((-0.15,) * 3, (0.15,) * 3, (8,) * 3), frequency_step=2)


def _mirror_scan(depth_m: float, positions: int = 15, step_m: float = 0.003) -> Measurements:
    """A board (Tx, one Rx 5 mm along x) over a raster in z = 0 facing a metal plane at
    z = ``depth_m``: each frame's return is its Rx mirrored in the plane seen from its Tx
    (image theory, no quadrature), 32 frequencies over 3 GHz, one scan."""
    lateral = (np.arange(positions) - (positions - 1) / 2) * step_m
    grid_xy = np.array([[x, y, 0.0] for x in lateral for y in lateral])
    tx = torch.tensor(grid_xy)[:, None]
    rx = torch.tensor(grid_xy + [0.005, 0.0, 0.0])[:, None]
    frequencies = torch.linspace(77.5e9, 80.5e9, 32, dtype=torch.float64)
    acq = Acquisition(tx, rx, frequencies, torch.tensor([[0.0, 0.0, 1.0]] * len(grid_xy), dtype=torch.float64),
                      scans=torch.zeros(len(grid_xy), dtype=torch.int64))
    mirrored = rx.clone()
    mirrored[..., 2] = 2 * depth_m - mirrored[..., 2]
    path = (tx - mirrored).norm(dim=-1)[..., None]  # (F, 1, 1)
    data = torch.exp(-2j * np.pi * frequencies * path / SPEED_OF_LIGHT) / path**2
    return Measurements(acq, data[:, :, None, :].to(torch.complex64))


def test_a_scan_places_a_face_it_sees_specularly_on_the_sub_aperture_before_it():
    """A plane facing a scan returns to every frame from the frame's own foot on it: no
    point, a wave focused far behind it. The whole scan's correlation along the normal peaks
    millimetres behind the plane; the range peaks, each line on the frames within
    sqrt(lambda D / 16) of it (and by the exact adjoint), within 0.2 mm of it, and search
    along the raster's normal."""
    from rfsdf.radar.imaging import view_correlation
    from rfsdf.radar.range_peaks import range_peaks

    depth = 0.1503  # between the voxel centres
    data = _mirror_scan(depth)
    along = np.arange(0.13, 0.18, 0.0005)
    line = torch.tensor([[0.0, 0.0, z] for z in along])
    whole = view_correlation(data, 0, line, method="exact").numpy()
    assert along[whole.argmax()] - depth > 0.005
    grid = Grid((-0.012, -0.012, 0.12), (0.012, 0.012, 0.18), (6, 6, 15))
    per_view = (matched_filter(data, grid, method="exact").per_view.abs() ** 2).numpy()
    peaks = range_peaks(data, per_view, grid, threshold=0.3, local_threshold=0.5, window_m=0.03)
    assert len(peaks.points) >= 20
    assert np.abs(peaks.points[:, 2] - depth).max() < 2e-4
    assert np.allclose(peaks.towards, [0.0, 0.0, -1.0])


def test_the_demo_images_a_scanned_radar_on_its_lattice_and_warm_starts_on_its_matched_filter(small_sar, tmp_path):
    """A radar whose views are scans gets the scanned demo's settings (``SCANNED``, no quick
    run); a demo of one images each scan by FFT on the raster's lattice, warm-starts on that
    matched filter, scores the default demo's baselines (CLEAN's on the lattice too) and the
    matched filter's detection, and its report reads them."""
    from click.testing import CliRunner

    from rfsdf.cli import main
    from rfsdf.config import merge_tables
    from rfsdf.demo import QUICK, SCANNED, demo_grid, demo_settings, run_demo
    from rfsdf.report import write_report

    path = tmp_path / "small-sar.toml"
    assert demo_settings("sar-77g") == SCANNED and demo_settings(str(path)).radar == str(path)
    assert demo_settings("near-77g", quick=True) == QUICK
    refused = CliRunner().invoke(main, ["demo", "--quick", "--radar", str(path), "--out", str(tmp_path / "q")])
    assert refused.exit_code == 2 and refused.output.count("\n") == 1 and "has no --quick demo" in refused.output
    acquisition = small_sar.acquisition()
    assert demo_grid((-0.03,) * 3, (0.03,) * 3, acquisition, 0.01) == lattice_grid(acquisition, (-0.03,) * 3, (0.03,) * 3)
    settings = dataclasses.replace(QUICK, scene="sphere", radar=str(path), voxel_m=0.004,
                                   recon=merge_tables(QUICK.recon, {"init": SCANNED.recon["init"],
                                                                    "render": {"element_step": 2, "frequency_step": 2}}))
    result = run_demo(tmp_path / "demo", settings, log=lambda _: None, progress=False)
    assert set(result.methods) == {"neural", "neural_warm_start", "mf_threshold", "clean_threshold", "clean_detection",
                                   "mf_detection"}
    assert result.voxel_mm == pytest.approx(4.0) and "clean_s" in result.timings_s
    assert all((tmp_path / "demo" / name).exists() for name in ("clean-mip.png", "clean-detection.ply", "mf-detection.ply"))
    assert all(np.isfinite(m.metrics.full.chamfer_l1_mm) for m in result.methods.values())
    report = write_report(tmp_path / "demo").read_text()
    assert "MF detection" in report and "CLEAN detection" in report
