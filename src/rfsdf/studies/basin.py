"""How far each data loss pulls a surface: the fit's basin, measured on the demo scene.

The start: the true surface displaced along its normals by a smooth random field u (Gaussian,
20 mm correlation: the shape ``benchmarks/fit_errors.py`` measured on real fits, unit rms on
the true surface) times sigma (1, 2 and 4 mm at full size), i.e. a RadarField regressed onto
f(p) - sigma u(p). Each loss (or continuation of losses) then fits it to the demo's data from
the first step, with the radar's gain held and every surface certain of its object's true
material (``Problem.known_materials``), so that only the geometry is free. Measured: the
observed-surface Chamfer of each start and of where each loss ends (and each object's
Chamfer, since flat faces and curved ones do not end alike), each loss at each start and at
the true surface (the floor: the noise and what the forward model cannot reproduce), and the
metric's own floor (the true SDF meshed as the fits are).
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np
import torch
from scipy import ndimage

from ..device import resolve_device
from ..field import RadarField
from ..geometry import Grid, interpolated_sdf
from ..materials import MATERIAL_CLASSES
from ..mesh import extract_mesh
from ..metrics import evaluate_scene
from ..radar import load_radar, simulate
from ..radar.coverage import observed_mask
from ..radar.simulate import SIMULATED_GAIN
from ..recon import Problem, ReconConfig, Trainer
from ..recon.losses import DATA_LOSSES
from ..recon.render import CoherentRenderer
from ..recon.trainer import initial_field
from ..recon.warm_start import fit_to_image
from ..scene import load_scene
from ..viz.figures import plt, save_figure
from .ball_fit import small_radar

NAME = "basin"
SUMMARY = "where the fit ends from the true surface displaced by smooth errors of 1-4 mm, object by object"

# each fit's data losses: one loss throughout, or a continuation (LossConfig.stages)
SCHEDULES = {
    "amplitude": [{"data": "amplitude", "until": 1.0}],
    "complex": [{"data": "complex", "until": 1.0}],
    "amplitude-then-complex": [{"data": "amplitude", "until": 0.5}, {"data": "complex", "until": 1.0}],
}
_FIELD_STEP_M = 0.002  # the random field's grid


@dataclass(frozen=True)
class Settings:
    scene: str = "objects"
    radar: str = "near-77g"  # a preset, or "small" (the tests' six-view toy radar)
    voxel_m: float = 0.006
    errors_mm: tuple[float, ...] = (1.0, 2.0, 4.0)
    correlation_m: float = 0.02
    # the complex loss saturates by 0.5 mm of smooth error on the demo (its landscape), so
    # the full size fits the amplitude loss only; the complex loss is still measured at each start
    schedules: tuple[str, ...] = ("amplitude",)
    steps: int = 40
    # the settings under which the ball's fit held the truth and removed 58-80 % of smooth
    # 1-4 mm errors (benchmarks/surface_gradient.py): a new mesh every step at lr 3e-4
    lr: float = 3e-4
    refresh_every: int = 1
    width: int = 128
    depth: int = 6
    # 600 left the demo's regressed truth 25 mm off (observed Chamfer); 2000 gives 0.87 mm
    regress_steps: int = 2000
    element_step: int = 2
    views_per_step: int = 6
    data_batch: int = 4096
    mesh_resolution: int = 128
    metric_samples: int = 50_000
    seed: int = 0
    device: str = "auto"


QUICK = Settings(scene="sphere", radar="small", voxel_m=0.0075, errors_mm=(1.0, 4.0),
                 schedules=("amplitude-then-complex",), steps=4, width=32, depth=4, regress_steps=100, element_step=1,
                 data_batch=1024, mesh_resolution=48, metric_samples=5_000)


@dataclass(frozen=True)
class Result:
    errors_mm: list[float]  # the displacement's rms on the true surface
    start_observed_mm: list[float]  # observed-surface Chamfer-L1 of each start
    end_observed_mm: dict[str, list[float]] = field(default_factory=dict)  # per schedule, per start
    end_chamfer_mm: dict[str, list[float]] = field(default_factory=dict)  # the whole surface
    start_objects_mm: list[dict[str, float]] = field(default_factory=list)  # per start, each object's Chamfer-L1
    end_objects_mm: dict[str, list[dict[str, float]]] = field(default_factory=dict)  # ... where each schedule ends
    start_loss: dict[str, list[float]] = field(default_factory=dict)  # each data loss at each start
    truth_loss: dict[str, float] = field(default_factory=dict)  # ... at the true surface
    truth_observed_mm: float = 0.0  # the true SDF meshed as the fits are: the metric's floor
    seconds: float = 0.0


class TrueMaterials:
    """Points -> class index of the nearest object's material (``Problem.known_materials``).

    The renderer asks for the same surface candidates every step until it refreshes them,
    so the answer for the last tensor asked about is kept (``Scene.object_index`` over a
    demo's 10^5 facets takes seconds)."""

    def __init__(self, scene):
        self.scene = scene
        self.classes = [MATERIAL_CLASSES.index(o.material.name) for o in scene.objects]
        self._asked: torch.Tensor | None = None
        self._answer: torch.Tensor | None = None

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        if points is not self._asked:
            with torch.no_grad():
                index = self.scene.object_index(points).to(points.device)
                self._asked, self._answer = points, torch.tensor(self.classes, device=points.device)[index]
        return self._answer


def smooth_displacement(scene, correlation_m: float, generator: torch.Generator):
    """A Gaussian random field u(points (N, 3)) -> (N,) over the scene's bounds, correlated over
    ``correlation_m`` [m] (autocorrelation exp(-r^2 / 2 l^2)) and of unit rms on the true
    surface: white noise on a 2 mm grid, Gaussian-filtered, read trilinearly."""
    lower, upper = np.asarray(scene.lower_m) - 0.02, np.asarray(scene.upper_m) + 0.02
    grid = Grid.from_voxel(lower, upper, _FIELD_STEP_M)
    noise = torch.randn(grid.shape, generator=generator, dtype=torch.float64).numpy()
    values = ndimage.gaussian_filter(noise, correlation_m / np.sqrt(2) / _FIELD_STEP_M, mode="wrap")
    field_at = interpolated_sdf(torch.as_tensor(values, dtype=torch.float32).flatten(), grid)
    surface = scene.sample_surface(0.002, seed=0, max_samples=50_000).points
    with torch.no_grad():
        rms = float(field_at(surface).pow(2).mean().sqrt())
    return lambda points: field_at(points.float().cpu()).to(points) / rms  # differentiable in the points


def run(settings: Settings) -> Result:
    clock = time.perf_counter()
    device = resolve_device(settings.device, "device")
    scene = load_scene(settings.scene)
    radar = small_radar() if settings.radar == "small" else load_radar(settings.radar)
    data = simulate(scene, radar, seed=settings.seed, device=device)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    known = TrueMaterials(scene)
    problem = Problem(data, grid, source=f"{settings.scene} ({settings.radar})", gain=SIMULATED_GAIN,
                      known_materials=known)
    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=partial(observed_mask, acquisition=data.acquisition, occluder=scene.sdf))
    mesh = lambda sdf: extract_mesh(sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution,  # noqa: E731
                                    device=device)

    def config(schedule: str) -> ReconConfig:
        return ReconConfig.model_validate({
            "field": {"width": settings.width, "depth": settings.depth},
            "render": {"element_step": settings.element_step, "refresh_every": settings.refresh_every},
            "loss": {"stages": SCHEDULES[schedule]},
            "sampling": {"views_per_step": settings.views_per_step, "data_batch": settings.data_batch},
            "train": {"steps": settings.steps, "lr": settings.lr, "checkpoint_every": settings.steps,
                      "geometry_delay": 0.0, "seed": settings.seed, "device": str(device)}})

    losses = SurfaceLosses(problem, config("amplitude"), known)
    displacement = smooth_displacement(scene, settings.correlation_m, torch.Generator().manual_seed(settings.seed))
    near = scene.sample_surface(settings.voxel_m / 2, seed=settings.seed, max_samples=50_000).points
    result = Result(list(settings.errors_mm), [], truth_loss=losses(scene.sdf),
                    truth_observed_mm=score(mesh(lambda p: scene.sdf(p.double()))).observed.chamfer_l1_mm)
    for error_mm in settings.errors_mm:
        target = lambda p, e=error_mm * 1e-3: scene.sdf(p) - e * displacement(p)  # noqa: E731
        start = regressed_field(problem, config("amplitude"), target, near, steps=settings.regress_steps,
                                seed=settings.seed)
        metrics = score(mesh(start.sdf))
        result.start_observed_mm.append(metrics.observed.chamfer_l1_mm)
        result.start_objects_mm.append(_per_object_mm(metrics))
        for name, value in losses(start.sdf).items():
            result.start_loss.setdefault(name, []).append(value)
        for schedule in settings.schedules:
            with tempfile.TemporaryDirectory() as run_dir:
                fit = Trainer(problem, config(schedule), run_dir, start=start.state_dict()).fit()
            metrics = score(mesh(fit.field.sdf))
            result.end_observed_mm.setdefault(schedule, []).append(metrics.observed.chamfer_l1_mm)
            result.end_chamfer_mm.setdefault(schedule, []).append(metrics.full.chamfer_l1_mm)
            result.end_objects_mm.setdefault(schedule, []).append(_per_object_mm(metrics))
    return Result(**{**result.__dict__, "seconds": time.perf_counter() - clock})


def surface_losses(settings: Settings) -> tuple[object, SurfaceLosses]:
    """The settings' scene and the :class:`SurfaceLosses` of any surface against its simulated
    data (every material and the radar's gain known), rendered as the settings' fits render."""
    scene = load_scene(settings.scene)
    radar = small_radar() if settings.radar == "small" else load_radar(settings.radar)
    device = resolve_device(settings.device, "device")
    known = TrueMaterials(scene)
    problem = Problem(simulate(scene, radar, seed=settings.seed, device=device),
                      Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m), gain=SIMULATED_GAIN,
                      known_materials=known)
    config = ReconConfig.model_validate({"render": {"element_step": settings.element_step},
                                         "train": {"device": str(device)}})
    return scene, SurfaceLosses(problem, config, known)


def _per_object_mm(metrics) -> dict[str, float]:
    """Each object's Chamfer-L1 [mm] (None where no fitted surface lies nearest to it)."""
    return {name: value.chamfer_l1_mm for name, value in metrics.objects.items()}


def regressed_field(problem: Problem, config: ReconConfig, target_sdf, near_m: torch.Tensor, *, steps: int,
                    seed: int = 0) -> RadarField:
    """The field a fit of ``config`` starts from (its initialisation), regressed onto
    ``target_sdf`` (points (N, 3) -> (N,) [m]) by ``steps`` of the warm start's regression,
    half of each batch within a voxel of ``near_m`` (M, 3) [m], points near the target's zero set."""
    field = initial_field(problem.grid, config, resolve_device(config.train.device, "train.device"))
    voxel = float(np.max(problem.grid.voxel_m))
    fit_to_image(field, problem.grid.lower_m, problem.grid.upper_m, target_sdf, None, steps=steps, lr=1e-3, batch=8192,
                 eikonal_weight=0.01, generator=torch.Generator().manual_seed(seed), near_m=near_m.cpu(),
                 near_share=0.5, near_jitter_m=voxel)
    return field


@dataclass(frozen=True)
class FixedSurface:
    """A given surface (not a field being fitted) as the renderer asks for one: its SDF, and the
    classes of its materials."""

    sdf: object
    materials: tuple[str, ...] = MATERIAL_CLASSES


class SurfaceLosses:
    """Each data loss (amplitude, complex, split) of a surface f against the data, every view,
    at the voxels where some view's image is above 2 % of its peak: rendered with the true
    materials and the radar's gain, as the fits are."""

    def __init__(self, problem: Problem, config: ReconConfig, known: TrueMaterials):
        rc = config.render
        self.renderer = CoherentRenderer(problem.measurements, problem.grid, element_step=rc.element_step,
                                         surface=rc.surface, device=config.train.device, bands=2)
        self.known, self.gain = known, problem.gain
        amplitude = self.renderer.observed.abs()
        self.voxels = (amplitude > 0.02).any(0).nonzero().squeeze(1)

    def __call__(self, sdf, *, per_voxel: bool = False, reading=None) -> dict[str, float] | dict[str, torch.Tensor]:
        """Each loss of the surface ``sdf``; ``per_voxel``: each shown voxel's share of it, (X,)
        over ``self.voxels`` (the data losses' ``per_voxel``). ``reading``: each facet's true class
        index (N,) -> the class probabilities (N, len(MATERIAL_CLASSES)) it reflects with, as a
        fit's material head might read it; None: each facet its own class."""
        renderer = self.renderer
        with torch.no_grad():
            renderer.refresh(sdf, torch.Generator().manual_seed(0))
            classes = self.known(renderer.candidates.anchors)
            probabilities = (torch.nn.functional.one_hot(classes, len(MATERIAL_CLASSES)).float() if reading is None
                             else reading(classes))
            halves = renderer(FixedSurface(sdf), torch.arange(renderer.num_views), self.voxels, geometry=False,
                              probabilities=probabilities, bands=True) * (self.gain / renderer.observed_peak)
        images = {True: halves, False: renderer.full_band(halves)}  # one rendering for every loss
        observed = {False: renderer.observed[:, self.voxels], True: renderer.band_observed[:, :, self.voxels]}
        losses = {name: DATA_LOSSES.get(name)(images[name == "split"], observed[name == "split"], fit_gain=False,
                                              per_voxel=per_voxel)
                  for name in ("amplitude", "complex", "split")}
        return losses if per_voxel else {name: float(value) for name, value in losses.items()}


def plot(result: Result, path) -> None:
    fig, (ends, landscape, objects) = plt.subplots(1, 3, figsize=(15, 4.2), layout="constrained")
    errors = result.errors_mm
    ends.loglog(errors, result.start_observed_mm, "k--", marker="o", label="start")
    for schedule, values in result.end_observed_mm.items():
        ends.loglog(errors, values, marker="s", label=f"after {schedule}")
    ends.axhline(result.truth_observed_mm, color="grey", lw=0.8, label="the true surface, meshed")
    ends.set_xlabel("rms displacement of the start [mm]")
    ends.set_ylabel("observed-surface Chamfer-L1 [mm]")
    ends.set_title("where each loss ends")
    ends.legend(fontsize=8)
    for name, values in result.start_loss.items():
        line, = landscape.semilogx(errors, values, marker="o", label=name)
        landscape.axhline(result.truth_loss[name], color=line.get_color(), lw=0.8, ls=":")
    landscape.set_xlabel("rms displacement [mm]")
    landscape.set_ylabel("relative data loss (dotted: at the truth)")
    landscape.set_title("each loss at the starts")
    landscape.legend(fontsize=8)
    schedule = next(iter(result.end_objects_mm), None)
    for name in result.start_objects_mm[0] if schedule else ():
        ratio = [end[name] / start[name] if end[name] and start[name] else np.nan
                 for start, end in zip(result.start_objects_mm, result.end_objects_mm[schedule])]
        objects.semilogx(errors, ratio, marker="o", label=name)
    objects.axhline(1.0, color="grey", lw=0.8)
    objects.set_xlabel("rms displacement of the start [mm]")
    objects.set_ylabel(f"each object's Chamfer, end / start ({schedule})")
    objects.set_title("which objects the fit pulls")
    objects.legend(fontsize=8)
    save_figure(fig, path)
