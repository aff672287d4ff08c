"""The coherent reconstruction: surface sampling, rendering against the simulator, gradients,
a tiny fit, checkpoints and registries."""

import dataclasses
import math
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from rfsdf.errors import RfsdfError
from rfsdf.field import RadarField
from rfsdf.geometry import Grid, gradient
from rfsdf.materials import mixture_fresnel
from rfsdf.metrics import surface_offset_mm
from rfsdf.parallel import use_threads
from rfsdf.radar import matched_filter, simulate
from rfsdf.radar.scattering import lit_mask
from rfsdf.radar.simulate import SAMPLES_PER_WAVELENGTH
from rfsdf.recon import (
    CoherentRenderer, Problem, ReconConfig, Trainer, amplitude_loss, load_field, project_to_surface,
    surface_candidates,
)
from rfsdf.recon.losses import DATA_LOSSES, complex_loss, split_spectrum_loss
from rfsdf.recon.checkpoint import CHECKPOINT_NAME
from rfsdf.recon.config import CalibrationConfig
from rfsdf.recon.warm_start import detection_target, excluded_voxels, fit_to_image
from rfsdf.scene import Scene, load_scene
from rfsdf.scene_spec import SceneSpec
from rfsdf.studies.ball_fit import ball_data

RADIUS = 0.02  # the `sphere` preset: a 2 cm metal ball at the origin


@pytest.fixture(scope="module")
def sphere_data(tiny_radar):
    """The `sphere` scene and its data, the ball sampled at lambda/6 (``ball_data``)."""
    return load_scene("sphere"), ball_data(tiny_radar, seed=0)


class _Ball(torch.nn.Module):
    """A field with one radius [m] and one reflectivity: f = |p| - r, Gamma = g."""

    def __init__(self, radius, gamma=1.0, dtype=torch.float32):
        super().__init__()
        self.radius = torch.nn.Parameter(torch.tensor(radius, dtype=dtype))
        self.gamma = torch.nn.Parameter(torch.tensor(gamma, dtype=dtype))

    def sdf(self, points):
        return points.norm(dim=1) - self.radius

    def reflectivity(self, points):
        return self.gamma.expand(len(points))


def _grid(voxels=16):
    return Grid((-0.06,) * 3, (0.06,) * 3, (voxels,) * 3)


def test_surface_samples_of_a_sphere_lie_on_it_with_the_right_area():
    radius, grid = 0.03, _grid(20)
    sdf = lambda p: p.norm(dim=1) - radius  # noqa: E731
    points = grid.points()
    for seed in range(3):
        cand = surface_candidates(sdf, points, sdf(points), float(grid.voxel_m[0]), 0.0013,
                                  torch.Generator().manual_seed(seed))
        on, normals, area = project_to_surface(sdf, cand)
        assert (on.norm(dim=1) - radius).abs().max() < 1e-6  # << lambda / 10 = 0.38 mm
        for evaluated, stored in zip((on, normals, area), cand.projected()):  # the frozen steps' shortcut
            torch.testing.assert_close(stored, evaluated)
        assert float(cand.area_m2.sum()) == pytest.approx(4 * math.pi * radius**2, rel=0.02)
        assert cand.spacing_m <= 0.0013
        torch.testing.assert_close(cand.normals, torch.nn.functional.normalize(cand.anchors, dim=1))
        torch.testing.assert_close(normals, cand.normals)  # f unchanged since the refresh
        torch.testing.assert_close(cand.curvature, 2 / cand.anchors.norm(dim=1))
        # the areas follow the surface: d(4 pi r^2)/dr = 8 pi r at the samples of the refresh
        grown = torch.tensor(radius, requires_grad=True)
        _, _, area = project_to_surface(lambda p, r=grown: p.norm(dim=1) - r, cand)
        area.sum().backward()
        assert float(grown.grad) == pytest.approx(8 * math.pi * radius, rel=0.02)


def test_the_sample_normals_turn_with_the_surface():
    """The normals project_to_surface returns are grad f / |grad f| at the anchors, differentiable
    in f's parameters: for a sphere centred at c, d(n . w)/dc = -(I - n n^T) w / |p0 - c|."""
    grid = _grid(20)
    centre = torch.tensor([0.004, -0.003, 0.002], dtype=torch.float64, requires_grad=True)
    sdf = lambda p: (p - centre.to(p)).norm(dim=1) - 0.03  # noqa: E731
    points = grid.points().double()
    with torch.no_grad():
        cand = surface_candidates(sdf, points, sdf(points), float(grid.voxel_m[0]), 0.002,
                                  torch.Generator().manual_seed(0))
    _, normals, _ = project_to_surface(sdf, cand)
    offset = cand.anchors - centre.detach()
    expected_normals = offset / offset.norm(dim=1, keepdim=True)
    torch.testing.assert_close(normals.detach(), expected_normals)
    weights = torch.randn(normals.shape, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
    (normals * weights).sum().backward()
    n, w = expected_normals, weights
    tangential = w - (w * n).sum(1, keepdim=True) * n
    torch.testing.assert_close(centre.grad, -(tangential / offset.norm(dim=1, keepdim=True)).sum(0))
    with torch.no_grad():  # no graph asked for: the same normals, detached
        _, detached, _ = project_to_surface(sdf, cand)
    assert not detached.requires_grad
    torch.testing.assert_close(detached, expected_normals)


def test_a_spheres_brightness_grows_with_its_radius_in_the_gradient_too(sphere_data):
    """The derivative of the predicted image energy in the radius against finite differences
    that draw fresh samples at each radius (4 draws): a sphere's RCS grows as r^2, so d log E /
    dr is about 2 / r = 100 / m. With frozen areas the gradient said -86 / m (samples crowd
    into the Fresnel zone as the sphere shrinks, each keeping its area): the fit pulled bright
    balls inward (docs/results/quality-history.md, "The area term")."""
    _, data = sphere_data
    renderer = CoherentRenderer(data, _grid(), spacing_m=data.acquisition.wavelength_m / 6)
    views, voxels = torch.arange(renderer.num_views), torch.arange(renderer.voxels.shape[0])

    def log_energy(radius, seed):
        ball = _Ball(radius)
        renderer.refresh(ball.sdf, torch.Generator().manual_seed(seed))
        energy = torch.log((renderer(ball, views, voxels).abs() ** 2).sum())
        energy.backward()
        return float(energy.detach()), float(ball.radius.grad)

    step, seeds = 1e-3, range(4)
    finite = np.mean([(log_energy(RADIUS + step, s)[0] - log_energy(RADIUS - step, s)[0]) / (2 * step) for s in seeds])
    analytic = np.mean([log_energy(RADIUS, s)[1] for s in seeds])
    assert 80 < finite < 150 and analytic == pytest.approx(finite, rel=0.15)


def _two_balls(wood: str = "wood") -> Scene:
    """A 3 cm metal ball and a 3 cm ball of ``wood`` (or another catalogue material), 5 cm apart."""
    ball = lambda name, material, x: {"name": name, "material": material, "shape": {  # noqa: E731
        "type": "sphere", "radius_m": 0.015, "transform": {"translate_m": [x, 0.0, 0.0]}}}
    return Scene(SceneSpec.model_validate({"name": "two-balls", "bounds": {"lower_m": [-0.06] * 3, "upper_m": [0.06] * 3},
                                           "objects": [ball("metal_ball", "metal", -0.025), ball("wood_ball", wood, 0.025)]}))


@pytest.mark.parametrize("surface", ["facets", "points"])
def test_renderer_on_the_true_samples_reproduces_the_simulator(tiny_radar, surface):
    """The simulator's own samples (its facets, or its stratified points) through the
    renderer's material path, each sample certain of its object's material: the simulator's
    data to round-off."""
    scene = _two_balls()
    radar = dataclasses.replace(tiny_radar, snr_db=None)
    clean = simulate(scene, radar, seed=3, surface=surface)
    renderer = CoherentRenderer(clean, _grid(8))
    acq = clean.acquisition
    spacing = acq.wavelength_m / SAMPLES_PER_WAVELENGTH
    samples = (scene.zero_set_facets(spacing, seed=3) if surface == "facets" else
               scene.sample_surface(spacing, seed=3, max_samples=150_000, stratified=True))  # simulate's
    classes = renderer.class_permittivities(("metal", "wood"))
    certain = torch.nn.functional.one_hot(samples.object_index, 2).double()  # object i is class i
    for view in range(acq.shape[0]):
        lit = lit_mask(samples.points, samples.normals, renderer.tx_centres[view], renderer.rx_centres[view],
                       occluder=scene.sdf)
        p, n, a = samples.points[lit], samples.normals[lit], samples.area_m2[lit]
        corners = None if samples.corners_m is None else samples.corners_m[lit]
        y = renderer.predict_data(view, p.double(), n.double(), a.double(),
                                  lambda cos, lit=lit: mixture_fresnel(cos, certain[lit], classes), corners)
        reference = clean.data[view]
        assert float((y[0] - reference).norm() / reference.norm()) < 1e-5


def test_the_renderers_facets_of_the_true_surface_give_the_data(sphere_data):
    """One physics, converged: the renderer's own facets of the true ball (marching cubes on
    its image grid's crossing voxels, another mesh than the simulator's) predict the
    simulator's images to a correlation of 0.999 in every view; its points (lambda/3) do not."""
    _, data = sphere_data
    truth = _Ball(RADIUS)
    correlation = {}
    for surface in ("facets", "points"):
        renderer = CoherentRenderer(data, _grid(), surface=surface)
        with torch.no_grad():
            renderer.refresh(truth.sdf, torch.Generator().manual_seed(0))
            predicted = renderer(truth, torch.arange(renderer.num_views), torch.arange(renderer.voxels.shape[0]))
        observed = renderer.observed
        correlation[surface] = ((predicted.conj() * observed).sum(1).abs()
                                / (predicted.norm(dim=1) * observed.norm(dim=1))).min()
    assert correlation["facets"] > 0.999 > correlation["points"], correlation


def test_the_material_path_of_a_metal_surface_is_the_free_path_at_reflectivity_one(sphere_data):
    """A field certain that its surface is metal (Gamma = -1 at every angle) renders the images
    of a free reflectivity of 1 with the sign flipped: the two paths share everything else."""
    _, data = sphere_data
    renderer = CoherentRenderer(data, _grid(10))
    ball = _Ball(RADIUS + 0.001)
    renderer.refresh(ball.sdf, torch.Generator().manual_seed(0))
    views, voxels = torch.arange(renderer.num_views), torch.arange(renderer.voxels.shape[0])
    free = renderer(ball, views, voxels)
    ball.materials, ball.material_head = ("metal", "glass"), True
    metal = torch.tensor([[1.0, 0.0]]).expand(len(renderer.candidates), 2)
    torch.testing.assert_close(renderer(ball, views, voxels, probabilities=metal), -free)


def test_renderer_and_loss_pass_gradcheck_in_float64(sphere_data):
    _, data = sphere_data
    renderer = CoherentRenderer(data, _grid(6), spacing_m=0.006, dtype=torch.float64)
    start = _Ball(RADIUS + 0.002, dtype=torch.float64)
    renderer.refresh(start.sdf, torch.Generator().manual_seed(0))
    views, voxels = torch.tensor([0, 4]), torch.arange(0, renderer.voxels.shape[0], 3)
    observed = renderer.observed.abs()[views][:, voxels]

    def loss(radius, gamma):
        ball = _Ball(0.0, dtype=torch.float64)
        ball.sdf = lambda p: p.norm(dim=1) - radius
        ball.reflectivity = lambda p: gamma.expand(len(p))
        return amplitude_loss(renderer(ball, views, voxels), observed)

    args = (torch.tensor(RADIUS + 0.002, dtype=torch.float64, requires_grad=True),
            torch.tensor(0.7, dtype=torch.float64, requires_grad=True))
    assert torch.autograd.gradcheck(loss, args, eps=1e-7, atol=1e-6, rtol=1e-3)


def test_gradient_in_the_radius_matches_finite_differences(sphere_data):
    _, data = sphere_data
    renderer = CoherentRenderer(data, _grid())
    ball = _Ball(RADIUS + 0.003)
    renderer.refresh(ball.sdf, torch.Generator().manual_seed(1))
    views, voxels = torch.arange(6), torch.arange(renderer.voxels.shape[0])
    observed = renderer.observed.abs()

    def loss():
        return amplitude_loss(renderer(ball, views, voxels), observed)

    loss().backward()
    step = 2e-6
    with torch.no_grad():
        ball.radius += step
        up = float(loss())
        ball.radius -= 2 * step
        down = float(loss())
    assert ball.radius.grad.item() == pytest.approx((up - down) / (2 * step), rel=0.05)
    assert ball.radius.grad.item() > 0  # 3 mm too large: the loss falls as the ball shrinks


def _config(**train) -> ReconConfig:
    return ReconConfig.model_validate({
        "field": {"width": 32, "depth": 4, "levels": 2, "init_radius_m": RADIUS + 0.003, "materials": []},
        # the warm start alone where a test asks for one (the primitives: tests/test_object_primitives.py)
        "init": {"method": "sphere", "primitives": False},
        "render": {"element_step": 1, "refresh_every": 4},
        "sampling": {"views_per_step": 6, "data_batch": 1024, "eikonal_batch": 512},
        "loss": {"eikonal_weight": 0.1},
        "train": {"steps": 12, "checkpoint_every": 5, "lr": 1e-3, "lr_end": 1e-4, **train},
    })


def _mean_radius(field, renderer) -> float:
    with torch.no_grad():
        renderer.refresh(field.sdf, torch.Generator().manual_seed(5))
        points, _, area, _ = renderer.surface_geometry(field)
        return float((points.norm(dim=1) * area).sum() / area.sum())


def _tiny_trainer(data, seed: int, folder) -> Trainer:
    return Trainer(Problem(data, _grid()), _config(steps=40, lr=5e-4, lr_end=5e-5, geometry_delay=0.0, seed=seed),
                   Path(folder) / "run")


def _dilated_start(data, seed: int) -> dict:
    """The tiny fit's field (``seed``) regressed onto the ball 3 mm too large: its state."""
    with tempfile.TemporaryDirectory() as folder:
        field = _tiny_trainer(data, seed, folder).field
        dilated = lambda p: p.norm(dim=1) - (RADIUS + 0.003)  # noqa: E731
        fit_to_image(field, (-0.06,) * 3, (0.06,) * 3, dilated, None, steps=400, lr=3e-3, batch=2048,
                     eikonal_weight=0.1, generator=torch.Generator().manual_seed(seed))
        return {k: v.clone() for k, v in field.state_dict().items()}


def _tiny_fit(data, seed: int, start: dict | None = None) -> tuple[float, float, list]:
    """The fit of a field regressed onto the ball 3 mm too large (``start``, or regressed
    here): its mean radius [m] before and after 40 steps, and its log (``seed``: the field's
    initialisation, the fit's and the regression's draws). ``benchmarks/tiny_fit_margin.py``
    measures its margins."""
    start = _dilated_start(data, seed) if start is None else start
    with tempfile.TemporaryDirectory() as folder:
        trainer = _tiny_trainer(data, seed, folder)
        trainer.field.load_state_dict(start)
        before = _mean_radius(trainer.field, trainer.renderer)
        fit = trainer.fit()
        assert len(fit.log) == 40 and all(math.isfinite(r.data) for r in fit.log)
        return before, _mean_radius(fit.field, trainer.renderer), fit.log


def test_a_tiny_fit_recovers_a_dilated_sphere(sphere_data):
    """From a 3 mm dilation towards the truth, judged over five seeds: every fit moves inward,
    and the median ends within lambda/2, having moved more than lambda/4; at the suite's thread
    count (the sums' last bits, and with them the fit's path, follow it and the CPU; a run at
    ``RFSDF_TEST_THREADS=1`` judges one thread). Not each fit within lambda/2: with 6 views of
    a 4 cm array the amplitude loss of the ball's radius ripples with period about a millimetre (the glint
    and the limb interfere; local minima near 20, 21 and 22 mm of about the same depth), and
    a fit stops in one of them. It used to reach lambda/4 helped by a bias: with frozen
    sample areas the gradient said a sphere brightens as it shrinks, and pulled every convex
    surface inward (docs/results/quality-history.md, "The area term").

    Margins (``benchmarks/tiny_fit_margin.py`` -> results/tiny_fit_margin.json: seeds 0-11
    at 1 thread, 0-5 at 2 and 4, data simulated at that count): every fit moved inward, by
    0.64 mm at least (seed 1, which stops in the 22 mm minimum, 2.32 mm off, at every thread
    count: the one fit in twelve beyond lambda/2 = 1.90 mm); seeds 0-4 end 0.11, 2.32, 1.71,
    0.28, 0.56 mm off (median 0.56) at 1, 2 and 4 threads alike, having moved 2.75 mm
    (median). Coarse-to-fine cells (``cell_voxels_start`` 3 or 4) do not lift the ripple
    minima (seed 6 stops at 22.5-23.1 mm). The data loss is not asserted: each step scores a
    fresh random batch of voxels against a fresh random surface sampling, and the mean of
    the last five steps was above that of the first five in 7 of the 24 fits."""
    _, data = sphere_data
    radii = np.array([_tiny_fit(data, seed)[:2] for seed in range(5)])  # [m]
    start, end = radii[:, 0], radii[:, 1]
    wavelength = data.acquisition.wavelength_m
    assert np.all(np.abs(start - (RADIUS + 0.003)) < 3e-4), start
    assert np.all(end < start), radii
    assert np.median(np.abs(end - RADIUS)) < wavelength / 2, radii
    assert np.median(start - end) > wavelength / 4, radii


@pytest.mark.parametrize("smoothing_m, steps, stays", [(None, 100, True), (0.006, 40, False)])
def test_started_on_the_true_ball_the_facet_fit_stays_on_it(sphere_data, tmp_path, smoothing_m, steps, stays):
    """The converged renderer's loss has its minimum at the truth, and its own gradient finds
    it: a field regressed onto the true ball, fitted for 100 steps at the default learning
    rate from the first step with its metal and the radar's gain known (only f free), ends
    within 0.05 mm of the seen surface on average and smoother than it started. Measured
    (mean / rms in mm; train seeds 0-3 at 4 threads, 0 and 2 at 1, 0 at 2): from 0.08-0.19
    off (either side) / 0.11-0.22 it overshoots inward, to -0.10 to -0.15 within 25 steps,
    and settles at -0.04 to 0.00 / 0.04-0.09 by step 75; stopped at 40 steps, still
    recovering, it ended at -0.02 to -0.12, and the count of threads decided the verdict.
    With the point sampler's 6 mm mean of the surface velocity the same fit roughens it, to
    0.46 mm rms in 40 steps (0.39-0.89 in 100): the mean keeps a facet's vertices from
    moving apart, so the tilt the data ask for cannot reach the surface, and what does reach
    it is the wrong shape."""
    from rfsdf.radar.coverage import observed_mask
    from rfsdf.radar.simulate import SIMULATED_GAIN
    from rfsdf.studies.basin import regressed_field

    scene, data = sphere_data
    metal = lambda p: torch.zeros(len(p), dtype=torch.int64, device=p.device)  # noqa: E731
    config = ReconConfig.model_validate({
        "field": {"width": 32, "depth": 4, "materials": ["metal", "glass"]},
        "init": {"method": "sphere"},
        "render": {"element_step": 1, "smoothing_m": smoothing_m},
        "sampling": {"data_batch": 1024},
        "train": {"steps": steps, "checkpoint_every": steps, "geometry_delay": 0.0,
                  "device": "cpu"}})
    problem = Problem(data, Grid.from_voxel(scene.lower_m, scene.upper_m, 0.0075), gain=SIMULATED_GAIN,
                      known_materials=metal)
    samples = scene.sample_surface(0.001, seed=1, max_samples=20_000)
    start = regressed_field(problem, config, scene.sdf, samples.points, steps=300)
    surface = samples.points[observed_mask(samples.points, samples.normals, data.acquisition, scene.sdf)].float()
    before = surface_offset_mm(start.sdf, surface)
    fit = Trainer(problem, config, tmp_path / "run", start=start.state_dict()).fit()
    after = surface_offset_mm(fit.field.sdf, surface)
    assert abs(before[0]) < 0.2 and before[1] < 0.3, before  # the start: the regression's own error
    held = abs(after[0]) < 0.05 and after[1] < before[1]
    assert held == stays, (before, after)


def test_warm_start_points_near_the_surface_fit_a_small_object():
    """A 12 mm ball in a 30 cm box gets a few of a uniform batch; a quarter of the batch
    drawn within a voxel of its surface fits it several times better in the same steps."""
    centre, radius = torch.tensor([0.07, 0.06, -0.04]), 0.012
    target = lambda p: (p - centre.to(p)).norm(dim=1) - radius  # noqa: E731
    grid = Grid((-0.15,) * 3, (0.15,) * 3, (50,) * 3)
    points = grid.points()
    near = points[target(points).abs() < 0.006]
    surface = centre + radius * torch.nn.functional.normalize(
        torch.randn(2000, 3, generator=torch.Generator().manual_seed(1)), dim=1)
    error = {}
    for share in (0.0, 0.25):
        torch.manual_seed(0)
        field = RadarField((-0.15,) * 3, (0.15,) * 3, levels=6, depth=4, width=64)
        fit_to_image(field, grid.lower_m, grid.upper_m, target, None, steps=150, lr=1e-3, batch=2048,
                     eikonal_weight=0.01, generator=torch.Generator().manual_seed(0), near_m=near,
                     near_share=share, near_jitter_m=0.006)
        with torch.no_grad():
            error[share] = float(field.sdf(surface).abs().mean())
    assert error[0.25] < 0.5 * error[0.0] and error[0.25] < 0.0025, error


def test_the_warm_start_turns_only_the_faces_the_views_see_towards_them():
    """A ball regressed onto its own SDF while the 'views' say every face looks up (+z): with
    the facing term the upper half flattens towards +z, the lower half (facing away, cosine
    < 0) keeps its normals, and without the term neither moves."""
    target = lambda p: p.norm(dim=1) - 0.05  # noqa: E731
    up = lambda p: torch.tensor([0.0, 0.0, 1.0]).expand(len(p), 3)  # noqa: E731
    surface = 0.05 * torch.nn.functional.normalize(torch.randn(4000, 3, generator=torch.Generator().manual_seed(1)),
                                                   dim=1)
    upper, lower = surface[:, 2] > 0.02, surface[:, 2] < -0.02
    cosine = {}
    for weight in (0.0, 0.1):
        torch.manual_seed(0)
        field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=4, depth=4, width=64)
        fit_to_image(field, (-0.1,) * 3, (0.1,) * 3, target, None, steps=150, lr=1e-3, batch=2048,
                     eikonal_weight=0.01, generator=torch.Generator().manual_seed(0), near_m=surface,
                     near_share=0.25, near_jitter_m=0.005, target_normal=up, normal_weight=weight)
        normals = torch.nn.functional.normalize(gradient(field.sdf, surface), dim=1)
        radial = torch.nn.functional.normalize(surface, dim=1)
        cosine[weight] = {"up": float(normals[upper, 2].mean()), "radial_below": float(
            (normals[lower] * radial[lower]).sum(1).mean()), "radial_above": float(
            (normals[upper] * radial[upper]).sum(1).mean())}
    assert cosine[0.1]["up"] > cosine[0.0]["up"] + 0.1, cosine
    assert cosine[0.0]["radial_above"] > 0.95 and cosine[0.0]["radial_below"] > 0.95, cosine
    assert cosine[0.1]["radial_below"] > 0.95, cosine


def test_the_warm_start_passes_through_the_range_peaks_where_the_target_is_half_a_voxel_off():
    """A ball whose voxel target stands 3 mm outside it (a boundary drawn half a voxel beyond
    the detection): regressed alone, f's zero set follows the target; with points on the true
    sphere as range peaks (``surface_m``, weighted by ``surface_weight``) it passes through them."""
    target = lambda p: p.norm(dim=1) - 0.053  # noqa: E731
    sphere = 0.05 * torch.nn.functional.normalize(torch.randn(3000, 3, generator=torch.Generator().manual_seed(1)),
                                                  dim=1)
    offset = {}
    for weight in (0.0, 1.0):
        torch.manual_seed(0)
        field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=4, depth=4, width=64)
        fit_to_image(field, (-0.1,) * 3, (0.1,) * 3, target, None, steps=150, lr=1e-3, batch=2048,
                     eikonal_weight=0.01, generator=torch.Generator().manual_seed(0), near_m=sphere,
                     near_share=0.25, near_jitter_m=0.006, surface_m=sphere[:1500],
                     surface_weights=torch.ones(1500), surface_weight=weight)
        with torch.no_grad():
            offset[weight] = float(field.sdf(sphere[1500:]).mean())  # points the term never saw
    assert offset[0.0] == pytest.approx(-0.003, abs=0.0007), offset
    assert abs(offset[1.0]) < 0.001, offset


def test_the_warm_start_turns_the_surface_at_the_range_peaks_towards_their_views():
    """A ball regressed onto its own SDF, with range peaks on a flat top (a disc 4 cm across,
    4 mm below the ball's pole) whose views look straight down on them (normals +z): both
    pull the zero set through the peaks, and only with ``surface_normal_weight`` do its normals
    there turn up as the views say (a specular return: the surface faces its view; their tilt
    at least ten times smaller than the noisy positions leave, whatever the thread count); the
    lower half, which no peak touches, keeps its own."""
    target = lambda p: p.norm(dim=1) - 0.05  # noqa: E731
    draw = torch.Generator().manual_seed(1)
    sphere = 0.05 * torch.nn.functional.normalize(torch.randn(3000, 3, generator=draw), dim=1)
    angle, radius = 2 * torch.pi * torch.rand(500, generator=draw), 0.02 * torch.rand(500, generator=draw).sqrt()
    disc = torch.stack([radius * torch.cos(angle), radius * torch.sin(angle), torch.full_like(angle, 0.046)], 1)
    cap = disc + torch.tensor([0.0, 0.0, 0.003]) * (torch.rand(500, 1, generator=draw) - 0.5)  # peaks +-1.5 mm off
    lower = sphere[sphere[:, 2] < -0.02]
    up = torch.tensor([0.0, 0.0, 1.0]).expand(len(cap), 3)
    result = {}
    for weight in (0.0, 1.0):
        torch.manual_seed(0)
        field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=4, depth=4, width=64)
        fit_to_image(field, (-0.1,) * 3, (0.1,) * 3, target, None, steps=150, lr=1e-3, batch=2048,
                     eikonal_weight=0.01, generator=torch.Generator().manual_seed(0), near_m=sphere,
                     near_share=0.25, near_jitter_m=0.006, surface_m=cap, surface_weights=torch.ones(len(cap)),
                     surface_weight=1.0, surface_normals=up, surface_normal_weight=weight)
        normal = lambda points: torch.nn.functional.normalize(gradient(field.sdf, points), dim=1)  # noqa: E731
        with torch.no_grad():
            offset = float(field.sdf(disc).abs().mean())
        result[weight] = {"up": float(normal(disc)[:, 2].mean()), "offset_m": offset,
                          "radial_below": float((normal(lower) * torch.nn.functional.normalize(lower, dim=1)).sum(1).mean())}
    tilt = {weight: 1 - r["up"] for weight, r in result.items()}  # 1 - mean cos to +z (noisy peaks tilt it)
    assert tilt[1.0] < 0.001 and tilt[1.0] < 0.1 * tilt[0.0], result
    assert max(r["offset_m"] for r in result.values()) < 0.001 and result[1.0]["radial_below"] > 0.95, result


def test_a_decayed_rate_ends_the_regression_where_the_target_is_not_where_the_last_batch_left_it():
    """A ball regressed from the same network by two draws of batches: at a constant rate the two
    ends differ by what the last batches did; with ``decay`` they lie several times nearer each
    other and nearer the target."""
    target = lambda p: p.norm(dim=1) - 0.05  # noqa: E731
    sphere = 0.05 * torch.nn.functional.normalize(torch.randn(2000, 3, generator=torch.Generator().manual_seed(1)),
                                                  dim=1)
    ends = {}
    for decay in (False, True):
        for draw in (0, 1):
            torch.manual_seed(0)
            field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=4, depth=4, width=64)
            fit_to_image(field, (-0.1,) * 3, (0.1,) * 3, target, None, steps=150, lr=3e-3, batch=1024,
                         eikonal_weight=0.01, generator=torch.Generator().manual_seed(draw), near_m=sphere,
                         near_share=0.25, near_jitter_m=0.006, decay=decay)
            with torch.no_grad():
                ends[decay, draw] = field.sdf(sphere)
    spread = {decay: float((ends[decay, 0] - ends[decay, 1]).abs().mean()) for decay in (False, True)}
    error = {decay: float(ends[decay, 0].abs().mean()) for decay in (False, True)}
    assert spread[True] < 0.3 * spread[False] and error[True] < error[False], (spread, error)


def test_a_range_peak_of_unknown_orientation_adds_nothing_to_the_warm_start():
    """``surface_normals`` zero at a point (a peak beside its glint's centre): the normal term
    leaves the fit exactly as with no normals at all."""
    target = lambda p: p.norm(dim=1) - 0.05  # noqa: E731
    sphere = 0.05 * torch.nn.functional.normalize(torch.randn(500, 3, generator=torch.Generator().manual_seed(1)),
                                                  dim=1)
    states = []
    for normals in (None, torch.zeros_like(sphere)):
        torch.manual_seed(0)
        field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=2, depth=3, width=32)
        fit_to_image(field, (-0.1,) * 3, (0.1,) * 3, target, None, steps=5, lr=1e-3, batch=256,
                     eikonal_weight=0.01, generator=torch.Generator().manual_seed(0), surface_m=sphere,
                     surface_weights=torch.ones(len(sphere)), surface_weight=1.0, surface_normals=normals,
                     surface_normal_weight=1.0)
        states.append(field.state_dict())
    assert all(torch.equal(states[0][key], states[1][key]) for key in states[0])


def test_the_detection_target_closes_two_glints_of_one_object_into_one_volume():
    """Two bright 3-voxel cubes one voxel apart: without closing two inside sets (the gap
    outside), closed over 2 voxels one (the gap inside); far voxels are outside by their distance."""
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (20,) * 3)  # 6 mm voxels
    power = np.zeros(grid.shape)
    power[6:9, 9:12, 9:12] = power[10:13, 9:12, 9:12] = 1.0
    open_set = detection_target(power, grid, threshold=0.5, local_threshold=0.5, window_m=0.018, closing_m=0.0)
    closed = detection_target(power, grid, threshold=0.5, local_threshold=0.5, window_m=0.018, closing_m=0.012)
    assert open_set[8, 10, 10] < 0 and open_set[10, 10, 10] < 0 and open_set[9, 10, 10] > 0
    assert closed[9, 10, 10] < 0
    assert closed[0, 10, 10] == pytest.approx(0.006 * 6 - 0.003)  # 6 voxels from the set, boundary half a voxel out


def test_the_warm_start_and_the_fit_each_use_their_own_eikonal_weight(sphere_data, tmp_path, monkeypatch):
    """The warm start regresses a rough thresholded image and wants a firmer Eikonal term than
    the fit (docs/results/demo-quality.md): ``[init]`` and ``[loss]`` each set one."""
    import rfsdf.recon.trainer as trainer_module

    _, data = sphere_data
    settings = _config(steps=2, geometry_delay=0.0).model_dump()
    settings["init"].update(method="mf", threshold=0.06, eikonal_weight=0.03)
    seen = {}
    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: seen.update(kw))
    trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / "run")
    trainer.warm_start()
    trainer.refresh_surface()
    terms = {key: float(value.detach()) for key, value in trainer.loss_terms().items()}
    assert seen["eikonal_weight"] == 0.03 and terms["eikonal"] > 0
    assert terms["loss"] == pytest.approx(terms["data"] + 0.1 * terms["eikonal"] + terms["peaks"], rel=1e-5)


def test_the_warm_start_excludes_range_sidelobes_and_optionally_the_front_halves(sphere_data, tmp_path, monkeypatch):
    """``[init] blank_range_sidelobes``, ``carve_front`` and ``glint_sidelobes`` (all on)
    reach the warm start as the voxels it leaves out, from the per-view images of its method
    (here the MF's); the glints' rule from the range peaks the others leave."""
    import rfsdf.recon.trainer as trainer_module
    from rfsdf.radar.detection import in_front_of_ridges, on_range_sidelobes
    from rfsdf.radar.glint_sidelobes import sidelobe_voxels
    from rfsdf.radar.range_peaks import range_peaks

    _, data = sphere_data
    seen = {}
    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: seen.update(kw))
    for carve, blank, glint in ((False, False, False), (True, False, False), (False, True, False), (False, False, True)):
        settings = _config(steps=2).model_dump()
        settings["init"].update(method="mf", carve_front=carve, blank_range_sidelobes=blank, glint_sidelobes=glint,
                                threshold=0.05)
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings),
                          tmp_path / f"{carve}{blank}{glint}")
        trainer.warm_start()
        grid = trainer.problem.grid
        per_view = (matched_filter(data, grid).per_view.abs() ** 2).numpy()  # every frame, as the warm start
        rule = {"threshold": 0.05, "local_threshold": 0.5, "window_m": 0.03}
        centres = data.acquisition.tx_m.mean(1).numpy()
        expected = np.zeros(grid.shape, bool)
        if carve:
            expected = in_front_of_ridges(per_view, centres, grid, **rule)
            assert expected.any()
        if blank:
            expected = on_range_sidelobes(per_view, centres, data.acquisition.frequencies_hz.numpy(), grid,
                                          level=ReconConfig().init.sidelobe_level, **rule)
        if glint:
            expected = sidelobe_voxels(data, range_peaks(data, per_view, grid, **rule), per_view, grid, **rule)
            assert expected.any()
        np.testing.assert_array_equal(seen["exclude"], expected)
    init = ReconConfig().init
    assert init.blank_range_sidelobes and init.carve_front and init.glint_sidelobes


def test_the_warm_start_gets_each_views_range_peaks_outside_the_excluded_voxels(sphere_data, tmp_path, monkeypatch):
    """``[init] peak_weight`` (on by default) hands the warm start the range peaks of the
    per-view images of its method (here the MF's), from the ridges it does not exclude, less
    those a view's glints explain (``glint_sidelobes``, which also excludes the detections they
    explain); 0 hands it none."""
    import rfsdf.recon.trainer as trainer_module
    from rfsdf.radar.glint_sidelobes import sidelobe_peaks
    from rfsdf.radar.range_peaks import range_peaks

    _, data = sphere_data
    seen = {}
    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: seen.update(kw))
    for weight in (0.0, 2.0):
        settings = _config(steps=2).model_dump()
        settings["init"].update(method="mf", threshold=0.05, peak_weight=weight)
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / f"{weight}")
        trainer.warm_start()
        assert seen["peak_weight"] == weight and seen["peak_normal_weight"] == trainer.config.init.peak_normal_weight
        if weight == 0:
            assert seen["peaks"] is None
    grid = trainer.problem.grid
    per_view = (matched_filter(data, grid).per_view.abs() ** 2).numpy()
    expected = range_peaks(data, per_view, grid, threshold=0.05, local_threshold=0.5, window_m=0.03,
                           keep=~excluded_voxels(trainer.config.init, per_view, data.acquisition, grid, 0.05))
    expected = expected.select(~sidelobe_peaks(data, expected))
    everything = range_peaks(data, per_view, grid, threshold=0.05, local_threshold=0.5, window_m=0.03)
    np.testing.assert_allclose(seen["peaks"].points, expected.points)
    assert set(seen["peaks"].view) == set(range(data.acquisition.num_views))
    assert seen["exclude"].any() and len(expected.points) < len(everything.points)
    assert (seen["exclude"] >= excluded_voxels(trainer.config.init, per_view, data.acquisition, grid, 0.05)).all()
    assert ReconConfig().init.peak_weight > 0



def test_the_warm_start_hands_its_field_and_peaks_to_the_primitives_when_asked(sphere_data, tmp_path, monkeypatch):
    """``[init] primitives`` (on by default) runs primitive_start on the warm start's field
    with its range peaks and the directions towards their views; with ``peak_cone_deg`` each
    peak's glint cap too, on the sphere of its range (its distance from its view's centre). The
    peaks of a bridged fit (rim returns) are no longer held: the fit's peaks are the others."""
    import rfsdf.recon.trainer as trainer_module

    _, data = sphere_data
    seen, fits = {}, []

    def primitive_start(field, points, towards, *args, caps=None, **kw):
        seen.update(points=points, towards=towards, caps=caps)
        fits[:] = [SimpleNamespace(explains=True, bridged=False, primitive="kept", fragment=None),
                   SimpleNamespace(explains=False, bridged=False, primitive="left", fragment=None),
                   SimpleNamespace(explains=True, bridged=True, primitive="bridge",
                                   fragment=SimpleNamespace(peaks=points[:3].double()))]
        return fits

    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: None)
    monkeypatch.setattr(trainer_module, "primitive_start", primitive_start)
    for on, cone in ((False, 0.0), (True, 0.0), (True, 0.5)):
        settings = _config(steps=2).model_dump()
        settings["init"].update(method="mf", threshold=0.05, primitives=on, peak_cone_deg=cone)
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / f"{on}{cone}")
        trainer.warm_start()
        assert (trainer.primitive_fits == fits) is on and (seen != {}) is on
        assert trainer.primitives == (["kept", "bridge"] if on else [])  # those that replaced their fragments
        assert (seen.get("caps") is not None) is (cone > 0)
    torch.testing.assert_close(seen["points"][3:], trainer.peaks[0])  # the bridge's three peaks not held
    torch.testing.assert_close(seen["towards"][3:], trainer.peaks[3])
    seen.update(points=seen["points"][3:], caps=seen["caps"][3:])
    centres = data.acquisition.view_centres()[0].to(trainer.peaks[0])[trainer.peaks[2]]
    ranges = (seen["points"] - centres).norm(dim=1)
    torch.testing.assert_close(trainer.peak_ranges(), ranges)
    assert seen["caps"].shape == (len(ranges), 19, 3)  # two rings about each peak
    torch.testing.assert_close((seen["caps"] - centres[:, None]).norm(dim=2), ranges[:, None].expand(-1, 19))
    torch.testing.assert_close(seen["caps"][:, 0], seen["points"])
    assert ReconConfig().init.primitives is True and ReconConfig().init.peak_cone_deg == 0.25

def _known(*objects) -> Scene:
    return Scene(SceneSpec.model_validate({"name": "known", "bounds": {"lower_m": [-0.1] * 3, "upper_m": [0.1] * 3},
                                           "objects": list(objects)}))


BOX = {"name": "box", "material": "wood", "shape": {"type": "difference", "children": [
    {"type": "box", "half_extents_m": [0.05, 0.05, 0.05], "center_m": [0, 0, 0]},
    {"type": "box", "half_extents_m": [0.047, 0.047, 0.047], "center_m": [0, 0, 0]}]}}


def test_seen_through_a_known_box_the_voxels_outside_its_cavity_and_at_its_walls_are_left_out():
    """``known_exclusion``: a closed 3 mm box on 6 mm voxels (no voxel centre need fall in
    its walls): every voxel outside its cavity and within the margin of a wall is left out,
    every voxel of the cavity farther in is kept; a sheet closes nothing, so only the voxels
    at it are left out."""
    from rfsdf.recon.warm_start import known_exclusion

    grid = Grid.from_voxel((-0.1,) * 3, (0.1,) * 3, 0.006)
    points = grid.points().double()
    box = _known(BOX)
    inner = (points.abs() < 0.047).all(1).reshape(grid.shape).numpy()
    wall_distance = box.sdf(points).reshape(grid.shape).numpy()
    for margin in (0.0, 0.003, 0.01):
        out = known_exclusion(grid, box, margin)
        np.testing.assert_array_equal(out[~inner], True)
        np.testing.assert_array_equal(out[inner], wall_distance[inner] < margin)
    sheet = _known({"name": "sheet", "material": "glass",
                    "shape": {"type": "box", "half_extents_m": [0.08, 0.08, 0.0015], "center_m": [0, 0, 0.02]}})
    distance = sheet.sdf(points).reshape(grid.shape).numpy()
    np.testing.assert_array_equal(known_exclusion(grid, sheet, 0.004), distance < 0.004)


def test_the_warm_start_seen_through_a_known_box_leaves_out_what_lies_outside_it(sphere_data, tmp_path, monkeypatch):
    """With ``Problem.through`` the warm start's excluded voxels take in ``known_exclusion``
    at ``[init] known_margin_m``: the detection, and the range peaks with it, keeps to the box."""
    import rfsdf.recon.trainer as trainer_module
    from rfsdf.recon.warm_start import known_exclusion

    _, data = sphere_data
    seen = {}
    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: seen.update(kw))
    settings = _config(steps=2).model_dump()
    settings["init"].update(method="mf", threshold=0.05)
    box = _known(BOX)
    trainer = Trainer(Problem(data, _grid(10), through=box), ReconConfig.model_validate(settings), tmp_path)
    trainer.warm_start()
    known = known_exclusion(trainer.problem.grid, box, ReconConfig().init.known_margin_m)
    assert known.any() and (~known).any()
    assert seen["exclude"][known].all()
    grid_points = trainer.problem.grid.points().double().numpy()
    keep = ~seen["exclude"].ravel()
    assert (np.abs(grid_points[keep]) < 0.047).all()
    assert seen["peaks"] is None or (np.abs(seen["peaks"].points) < 0.047 + 0.015).all()


def test_the_fit_holds_its_zero_set_through_the_warm_starts_range_peaks(sphere_data, tmp_path):
    """``[loss] peak_weight``: while the geometry moves, the fit adds that times the
    amplitude-weighted mean |f| at the warm start's range peaks. Peaks on the true ball, a
    field started 3 mm too large: after 4 free steps f at the peaks is under half what the data loss
    alone leaves; the term is that mean, exactly, and the peaks come back with a resumed run."""
    _, data = sphere_data
    golden = np.pi * (3 - np.sqrt(5)) * np.arange(200)
    z = np.linspace(0.05, 0.95, 200)  # the hemisphere that faces the views (+z and around)
    points = RADIUS * np.stack([np.sqrt(1 - z**2) * np.cos(golden), np.sqrt(1 - z**2) * np.sin(golden), z], 1)
    peaks = (torch.from_numpy(points).float(), torch.linspace(0.2, 1.0, 200))
    left = {}
    for weight in (0.0, 1000.0):
        settings = _config(steps=4, geometry_delay=0.0).model_dump()
        settings["loss"].update(peak_weight=weight, peak_cone_deg=0.0)  # f at the peaks: no views to read caps from
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / f"{weight}")
        trainer.peaks = peaks
        if weight:
            trainer.refresh_surface()
            terms = trainer.loss_terms()
            with torch.no_grad():
                held = (trainer.field.sdf(peaks[0]).abs() * peaks[1]).sum() / peaks[1].sum()
            assert float(terms["peaks"].detach()) == pytest.approx(weight * float(held), rel=1e-5)
        trainer.fit()
        with torch.no_grad():
            left[weight] = float(trainer.field.sdf(peaks[0]).abs().mean())
    assert left[1000.0] < 0.5 * left[0.0], left
    resumed = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / "1000.0")
    resumed.load()
    assert all(torch.equal(a, b) for a, b in zip(resumed.peaks, peaks))


def test_the_fit_can_hold_its_range_peaks_as_glints(sphere_data, tmp_path):
    """``[loss] peak_cone_deg``: the held term is the amplitude-weighted mean |least f| over
    each peak's glint cap (``glint_gap`` on the sphere of its range about its view's centre);
    a planar scan's peaks have no range to read, so their caps are the peaks themselves."""
    from rfsdf.radar import Measurements
    from rfsdf.recon.glints import glint_gap

    _, data = sphere_data
    centres = data.acquisition.view_centres()[0].float()
    view = torch.arange(12) % data.acquisition.num_views
    towards = torch.nn.functional.normalize(centres[view], dim=1)  # lines through the ball's centre
    points = 0.9 * RADIUS * towards + 0.002 * torch.randn(12, 3, generator=torch.Generator().manual_seed(0))
    amplitude = torch.linspace(0.2, 1.0, 12)
    settings = _config(steps=2, geometry_delay=0.0).model_dump()
    settings["loss"].update(peak_weight=1000.0, peak_cone_deg=0.5)
    trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / "glints")
    trainer.peaks = (points, amplitude, view, towards)
    trainer.refresh_surface()
    terms = trainer.loss_terms()
    ranges = (points - centres[view]).norm(dim=1)
    with torch.no_grad():
        gaps = glint_gap(trainer.field.sdf, points, towards, ranges, math.radians(0.5))
        on_lines = trainer.field.sdf(points)
    assert float(terms["peaks"].detach()) == pytest.approx(1000.0 * float((gaps.abs() * amplitude).sum()
                                                                          / amplitude.sum()), rel=1e-5)
    assert (gaps <= on_lines + 1e-7).all() and (gaps < on_lines - 1e-5).any()  # the least f over a cap
    assert trainer.peak_caps(0.0) is None and ReconConfig().loss.peak_cone_deg == 0.25
    scanned = dataclasses.replace(data.acquisition, scans=torch.zeros(data.acquisition.shape[0], dtype=torch.int64))
    trainer = Trainer(Problem(Measurements(scanned, data.data), _grid(10)), ReconConfig.model_validate(settings),
                      tmp_path / "scanned")
    trainer.peaks = (points, amplitude, torch.zeros(12, dtype=torch.int64), towards)
    assert (trainer.peak_ranges() == 0).all()
    torch.testing.assert_close(trainer.peak_caps(0.5), points[:, None].expand(-1, 19, -1))


def test_the_warm_start_can_blank_sidelobes_of_the_matched_filter_beside_cleans(sphere_data, tmp_path, monkeypatch):
    """``[init] sidelobes_in_mf`` with the CLEAN method: what is a range sidelobe (within
    ``sidelobe_reach``, under ``sidelobe_level``) in the matched filter's per-view images is
    left out too."""
    import rfsdf.recon.trainer as trainer_module
    from rfsdf.radar.clean import clean_image
    from rfsdf.radar.detection import on_range_sidelobes

    _, data = sphere_data
    seen = {}
    monkeypatch.setattr(trainer_module, "warm_start", lambda *args, **kw: seen.update(kw))
    grid = _grid(10)
    clean = clean_image(data, grid)
    frequencies, centres = data.acquisition.frequencies_hz.numpy(), data.acquisition.tx_m.mean(1).numpy()
    mf = (matched_filter(data, grid).per_view.abs() ** 2).numpy()
    for in_mf in (False, True):
        settings = _config(steps=2).model_dump()
        settings["init"].update(method="clean", carve_front=False, glint_sidelobes=False, threshold=0.05,
                                sidelobe_reach=6.0, sidelobe_level=0.4, sidelobes_in_mf=in_mf)
        trainer = Trainer(Problem(data, grid, clean=clean), ReconConfig.model_validate(settings), tmp_path / f"{in_mf}")
        trainer.warm_start()
        rule = {"threshold": 0.05, "local_threshold": 0.5, "window_m": 0.03, "reach": 6.0, "level": 0.4}
        expected = on_range_sidelobes(clean.per_view_power.numpy(), centres, frequencies, grid, **rule)
        if in_mf:
            expected |= on_range_sidelobes(mf, centres, frequencies, grid, **rule)
        np.testing.assert_array_equal(seen["exclude"], expected)


def test_f_stays_frozen_while_gamma_adapts_first(sphere_data, tmp_path):
    _, data = sphere_data
    trainer = Trainer(Problem(data, _grid(10)), _config(steps=6, geometry_delay=0.5), tmp_path / "run")
    start = {k: v.clone() for k, v in trainer.field.state_dict().items()}
    seen = {}

    def snapshot(step):
        seen[step] = {k: v.clone() for k, v in trainer.field.state_dict().items()}

    trainer.fit(on_step=snapshot)
    geometry = [k for k in start if k.startswith("geometry.")]
    reflectance = [k for k in start if k.startswith("reflectance.")]
    assert geometry and reflectance
    assert all(torch.equal(seen[3][k], start[k]) for k in geometry)  # steps 1-3: Gamma only
    assert not all(torch.equal(seen[3][k], start[k]) for k in reflectance)
    assert not all(torch.equal(seen[6][k], seen[3][k]) for k in geometry)  # then f moves
    assert all(r.eikonal == 0 for r in trainer.log[:3]) and all(r.eikonal > 0 for r in trainer.log[3:])


def test_with_displacement_knots_the_warm_start_moves_the_network_and_the_fit_only_the_knots(sphere_data, tmp_path):
    """``field.displacement_knot_m``: the warm start's regression leaves the displacement at
    zero, the fit then moves f through it alone (no geometry weight changes), and the ball,
    too large at the start, shrinks (by 0.28 mm in 20 steps when written: the knots' own pull
    is slow, the network's moves it 2.75 mm in 40 steps, `test_a_tiny_fit_recovers_a_dilated_sphere`)."""
    _, data = sphere_data
    field = RadarField((-0.06,) * 3, (0.06,) * 3, levels=2, width=32, depth=4, displacement_knot_m=0.01)
    weights = field.geometry.layers[0].weight.clone()
    fit_to_image(field, (-0.06,) * 3, (0.06,) * 3, lambda p: p.norm(dim=1) - RADIUS, None, steps=3,
                 lr=1e-3, batch=512, eikonal_weight=0.1, generator=torch.Generator().manual_seed(0))
    assert torch.count_nonzero(field.displacement.offsets_m) == 0
    assert not torch.equal(field.geometry.layers[0].weight, weights)

    config = _config(steps=20, geometry_delay=0.0, lr=1e-3, lr_end=3e-4)
    config = config.model_copy(update={"field": config.field.model_copy(update={"displacement_knot_m": 0.01})})
    trainer = Trainer(Problem(data, _grid()), config, tmp_path / "run")
    before = {k: v.clone() for k, v in trainer.field.state_dict().items()}
    radius = _mean_radius(trainer.field, trainer.renderer)
    trainer.fit()
    after = trainer.field.state_dict()
    assert all(torch.equal(after[k], before[k]) for k in before if k.startswith("geometry."))
    assert torch.count_nonzero(after["displacement.offsets_m"]) > 0
    end = _mean_radius(trainer.field, trainer.renderer)
    assert end < radius - 0.0001, (radius, end)


def test_the_geometrys_learning_rate_decays_over_every_step_or_from_its_release(sphere_data, tmp_path):
    """Freed at step 6 of 10 (lr 1e-3 -> 1e-4, exponential): "shared" takes the one decay over
    every step up where it is, 1e-3 x 0.1^0.6; "from_release" starts the whole decay there."""
    _, data = sphere_data
    rates = {}
    for schedule in ("shared", "from_release"):
        config = _config(steps=10, geometry_delay=0.6, geometry_schedule=schedule)
        trainer = Trainer(Problem(data, _grid(10)), config, tmp_path / schedule)
        geometry, reflectance = trainer.scheduler.lr_lambdas[:2]
        rates[schedule] = [geometry(step) for step in range(10)]
        assert [reflectance(step) for step in (0, 6)] == pytest.approx([1.0, 0.1 ** 0.6])
    assert rates["shared"][:6] == rates["from_release"][:6] == [0.0] * 6
    assert rates["shared"][6:] == pytest.approx([0.1 ** (step / 10) for step in range(6, 10)])
    assert rates["from_release"][6:] == pytest.approx([0.1 ** (step / 4) for step in range(4)])
    with pytest.raises(ValueError, match="geometry_schedule"):
        _config(geometry_schedule="later")


@pytest.mark.parametrize("level", [0.0, 1.5, float("nan")])
def test_a_sidelobe_level_outside_zero_to_one_is_refused(level):
    with pytest.raises(ValueError, match="sidelobe_level"):
        ReconConfig.model_validate({"init": {"sidelobe_level": level}})


def test_a_fit_writes_no_progress_line_a_step_into_a_log(sphere_data, tmp_path, capsys):
    """stderr is not a terminal here, as in a batch job: a short fit writes no bar at all
    (a forced redraw per step once wrote a line per step into the demo's log)."""
    _, data = sphere_data
    Trainer(Problem(data, _grid(10)), _config(steps=6), tmp_path / "run", progress=True).fit()
    assert capsys.readouterr().err.count("fit:") == 0


@pytest.fixture
def one_thread():
    """torch at one thread for the test, the count restored after it: bit for bit is a
    promise at a fixed thread count and kernel split; once (CI, stop 58), after the whole
    suite had run before it on two threads, the resumed weights differed from the straight
    run's in the eighth digit, which neither this file alone nor six straight runs in one
    process with other allocations between them reproduced."""
    default = torch.get_num_threads()
    use_threads(1)  # numba's too: its loops would set the shared OpenMP team back
    yield
    use_threads(default)


def test_resume_after_a_kill_reproduces_the_uninterrupted_run(sphere_data, tmp_path, one_thread):
    _, data = sphere_data
    problem = Problem(data, _grid(10), "data.h5")
    straight = Trainer(problem, _config(), tmp_path / "a").fit().field

    def kill_at_7(step):
        if step == 7:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        Trainer(problem, _config(), tmp_path / "b").fit(on_step=kill_at_7)  # last checkpoint: step 5
    resumed = Trainer(problem, _config(), tmp_path / "b").fit(resume=True).field
    for a, b in zip(straight.state_dict().values(), resumed.state_dict().values()):
        assert torch.equal(a, b)
    assert torch.equal(load_field(tmp_path / "b").state_dict()["geometry.layers.0.weight"],
                       straight.state_dict()["geometry.layers.0.weight"])
    with pytest.raises(RfsdfError, match="already holds a run"):
        Trainer(problem, _config(), tmp_path / "b").fit()
    other = Problem(dataclasses.replace(data, data=data.data * 1.5), _grid(10), "other.h5")
    with pytest.raises(RfsdfError, match="fitted on data.h5 .* not on other.h5"):
        Trainer(other, _config(), tmp_path / "b").fit(resume=True)


def test_the_primitives_that_replaced_their_fragments_resume_with_the_run(sphere_data, tmp_path):
    """The checkpoint holds them (the material readout reads through them after a resume)."""
    from rfsdf.recon.object_primitives import FramedPrimitive

    _, data = sphere_data
    problem = Problem(data, _grid(10), "data.h5")
    trainer = Trainer(problem, _config(), tmp_path)
    trainer.primitives = [FramedPrimitive("capsule", [0.01, 0.0, 0.0], [0.0, 0.3, 0.0], [0.01, 0.02])]
    trainer.save()
    resumed = Trainer(problem, _config(), tmp_path)
    resumed.load()
    points = torch.rand(50, 3, dtype=torch.float64) * 0.04
    assert [p.kind for p in resumed.primitives] == ["capsule"]
    torch.testing.assert_close(resumed.primitives[0](points), trainer.primitives[0](points))


def test_a_run_resumes_on_another_device_but_not_with_other_settings(sphere_data, tmp_path):
    """The device says where a fit runs, not what it fits: a run started under one
    train.device goes on under another, as under another known gain given after the fit
    (calibration.gain, which only the materials' reading uses); any other setting refuses."""
    _, data = sphere_data
    problem = Problem(data, _grid(10), "data.h5")
    Trainer(problem, _config(steps=6, device="auto"), tmp_path / "run").fit()
    assert len(Trainer(problem, _config(steps=6, device="cpu"), tmp_path / "run").fit(resume=True).log) == 6
    given = _config(steps=6).model_copy(update={"calibration": CalibrationConfig(gain=2.5)})
    assert len(Trainer(problem, given, tmp_path / "run").fit(resume=True).log) == 6
    with pytest.raises(RfsdfError, match="made with another config"):
        Trainer(problem, _config(steps=6, lr=2e-3), tmp_path / "run").fit(resume=True)


def test_the_data_cells_anneal_from_coarse_to_fine_once_f_moves(sphere_data, tmp_path):
    _, data = sphere_data
    config = _config(steps=10, geometry_delay=0.2)
    config = ReconConfig.model_validate({**config.model_dump(), "sampling": {
        **config.sampling.model_dump(), "cell_voxels": 1, "cell_voxels_start": 4}})
    trainer = Trainer(Problem(data, _grid(10)), config, tmp_path / "run")
    sizes = []
    for step in range(10):
        trainer.step = step
        sizes.append(trainer.cell_size())
    assert sizes[:3] == [4, 4, 4] and sizes[-1] == 1 and sizes == sorted(sizes, reverse=True)
    assert Trainer(Problem(data, _grid(10)), _config(), tmp_path / "b").cell_size() == 2  # unset: constant


def test_non_finite_loss_stops_with_a_clear_error_and_keeps_the_checkpoint(sphere_data, tmp_path, monkeypatch):
    _, data = sphere_data
    trainer = Trainer(Problem(data, _grid(10)), _config(), tmp_path / "run")
    real = trainer.loss_terms

    def poisoned():
        terms = real()
        if trainer.step >= 7:
            terms["loss"] = terms["loss"] * float("nan")
        return terms

    monkeypatch.setattr(trainer, "loss_terms", poisoned)
    with pytest.raises(RfsdfError, match=r"step 7: loss is not finite.*last good checkpoint kept"):
        trainer.fit()
    assert torch.load(tmp_path / "run" / CHECKPOINT_NAME, weights_only=True)["step"] == 5


@pytest.mark.parametrize("table,key,name", [("render", "renderer", "physics"), ("loss", "data", "l7"),
                                            ("train", "schedule", "cosine")])
def test_unknown_names_are_refused_with_the_known_ones(table, key, name):
    with pytest.raises(Exception, match=f"unknown .*'{name}'; known: "):
        ReconConfig.model_validate({table: {key: name}})


def test_a_continuation_names_its_losses_in_order_and_refuses_others():
    stages = {"loss": {"stages": [{"data": "amplitude", "until": 0.4}, {"data": "complex", "until": 1.0}]}}
    loss = ReconConfig.model_validate(stages).loss
    assert [loss.stage_at(f) for f in (0.0, 0.39, 0.4, 0.99, 1.0)] == ["amplitude"] * 2 + ["complex"] * 3
    assert ReconConfig.model_validate({"loss": {"data": "complex"}}).loss.stage_at(0.9) == "complex"  # throughout
    with pytest.raises(Exception, match="unknown data loss 'phase'; known: "):
        ReconConfig.model_validate({"loss": {"stages": [{"data": "phase", "until": 1.0}]}})
    for until in ([0.6, 0.4, 1.0], [0.5, 0.9]):
        with pytest.raises(Exception, match="each stage must end after the one before and the last at 1"):
            ReconConfig.model_validate({"loss": {"stages": [{"data": "amplitude", "until": u} for u in until]}})
    for until in (0.0, 1.5):
        with pytest.raises(Exception, match="until"):
            ReconConfig.model_validate({"loss": {"stages": [{"data": "amplitude", "until": until}]}})


def test_the_default_continuation_is_amplitude_while_f_is_frozen_then_split():
    """Neither loss.data nor loss.stages given: amplitude until train.geometry_delay, then
    split; with no delay split throughout; loss.data alone is that loss at every step; a
    written config reads back as itself."""
    default = ReconConfig()
    assert [(s.data, s.until) for s in default.loss.stages] == [("amplitude", 0.7), ("split", 1.0)]
    assert default.loss.stage_at(default.train.geometry_delay_steps / default.train.steps) == "split"
    assert default.loss.stage_at((default.train.geometry_delay_steps - 1) / default.train.steps) == "amplitude"
    delayed = ReconConfig.model_validate({"train": {"geometry_delay": 0.4}})
    assert [(s.data, s.until) for s in delayed.loss.stages] == [("amplitude", 0.4), ("split", 1.0)]
    assert [s.data for s in ReconConfig.model_validate({"train": {"geometry_delay": 0.0}}).loss.stages] == ["split"]
    assert ReconConfig.model_validate({"loss": {"data": "amplitude"}}).loss.names() == ["amplitude"]
    assert ReconConfig.model_validate(delayed.model_dump()) == delayed
    with pytest.raises(Exception, match="geometry_delay"):
        ReconConfig.model_validate({"train": {"geometry_delay": "soon"}})


def test_the_complex_loss_forgives_each_views_phase_and_gain_but_not_a_phase_error():
    g = torch.Generator().manual_seed(0)
    predicted = torch.randn(3, 40, dtype=torch.complex128, generator=g)
    turns = torch.exp(1j * torch.tensor([0.3, -2.0, 1.1], dtype=torch.float64))[:, None]
    assert float(complex_loss(predicted, 2.5 * turns * predicted)) < 1e-20
    assert float(complex_loss(predicted, turns * predicted, fit_gain=False)) < 1e-20
    assert float(complex_loss(predicted, 2.5 * turns * predicted, fit_gain=False)) > 0.3  # a known gain is held
    moved = predicted * torch.exp(1j * torch.linspace(0, 1.0, 40, dtype=torch.float64))  # one glint's phase, not all
    assert float(complex_loss(predicted, moved)) > 0.01 > float(amplitude_loss(predicted, moved))
    observed = 2.5 * turns * moved
    assert torch.autograd.gradcheck(lambda p: complex_loss(p, observed), (predicted.clone().requires_grad_(True),))


def test_each_data_loss_per_voxel_is_where_its_misfit_lies_and_sums_to_it():
    """``per_voxel``: each voxel's share of a data loss (summed over the views), the whole
    loss when summed, gain fitted or held; a misfit confined to one voxel lies there alone."""
    g = torch.Generator().manual_seed(3)
    predicted = torch.randn(3, 2, 30, dtype=torch.complex128, generator=g)
    observed = predicted.clone()
    observed[:, :, 11] += 0.5
    for name in DATA_LOSSES.names():
        loss = DATA_LOSSES.get(name)
        p, o = (predicted, observed) if name == "split" else (predicted.sum(1), observed.sum(1))
        for fit_gain in (True, False):
            shares = loss(p, o, fit_gain=fit_gain, per_voxel=True)
            assert shares.shape == (30,) and float(shares.sum()) == pytest.approx(float(loss(p, o, fit_gain=fit_gain)))
        shares = loss(p, o, fit_gain=False, per_voxel=True)  # (the complex loss still turns each view)
        assert float(shares[11]) > 0 and float(shares.sum() - shares[11]) < 0.05 * float(shares[11]), name


def test_split_spectrum_interferograms_see_the_range_that_each_views_phase_absorbs():
    """A point target moved towards the array by 1, 2 and 4 mm (one to four carrier cycles of
    the round trip): its image at its true position turns by about 2 k delta in each half of the
    band, so the complex loss, which fits each view's phase, hardly sees the move, while the
    interferogram I_lo conj(I_hi) turns by 2 (k_lo - k_hi) delta (to 3 %: the array's elements
    see the move a little off their axis) and the split-spectrum loss grows with it."""
    from rfsdf.radar.operator import SensingOperator
    from rfsdf.studies.ball_fit import small_radar

    acq = small_radar(bandwidth_hz=4e9, subcarriers=16).acquisition().view(0)
    acq = dataclasses.replace(acq, **{n: getattr(acq, n).double() for n in ("tx_m", "rx_m", "boresight")})
    op, k = SensingOperator(acq), 2 * math.pi * acq.frequencies_hz.double() / 2.99792458e8
    lower = torch.arange(16) < 8
    voxels = torch.tensor([[0.0, 0.0, 0.0]], dtype=torch.float64) + torch.linspace(-0.01, 0.01, 9,
                                                                                    dtype=torch.float64)[:, None]

    def band_images(target):
        y = op.forward(torch.as_tensor([target], dtype=torch.float64), torch.ones(1, dtype=torch.complex128))
        return torch.stack([op.adjoint(y * mask, voxels) for mask in (lower, ~lower)])[None]  # (1, 2, X)

    observed = band_images([0.0, 0.0, 0.0])
    split, whole = [], []
    for delta in (1e-3, 2e-3, 4e-3):
        moved = band_images((-delta * acq.boresight[0]).tolist())
        interferogram = moved[0, 0, 4] * moved[0, 1, 4].conj() / (observed[0, 0, 4] * observed[0, 1, 4].conj())
        expected = 2 * (k[lower].mean() - k[~lower].mean()) * delta
        assert float(torch.angle(interferogram)) == pytest.approx(float(expected), rel=0.03)
        split.append(float(split_spectrum_loss(moved, observed)))
        whole.append(float(complex_loss(moved.sum(1), observed.sum(1))))
    assert split == sorted(split) and split[0] > 0.005, split
    assert max(whole) < split[0] / 5, (whole, split)
    assert float(split_spectrum_loss(3.0 * torch.exp(1j * torch.tensor(0.7)) * observed, observed)) < 1e-20


def test_the_renderers_sub_band_images_add_up_to_its_full_band_image(sphere_data):
    """Each half of the band imaged alone, weighted by its share of the frequencies, sums to
    the full-band image, predicted and observed alike (the observed one from a renderer of the
    full band alone); the true ball's predicted halves match the data's (correlation 0.999,
    as the full band's)."""
    _, data = sphere_data
    truth = _Ball(RADIUS)
    renderer = CoherentRenderer(data, _grid(10), bands=2)
    views, voxels = torch.arange(renderer.num_views), torch.arange(renderer.voxels.shape[0])
    with torch.no_grad():
        renderer.refresh(truth.sdf, torch.Generator().manual_seed(0))
        full, halves = renderer(truth, views, voxels), renderer(truth, views, voxels, bands=True)
    torch.testing.assert_close(halves.mean(1), full, rtol=1e-4, atol=1e-5 * float(full.abs().max()))
    full_band = CoherentRenderer(data, _grid(10))  # its observed images from the whole band at once
    torch.testing.assert_close(renderer.observed, full_band.observed, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(renderer.band_observed.mean(1), full_band.observed, rtol=1e-4, atol=1e-5)
    observed = renderer.band_observed.reshape(renderer.num_views, -1)
    correlation = (halves.reshape(renderer.num_views, -1).conj() * observed).sum(1).abs() / (
        halves.reshape(renderer.num_views, -1).norm(dim=1) * observed.norm(dim=1))
    assert float(correlation.min()) > 0.999, correlation
    with pytest.raises(ValueError, match="bands must be 1 to the"):
        CoherentRenderer(data, _grid(10), bands=100)


def test_detection_threshold_auto_is_the_clean_residual_floor_and_numbers_pass_through():
    from rfsdf.config import validate
    from rfsdf.recon.warm_start import detection_threshold

    class Floor:
        def residual_floor(self):
            return 0.0627

    assert ReconConfig.model_validate({"init": {"threshold": "auto"}}).init.threshold == "auto"
    assert detection_threshold("auto", Floor()) == 0.0627
    assert detection_threshold(ReconConfig.model_validate({"init": {"threshold": 0.12}}).init.threshold, None) == 0.12
    with pytest.raises(ValueError, match="needs the CLEAN image"):
        detection_threshold("auto", None)
    for bad, message in (({"threshold": 1.5}, 'init.threshold: must be "auto" or a number between 0 and 1'),
                         ({"threshold": "median"}, "init.threshold: must be"),
                         ({"method": "mf", "threshold": "auto"}, 'init: threshold "auto" is the CLEAN residual floor')):
        with pytest.raises(RfsdfError, match=message):
            validate(ReconConfig, {"init": bad}, "recon.toml")


def test_a_lines_range_peak_is_the_vertex_of_its_parabola_and_moves_with_the_peak():
    """``peak_offset``: a parabola's vertex exactly; a range peak sinc^2(2 B t / c) of the
    demo's 4 GHz shifted by up to 3 mm, to 2 %; no peak (a rising line) is marked so. The
    match loss is 0 where the predicted peaks lie on the observed ones and grows with their
    distance, whatever either line's brightness."""
    from rfsdf.recon.losses import peak_match_loss, peak_offset

    offsets = torch.linspace(-0.006, 0.006, 5, dtype=torch.float64)
    vertex, valid = peak_offset((1 - ((offsets - 0.0013) / 0.01) ** 2)[None], offsets)
    assert float(vertex) == pytest.approx(0.0013, abs=1e-12) and bool(valid)
    for shift in (0.0005, 0.001, 0.003):
        vertex, valid = peak_offset(torch.sinc(2 * 4e9 * (offsets - shift) / 3e8)[None] ** 2, offsets)
        assert float(vertex) == pytest.approx(shift, rel=0.02) and bool(valid)
    assert not bool(peak_offset((offsets + 1.0)[None], offsets)[1])
    image = lambda shift, gain: gain * torch.sinc(2 * 4e9 * (offsets - shift) / 3e8).to(torch.complex128)  # noqa: E731
    weights = torch.ones(2, dtype=torch.float64)
    observed = torch.stack([image(0.0, 1.0), image(0.001, 3.0)])
    assert float(peak_match_loss(torch.stack([image(0.0, 5.0), image(0.001, 0.2)]), observed, offsets, weights,
                                 1e-3)) == pytest.approx(0.0, abs=1e-9)
    near, far = (float(peak_match_loss(torch.stack([image(d, 1.0), image(0.001 + d, 1.0)]), observed, offsets,
                                       weights, 1e-3)) for d in (0.0005, 0.002))
    assert 0 < near < far


def test_the_renderer_images_lines_as_it_images_voxels(sphere_data):
    """``lines``: each view's image at points of its own comes from the same prediction as
    its voxels' (full band, also while it forms sub-band images); placed at voxel centres
    they are those voxels' images, and ``observed_at`` there is ``observed``."""
    _, data = sphere_data
    renderer = CoherentRenderer(data, _grid(10), bands=2)
    field = _Ball(RADIUS)
    renderer.refresh(field.sdf, torch.Generator().manual_seed(0))
    views, voxels = torch.tensor([0, 3]), torch.arange(0, 1000, 7)
    lines = [renderer.voxels[voxels[:40]], None]
    for bands in (False, True):
        images, line_images = renderer(field, views, voxels, bands=bands, lines=lines)
        torch.testing.assert_close(images, renderer(field, views, voxels, bands=bands), rtol=1e-4, atol=1e-6)
        full = renderer.full_band(images) if bands else images
        torch.testing.assert_close(line_images[0], full[0, :40], rtol=1e-4, atol=1e-6)
        assert line_images[1] is None
    torch.testing.assert_close(renderer.observed_at(3, renderer.voxels[voxels]), renderer.observed[3, voxels],
                               rtol=1e-4, atol=1e-6)


def test_the_fit_moves_its_predicted_range_peaks_onto_the_datas(sphere_data, tmp_path):
    """``[loss] peak_match_weight``: lines of sight through the true ball, one set a view,
    each towards its view; a field started 3 mm too large ends nearer the ball after 4 free
    steps with the peaks matched than on the data loss alone (the held peaks off in both)."""
    _, data = sphere_data
    centres = 0.5 * sum(data.acquisition.view_centres())  # (V, 3)
    golden = np.pi * (3 - np.sqrt(5)) * np.arange(30)
    points, views, towards = [], [], []
    for v, centre in enumerate(centres.numpy()):
        axis = centre / np.linalg.norm(centre)
        helper = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
        helper /= np.linalg.norm(helper)
        other = np.cross(axis, helper)
        tilt = np.linspace(0.0, 0.4, 30)  # within 23 degrees of the view's own direction
        direction = (np.cos(tilt)[:, None] * axis + np.sin(tilt)[:, None] * (np.cos(golden)[:, None] * helper
                                                                           + np.sin(golden)[:, None] * other))
        on = RADIUS * direction
        points.append(on)
        towards.append((centre - on) / np.linalg.norm(centre - on, axis=1, keepdims=True))
        views.append(np.full(30, v))
    peaks = (torch.from_numpy(np.concatenate(points)).float(), torch.ones(30 * len(centres)),
             torch.from_numpy(np.concatenate(views)), torch.from_numpy(np.concatenate(towards)).float())
    radius = {}
    for weight in (0.0, 10.0):
        settings = _config(steps=4, geometry_delay=0.0).model_dump()
        settings["loss"].update(peak_weight=0.0, peak_match_weight=weight)
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / f"{weight}")
        trainer.peaks = peaks
        if weight:
            trainer.refresh_surface()
            assert float(trainer.loss_terms()["peak_match"].detach()) > 0
        trainer.fit()
        radius[weight] = _mean_radius(trainer.field, trainer.renderer)
    assert abs(radius[10.0] - RADIUS) < abs(radius[0.0] - RADIUS) - 0.0005, radius


def test_the_bending_energy_is_a_term_of_the_fit_only_when_asked(sphere_data, tmp_path):
    """``[loss] bending_weight``: a positive term of its weight while the geometry moves, no
    term (and no draw from the generator) at 0, so the default fit is unchanged by it."""
    _, data = sphere_data
    terms = {}
    for weight in (0.0, 1.0):
        settings = _config(steps=1, geometry_delay=0.0).model_dump()
        settings["loss"].update(bending_weight=weight)
        trainer = Trainer(Problem(data, _grid(10)), ReconConfig.model_validate(settings), tmp_path / f"{weight}")
        trainer.refresh_surface()
        terms[weight] = trainer.loss_terms()
    assert "bending" not in terms[0.0]
    assert 0 < float(terms[1.0]["bending"].detach()) < 4  # |n - n'|^2 of unit normals is at most 4
    assert float(terms[1.0]["loss"].detach()) > float(terms[0.0]["loss"].detach())
