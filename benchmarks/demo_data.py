"""The default demo's data, as the benchmarks that analyse it need them: the scene, its
simulated measurements (the demo's seed) and their matched-filter image on the demo grid;
and the demo's warm start on them."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass

from rfsdf.demo import DemoSettings, with_calibration
from rfsdf.geometry import Grid
from rfsdf.material_estimates import scene_reference
from rfsdf.radar import Image, Measurements, load_radar, matched_filter, simulate
from rfsdf.radar.clean import clean_image
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.scene import Scene, load_scene


@dataclass(frozen=True)
class DemoData:
    settings: DemoSettings
    scene: Scene
    measurements: Measurements
    image: Image


def demo_data(settings: DemoSettings | None = None, device=None) -> DemoData:
    """Simulate and image the demo scene exactly as ``rfsdf demo`` does (about 40 s on 2 cores);
    ``settings`` None: the demo's defaults; ``device`` where the simulator and the matched
    filter run (None: the CPU, as the demo's default on a machine without a GPU)."""
    settings = settings or DemoSettings()
    scene = load_scene(settings.scene)
    measurements = simulate(scene, load_radar(settings.radar), seed=settings.seed,
                            max_samples=settings.max_surface_samples,
                            samples_per_wavelength=settings.samples_per_wavelength,
                            stratified=settings.stratified_samples, surface=settings.surface, device=device)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    return DemoData(settings, scene, measurements, matched_filter(measurements, grid, device=device))


def calibrated_problem(data: DemoData, config: ReconConfig, clean, *, gain: float | None = None):
    """The fit's :class:`Problem` on ``data`` with its ``clean`` image (and a known ``gain``), the
    materials of ``config``'s calibration reference known where it names one; and that reference
    (None without one)."""
    reference = (None if config.calibration.reference is None
                 else scene_reference(data.scene, config.calibration, data.measurements.acquisition))
    problem = Problem(data.measurements, data.image.grid, clean=clean, image=data.image, gain=gain,
                      known_materials=None if reference is None else reference.labels(tuple(config.field.materials)))
    return problem, reference


def demo_warm_start(data: DemoData, seed: int = 0) -> tuple[Trainer, ReconConfig]:
    """The warm start as ``rfsdf demo`` builds it on ``data`` (the default reconstruction, calibrated
    by the scene's reference where it names one; ``seed`` the fit's, ``[train] seed``): the trainer
    after it (its ``field`` and range ``peaks``; its run folder gone) and the config."""
    scene, grid = data.scene, data.image.grid
    config = with_calibration(ReconConfig.model_validate({"train": {"seed": seed}}), scene, data.settings)
    reference = (None if config.calibration.reference is None
                 else scene_reference(scene, config.calibration, data.measurements.acquisition))
    problem = Problem(data.measurements, grid, clean=clean_image(data.measurements, grid),
                      known_materials=None if reference is None else reference.labels(tuple(config.field.materials)))
    with tempfile.TemporaryDirectory() as run:
        trainer = Trainer(problem, config, run)
        trainer.warm_start()
    return trainer, config
