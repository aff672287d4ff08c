import pytest
import torch

from rfsdf.errors import RfsdfError
from rfsdf.geometry import Grid
from rfsdf.radar import Acquisition, load_radar, point_spread
from rfsdf.recon import PhysicsRenderer, Problem, ReconConfig, Trainer, delta_sigma, sigma_at
from rfsdf.recon.trainer import load_field
from rfsdf.recon.warm_start import image_signed_distance

TRUE_RADIUS = 0.035


def _tiny_problem() -> Problem:
    """A sphere's 'MF power' (a thin Gaussian shell) seen by 4 views on the axes."""
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (16, 16, 16))
    p = grid.points()
    shell = torch.exp(-0.5 * ((p.norm(dim=1) - TRUE_RADIUS) / 0.006) ** 2).reshape(grid.shape)
    centres = torch.tensor([[0.5, 0, 0], [-0.5, 0, 0], [0, 0.5, 0], [0, -0.5, 0]], dtype=torch.float64)
    acq = Acquisition(centres[:, None], centres[:, None], torch.tensor([79e9]), -centres / 0.5)
    return Problem(grid, shell.expand(4, -1, -1, -1).clone(), centres.float(), acq)


def _config(steps=20, init="sphere", **train) -> ReconConfig:
    return ReconConfig.model_validate({
        "field": {"width": 32, "depth": 4, "levels": 2, "init_radius_m": 0.02},
        "init": {"method": init, "threshold": 0.5, "steps": 150, "lr": 3e-3, "batch": 1024},
        "render": {"renderer": "local", "facing_exponent": 0.0},
        "sampling": {"data_batch": 512, "eikonal_batch": 256, "views_per_step": 2},
        "train": {"steps": steps, "checkpoint_every": 5, "lr": 3e-3, **train},
    })


def test_sigma_anneals_exponentially_to_the_end_value():
    assert sigma_at(0, 100, 0.03, 0.01) == pytest.approx(0.03)
    assert sigma_at(50, 100, 0.03, 0.01) == pytest.approx((0.03 * 0.01) ** 0.5)
    assert sigma_at(100, 100, 0.03, 0.01) == pytest.approx(0.01)
    assert sigma_at(0, 100, 0.03, 0.01, "constant") == 0.01
    assert delta_sigma(torch.tensor([0.0, 0.01]), 0.01).tolist() == pytest.approx([1.0, 0.6065306])


def test_fit_moves_the_zero_level_set_toward_the_truth(tmp_path):
    problem = _tiny_problem()
    directions = torch.nn.functional.normalize(torch.randn(500, 3, generator=torch.Generator().manual_seed(1)), dim=1)
    on_truth = directions * TRUE_RADIUS
    trainer = Trainer(problem, _config(steps=150), tmp_path / "run")
    with torch.no_grad():
        before = trainer.field.sdf(on_truth).abs().mean().item()
    field = trainer.fit()
    with torch.no_grad():
        after = field.sdf(on_truth).abs().mean().item()
    assert before == pytest.approx(TRUE_RADIUS - 0.02, abs=0.003)
    assert after < 0.4 * before
    assert (tmp_path / "run" / "log.csv").read_text().count("\n") == 151


def test_image_signed_distance_of_a_ball_matches_the_closed_form():
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (40, 40, 40))
    p = grid.points()
    power = (p.norm(dim=1) < 0.03).float().reshape(grid.shape)  # 1 inside a 3 cm ball, 0 outside
    distance = torch.from_numpy(image_signed_distance(power.numpy(), grid, 0.5)).flatten()
    exact = p.norm(dim=1) - 0.03
    assert (distance - exact).abs().max() < float(grid.voxel_m[0])  # voxelised boundary: within a voxel
    assert (distance - exact).abs().mean() < 0.4 * float(grid.voxel_m[0])
    with pytest.raises(ValueError, match="selects no voxel"):
        image_signed_distance(torch.zeros(grid.shape).numpy(), grid, 0.5)


def test_image_warm_start_puts_the_surface_where_the_image_is_bright(tmp_path):
    directions = torch.nn.functional.normalize(torch.randn(500, 3, generator=torch.Generator().manual_seed(1)), dim=1)
    trainer = Trainer(_tiny_problem(), _config(steps=1, init="image"), tmp_path / "run")
    trainer.warm_start()
    with torch.no_grad():
        on_truth = trainer.field.sdf(directions * TRUE_RADIUS).abs().mean().item()
    # The shell image above half its peak amplitude is a shell of half-width ~7 mm around the
    # truth: the warm start's zero set hugs its outer side, much nearer than the 15 mm start.
    assert on_truth < 0.010


def test_resume_after_a_kill_reproduces_the_uninterrupted_run(tmp_path):
    problem = _tiny_problem()
    straight = Trainer(problem, _config(), tmp_path / "a").fit()

    def kill_at_12(step):
        if step == 12:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        Trainer(problem, _config(), tmp_path / "b").fit(on_step=kill_at_12)  # last checkpoint: step 10
    resumed = Trainer(problem, _config(), tmp_path / "b").fit(resume=True)
    for a, b in zip(straight.state_dict().values(), resumed.state_dict().values()):
        assert torch.equal(a, b)
    assert torch.equal(load_field(tmp_path / "b").state_dict()["geometry.layers.0.weight"],
                       straight.state_dict()["geometry.layers.0.weight"])
    with pytest.raises(RfsdfError, match="already holds a run"):
        Trainer(problem, _config(), tmp_path / "b").fit()


def test_non_finite_loss_stops_with_a_clear_error_and_keeps_the_checkpoint(tmp_path, monkeypatch):
    trainer = Trainer(_tiny_problem(), _config(), tmp_path / "run")
    real = trainer.loss_terms

    def poisoned(sigma):
        terms = real(sigma)
        if trainer.step >= 7:
            terms["loss"] = terms["loss"] * float("nan")
        return terms

    monkeypatch.setattr(trainer, "loss_terms", poisoned)
    with pytest.raises(RfsdfError, match=r"step 7: loss is not finite.*last good checkpoint kept"):
        trainer.fit()
    state = torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=False)
    assert state["step"] == 5


def test_physics_renderer_reproduces_the_exact_psf_of_a_point():
    acq = load_radar("near-77g").acquisition().view(slice(0, 2))
    grid = Grid((-0.03,) * 3, (0.03,) * 3, (12, 12, 12))
    renderer = PhysicsRenderer.from_acquisition(acq, grid, psf_radius_m=0.03)
    intensity = torch.zeros(2, *grid.shape)
    intensity[:, 6, 6, 6] = 1.0  # a unit scatterer on the central voxel
    predicted = renderer(intensity, torch.tensor([0, 1]))
    centre = grid.points()[6 * 144 + 6 * 12 + 6]
    exact = point_spread(acq, centre, grid).per_view.abs() ** 2
    assert predicted[:, 6, 6, 6] == pytest.approx(torch.ones(2), rel=1e-4)
    assert torch.allclose(predicted, exact, atol=1e-4)
