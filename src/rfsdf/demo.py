"""The whole pipeline on one scene: simulate, image, reconstruct (GeRaF), mesh, evaluate
against the truth and against the baselines, and picture every stage.

``run_demo`` writes into one folder:

    demo-settings.json                 the settings this folder holds a run of
    measurements.h5, image.h5          the data and its matched-filter image
    scene-slices.png, image-mip.png    the true SDF; MF power projections
    clean-mip.png                      CLEAN power projections (the warm start's image,
                                       unless it starts on the matched filter, as ``SCANNED``)
    run/                               the fit: checkpoint.pt, log.csv, config.toml
    neural.ply, neural-warm-start.ply  the GeRaF reconstruction, and its field before the fit
    mf-threshold.ply, clean-threshold.ply, clean-detection.ply    the baselines (with a
                                       matched-filter warm start also its mf-detection.ply)
    recon-slices.png, training.png     neural SDF against the truth; loss curves
    metrics.json                       metrics of every method (full, observed surface,
                                       per object), the baselines' sweeps, stage timings

(`rfsdf demo` then writes ``report.html`` and ``object-slices.png`` with :mod:`rfsdf.report`.)

A demo run folder is resumable: run again with the same settings and the simulated data
are read back, the fit continues from its last checkpoint (a finished fit is reused);
other settings are refused before anything is written.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from .baseline import best_threshold_mesh, detection_mesh
from .config import validate
from .device import resolve_device
from .errors import RfsdfError
from .geometry import Grid
from .jsonio import to_json, write_json
from .material_estimates import (
    MaterialReport, fit_materials, materials_table, paint_mesh, scene_reference,
)
from .mesh import export_mesh, extract_mesh
from .metrics import SceneMetrics, evaluate_scene, once_per_samples
from .radar import (
    Measurements, Radar, check_materials_in_band, check_radar_for_scene, load_radar, matched_filter,
    read_measurements, simulate, write_image, write_measurements,
)
from .radar.clean import MAX_COMPONENTS, clean_image
from .radar.coverage import observed_mask
from .radar.imaging import require_image_memory
from .radar.scan_imaging import lattice_grid
from .radar.simulate import SAMPLES_PER_WAVELENGTH
from .recon import Problem, ReconConfig, Trainer
from .recon.calibration import check_reference
from .recon.warm_start import detection_threshold, excluded_voxels
from .scene import Scene, load_scene
from .viz import plot_mip, plot_sdf_slices, plot_training_curves

__all__ = ["DemoSettings", "QUICK", "SCANNED", "demo_settings", "demo_grid", "SceneAndRadar", "load_scene_and_radar",
           "claim_folder", "require_demo_images", "MethodResult", "DemoResult", "SETTINGS_NAME", "SIMULATION_CHECKPOINT", "simulated_in", "run_demo", "metrics_rows", "metrics_table"]

SIMULATION_CHECKPOINT = "simulation.partial.pt"
"""The views a demo's simulation has done, where it traces them one by one; gone once its
measurements.h5 is written (a rerun of the same --out continues from it)."""


@dataclass(frozen=True)
class DemoSettings:
    """What the demo runs: the default is the README's demo; ``QUICK`` is a seconds-long smoke
    run; ``SCANNED`` the demo of a radar whose views are raster scans (preset ``sar-77g``)."""

    scene: str = "objects"
    radar: str = "near-77g"
    voxel_m: float = 0.006
    seed: int = 0
    max_surface_samples: int = 150_000  # of the simulator
    samples_per_wavelength: float = SAMPLES_PER_WAVELENGTH  # of the simulator's surface
    surface: str = "facets"  # the simulator's surface: facets of the zero set (converged) or points
    stratified_samples: bool = True  # the simulator's points (surface "points") one per stratum of equal area
    recon: dict = field(default_factory=dict)  # ReconConfig overrides (nested tables)
    # a known radar gain the materials are read in after the relative fit (absolute |Gamma|, the
    # config's calibration.gain): SIMULATED_GAIN for this simulator's data, or a separate
    # capture's (rfsdf calibrate); None: the scene's calibration_reference where it names one
    gain: float | None = None
    # leave out the scene's calibration_reference (one gain fitted per step, relative materials)
    relative: bool = False
    mesh_resolution: int = 128
    metric_samples: int = 50_000
    clean_components: int = MAX_COMPONENTS  # CLEAN's most components per view


QUICK = DemoSettings(
    # points lambda/1.5 apart (16,000 on the default scene): coarse on purpose, it is a smoke test;
    # 1,000 metric samples (each a query of the true surface's mesh; blurred thresholds put them far
    # from it, where queries cost most: the tests' toy-radar sphere job 12.5 s, 16 s at 2,000)
    voxel_m=0.015, max_surface_samples=20_000, samples_per_wavelength=1.5, mesh_resolution=40, metric_samples=1_000,
    # a sixth of CLEAN's time; its residual floor (the detection threshold) higher than 0.05
    clean_components=50,
    # without the primitives (their fits took 36 s of the quick demo's 73 on 2 cores)
    recon={"field": {"width": 48, "depth": 4},
           "init": {"steps": 40, "batch": 2048, "primitives": False},
           "render": {"element_step": 4, "spacing_m": 0.004, "refresh_every": 3},
           "sampling": {"data_batch": 1024, "eikonal_batch": 512, "views_per_step": 2},
           "train": {"steps": 6, "checkpoint_every": 3}},
)


# GeRaF's acquisition (preset sar-77g: an IWR1443 over a 33 x 33 raster at four turntable
# angles) on hand-sized objects: each scan imaged by FFT on its raster's lattice (voxels of
# its 3 mm step); the warm start on that matched filter (on CLEAN's it scored 5.4-5.7 mm
# against 4.9: docs/guide/radar.md, "Scanned views"), its range peaks each on the
# sub-aperture before it; the fit on every 16th frame and every
# 8th frequency (68 frames a scan, 8 frequencies over the same band: the same scores as
# every 4th's, in 0.55x the step; docs/guide/radar.md, "The demo on scans"); without the
# primitives, which were measured on the demo's views and not yet on scans
SCANNED = DemoSettings(
    scene="handheld", radar="sar-77g", voxel_m=0.003,
    recon={"init": {"method": "mf", "threshold": 0.1, "primitives": False},
           "render": {"element_step": 4, "frequency_step": 8},
           "train": {"steps": 40, "material_lr_scale": 100}},
)


def demo_settings(radar_name: str, *, quick: bool = False) -> DemoSettings:
    """The demo's settings for the radar ``radar_name`` (a preset or file): ``SCANNED``'s where
    its views are raster scans, else the default (``QUICK`` with ``quick``; a scanned radar has
    no quick run: its scans are what take the time)."""
    if load_radar(radar_name).acquisition().scans is not None:
        if quick:
            raise RfsdfError(f"{radar_name}: a radar whose views are scans has no --quick demo")
        return dataclasses.replace(SCANNED, radar=radar_name)
    return dataclasses.replace(QUICK if quick else DemoSettings(), radar=radar_name)


def demo_grid(lower_m, upper_m, acquisition, voxel_m: float) -> Grid:
    """The demo's image grid over the box [lower_m, upper_m]: voxels of ``voxel_m`` [m], or
    where the views are planar raster scans, voxels of their step on their lattice (imaged by
    FFT, :func:`~rfsdf.radar.scan_imaging.lattice_grid`)."""
    if acquisition.scans is not None:
        try:
            return lattice_grid(acquisition, lower_m, upper_m)
        except ValueError:  # scans that are no raster: back-projection on the plain grid
            pass
    return Grid.from_voxel(lower_m, upper_m, voxel_m)


@dataclass(frozen=True)
class MethodResult:
    """One reconstruction method's mesh scores; ``details`` says how it was chosen (e.g. the
    threshold sweep of a baseline)."""

    label: str
    metrics: SceneMetrics
    details: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"label": self.label, **self.metrics.as_dict(), **self.details}


@dataclass(frozen=True)
class DemoResult:
    """Everything the demo measured (written as metrics.json)."""

    scene: str
    radar: str
    grid: tuple[int, int, int]
    voxel_mm: float
    threads: int
    fit_steps: int
    seconds_per_step: float
    methods: dict[str, MethodResult]
    timings_s: dict[str, float]
    materials: MaterialReport | None = None  # the GeRaF fit's, when it has a material head

    def as_dict(self) -> dict:
        return {"scene": self.scene, "radar": self.radar, "grid": list(self.grid), "voxel_mm": self.voxel_mm,
                "threads": self.threads, "fit_steps": self.fit_steps, "seconds_per_step": self.seconds_per_step,
                "methods": {name: m.as_dict() for name, m in self.methods.items()}, "timings_s": self.timings_s,
                "materials": None if self.materials is None else self.materials.as_dict()}


SETTINGS_NAME = "demo-settings.json"


def claim_folder(out: Path, settings) -> None:
    """Make ``out`` the folder of a demo of ``settings`` (a dataclass), or refuse before
    writing anything: a folder holding a demo of other settings (or files of an unknown run)
    would end up mixing two runs. A setting the folder's stamp lacks (one added since) counts
    as its default."""
    stamp, wanted = out / SETTINGS_NAME, json.loads(to_json(dataclasses.asdict(settings)))
    if stamp.exists():
        try:
            held = json.loads(stamp.read_text())
        except (OSError, ValueError):
            held = None
        if isinstance(held, dict):
            held = {**{f.name: f.default for f in dataclasses.fields(settings) if f.name not in held
                       and isinstance(f.default, (bool, int, float, str, type(None)))}, **held}
        if held != wanted:
            changed = ", ".join(f"{k}: {held.get(k)!r} -> {v!r}" for k, v in wanted.items()
                                if held.get(k) != v) if isinstance(held, dict) else "unreadable settings"
            raise RfsdfError(f"{out}: holds a demo of other settings ({changed}); choose another --out")
    elif any((out / name).exists() for name in ("measurements.h5", "image.h5", "run", SIMULATION_CHECKPOINT)):
        raise RfsdfError(f"{out}: holds files of another run; choose another --out")
    write_json(stamp, wanted)


def simulated_in(out: Path, simulation: Callable[..., Measurements]) -> Measurements:
    """``simulation(checkpoint=...)``'s measurements written to ``out``/measurements.h5, the
    views it kept in ``out``/:data:`SIMULATION_CHECKPOINT` (a rerun continues from them)
    removed once they are."""
    measurements = simulation(checkpoint=out / SIMULATION_CHECKPOINT)
    write_measurements(out / "measurements.h5", measurements)
    (out / SIMULATION_CHECKPOINT).unlink(missing_ok=True)
    return measurements


@dataclass(frozen=True)
class SceneAndRadar:
    """A scene and the radar that images it, loaded and checked against each other."""

    scene: Scene
    radar: Radar


def load_scene_and_radar(scene_name: str, radar_name: str) -> SceneAndRadar:
    """The scene and the radar that settings name (presets or files), refused in one line
    before any work when the radar cannot image the scene's box or a material has no model
    in its band."""
    radar = load_radar(radar_name)
    scene = load_scene(scene_name).around_radar(radar.positions_m)
    check_radar_for_scene(radar, scene.lower_m, scene.upper_m, source=radar_name)
    check_materials_in_band(scene, radar, source=scene_name)
    return SceneAndRadar(scene, radar)


def require_demo_images(inputs: SceneAndRadar, settings: DemoSettings) -> None:
    """RfsdfError, before any work, when the demo's images of the scene do not fit in
    memory (a room's box at the demo's voxel is billions of voxels)."""
    grid = Grid.from_voxel(inputs.scene.lower_m, inputs.scene.upper_m, settings.voxel_m)
    try:
        require_image_memory(len(inputs.radar.positions_m), grid, f"the demo's images of {settings.scene}")
    except RfsdfError as exc:
        raise RfsdfError(f"{exc}; the GeRaF demo reconstructs scenes of objects about a metre across; for a room, "
                         "--model primitive, hybrid or all") from None


def with_calibration(config: ReconConfig, scene: Scene, settings: DemoSettings) -> ReconConfig:
    """``config`` calibrated as the settings ask: in their known ``gain`` (given after the relative
    fit), else by the scene's ``calibration_reference`` (rendered as its own material) unless
    the settings ask for relative materials; as it is when it has a calibration already or no
    material head."""
    name = scene.spec.calibration_reference
    calibration = config.calibration
    if calibration.reference is not None or calibration.gain is not None or not config.field.materials:
        return config
    merged = config.model_dump()
    if settings.gain is not None:
        merged["calibration"]["gain"] = settings.gain
    elif name is not None and not settings.relative:
        material = next(o.material.name for o in scene.objects if o.name == name)
        merged["calibration"]["reference"] = f"{name}={material}"
    else:
        return config
    return validate(ReconConfig, merged, f"{settings.scene}: calibration")


def run_demo(out, settings: DemoSettings | None = None, *, device: str = "auto",
             log: Callable[[str], None] = print, progress: bool = True,
             measurements: Measurements | None = None) -> DemoResult:
    """Run the pipeline into folder ``out`` with ``settings`` (None: the demo's defaults);
    returns (and writes as metrics.json) the results. ``measurements``: data of the scene
    and radar to use instead of simulating them (the model demo's, so every model sees the
    same data).

    ``device`` (auto, cpu, cuda) runs every stage there, the fit included (it overrides the
    settings' ``train.device``); it is not a setting of the run: a demo resumes on any device.
    """
    out = Path(out)
    settings = settings or DemoSettings()
    device = resolve_device(device)
    inputs = load_scene_and_radar(settings.scene, settings.radar)
    scene, radar = inputs.scene, inputs.radar
    require_demo_images(inputs, settings)
    config = with_calibration(validate(ReconConfig, settings.recon, "recon"), scene, settings).on_device(device)
    claim_folder(out, settings)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[stage] = round(now - clock, 2)
        clock = now

    log(scene.summary())
    log(radar.summary())
    plot_sdf_slices(scene.sdf, scene.lower_m, scene.upper_m, out / "scene-slices.png",
                    title=f"scene {scene.name!r}: SDF slices")
    if (out / "measurements.h5").exists():  # written atomically by a run of these settings (claim_folder)
        measurements = read_measurements(out / "measurements.h5")
    elif measurements is not None:
        write_measurements(out / "measurements.h5", measurements)
    else:
        measurements = simulated_in(out, partial(simulate, scene, radar, seed=settings.seed,
                                                 max_samples=settings.max_surface_samples,
                                                 samples_per_wavelength=settings.samples_per_wavelength,
                                                 stratified=settings.stratified_samples, surface=settings.surface,
                                                 device=device, progress=progress))
    lap("simulate_s")

    grid = demo_grid(scene.lower_m, scene.upper_m, measurements.acquisition, settings.voxel_m)
    voxel_mm = float(np.max(grid.voxel_m)) * 1e3
    log(f"matched filter on {grid.shape} voxels of {voxel_mm:.1f} mm ({device})")
    image = matched_filter(measurements, grid, device=device, progress=progress)
    write_image(out / "image.h5", image)
    mf_power = image.power().numpy()
    plot_mip(mf_power, grid.lower_m, grid.upper_m, out / "image-mip.png", title="matched-filter power (mean over views)")
    lap("image_s")

    rc = config.render
    clean = clean_image(measurements, grid, device=device, progress=progress, max_components=settings.clean_components)
    log(f"CLEAN residual floor {clean.residual_floor():.3f} of the peak amplitude"
        f"{' (the detection threshold)' if config.init.threshold == 'auto' else ''}")
    plot_mip(clean.power.numpy(), grid.lower_m, grid.upper_m, out / "clean-mip.png",
             title="CLEAN power (mean over views)", quantity="CLEAN power")
    lap("clean_s")

    log(f"GeRaF fit: {rc.renderer} renderer, {config.init.method} warm start "
        f"({config.init.steps} steps) + {config.train.steps} steps")
    reference = None
    if config.calibration.reference is not None:
        reference = scene_reference(scene, config.calibration, measurements.acquisition)
    problem = Problem(measurements, grid, str(out / "measurements.h5"), clean=clean, image=image,
                      known_materials=None if reference is None else reference.labels(tuple(config.field.materials)))
    trainer = Trainer(problem, config, out / "run", progress=progress)
    fit = trainer.fit(resume=True)
    lap("fit_s")

    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=once_per_samples(partial(observed_mask, acquisition=measurements.acquisition,
                                                      occluder=scene.sdf)))
    neural = extract_mesh(fit.field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution, device=device)
    warm = extract_mesh(fit.warm_field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution, device=device)
    export_mesh(warm, out / "neural-warm-start.ply")
    methods = {"neural": MethodResult("GeRaF (neural)", score(neural)),
               "neural_warm_start": MethodResult("its warm start", score(warm))}
    lap("mesh_and_evaluate_s")
    materials = None
    if fit.field.material_head is not None:  # its mesh carries each vertex's material, as the table reads it
        calibration = None if reference is None else check_reference(trainer, reference)
        if calibration is not None and calibration.warning() is not None:
            log(f"warning: {calibration.warning()}")
        materials = fit_materials(trainer, neural, scene=scene, calibration=calibration, seed=settings.seed)
        lap("materials_s")
    export_mesh(neural if materials is None else
                paint_mesh(fit.field, neural, measurements.acquisition.center_frequency_hz, materials.head_scale),
                out / "neural.ply")

    reference = scene.ground_truth_mesh()
    # the baselines: each image's best global threshold, and the warm start's detection without the fit
    thresholded = [("mf_threshold", mf_power, "MF threshold"), ("clean_threshold", clean.power.numpy(), "CLEAN threshold")]
    for name, power, label in thresholded:
        best = best_threshold_mesh(power, grid, reference, samples=settings.metric_samples, seed=settings.seed)
        export_mesh(best.mesh, out / f"{name.replace('_', '-')}.ply")
        methods[name] = MethodResult(f"{label} ({best.fraction:g})", score(best.mesh),
                                     {"fraction": best.fraction,
                                      "sweep_chamfer_mm": {str(k): v for k, v in best.sweep.items()}})
    ic = config.init
    # CLEAN's detection at its own threshold (the residual floor unless the CLEAN warm start
    # names one); with a matched-filter warm start also that start's detection, without the fit
    detections = [("clean_detection", "CLEAN detection", clean.per_view_power.numpy(),
                   ic.threshold if ic.method == "clean" else "auto")]
    if ic.method == "mf":
        detections.append(("mf_detection", "MF detection", (image.per_view.abs() ** 2).numpy(), ic.threshold))
    for name, label, per_view, setting in detections:
        threshold = detection_threshold(setting, clean)
        exclude = excluded_voxels(ic, per_view, measurements.acquisition, grid, threshold)
        detected = detection_mesh(per_view.mean(0), grid, threshold=threshold, local_threshold=ic.local_threshold,
                                  window_m=ic.window_m, exclude=exclude)
        export_mesh(detected, out / f"{name.replace('_', '-')}.ply")
        methods[name] = MethodResult(label, score(detected),
                                     {"threshold": threshold, "threshold_setting": setting,
                                      "local_threshold": ic.local_threshold,
                                      "carve_front": ic.carve_front,
                                      "blank_range_sidelobes": ic.blank_range_sidelobes})
    lap("baselines_s")

    plot_sdf_slices(fit.field.cpu().sdf, scene.lower_m, scene.upper_m, out / "recon-slices.png", reference=scene.sdf,
                    title="neural SDF (black) against the true surfaces (dashed)")
    plot_training_curves([dataclasses.asdict(r) for r in fit.log], out / "training.png", title=f"GeRaF fit ({rc.renderer} renderer)")
    lap("figures_s")

    result = DemoResult(scene.name, radar.name, grid.shape, voxel_mm, torch.get_num_threads(),
                        len(fit.log), round(fit.seconds_per_step, 3), methods,
                        {**timings, "total_s": round(sum(timings.values()), 2)}, materials)
    write_json(out / "metrics.json", result.as_dict())
    return result


def _cell(value, fmt: str) -> str:
    return "-" if value is None or (isinstance(value, float) and not np.isfinite(value)) else format(value, fmt)


_ROWS = (("Chamfer-L1 [mm]", "full", "chamfer_l1_mm", ".2f"), ("F-score @ 5 mm", "full", "fscore", ".3f"),
         ("precision", "full", "precision", ".3f"), ("recall", "full", "recall", ".3f"),
         ("normal consistency", "full", "normal_consistency", ".3f"),
         ("Hausdorff-95 [mm]", "full", "hausdorff95_mm", ".1f"), ("volumetric IoU", "full", "iou", ".3f"),
         ("observed Chamfer [mm]", "observed", "chamfer_l1_mm", ".2f"), ("observed F-score", "observed", "fscore", ".3f"),
         ("accuracy near seen [mm]", None, "accuracy_near_observed_mm", ".2f"),
         ("accuracy near unseen [mm]", None, "accuracy_near_unobserved_mm", ".2f"),
         ("completeness of seen [mm]", None, "completeness_observed_mm", ".2f"),
         ("completeness of unseen [mm]", None, "completeness_unobserved_mm", ".2f"))


def metrics_rows(result: dict) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """The method labels and the rows (metric name, one formatted cell per method) of a
    result as written to metrics.json (``DemoResult.as_dict()``): full surface, observed
    surface, then the recall of each object by name."""
    methods = list(result["methods"].values())
    rows = [(label, [_cell((m if part is None else m.get(part) or {}).get(key), fmt) for m in methods])
            for label, part, key, fmt in _ROWS]
    rows += [(f"recall {name}", [_cell(m["objects"][name]["recall"], ".2f") for m in methods])
             for name in methods[0]["objects"]]
    return [m["label"] for m in methods], rows


def metrics_table(result: DemoResult) -> str:
    """Every method's metrics side by side (full surface, observed surface, per-object recall),
    then the materials when the fit has a head."""
    labels, rows = metrics_rows(result.as_dict())
    width = max(18, *(len(label) + 2 for label in labels))
    lines = [f"{'':<24}" + "".join(f"{label:>{width}}" for label in labels)]
    lines += [f"{name:<24}" + "".join(f"{cell:>{width}}" for cell in cells) for name, cells in rows]
    metrics = next(iter(result.methods.values())).metrics
    if metrics.observed_fraction is not None:
        lines.append(f"(observed surface: {metrics.observed_fraction:.0%} of the true surface is seen near specular "
                     "by some view; by object: " + ", ".join(f"{name} {m.observed_fraction:.0%}"
                                                             for name, m in metrics.objects.items()) + ")")
    if result.materials is not None:
        lines.append(materials_table(result.materials.as_dict()))
    return "\n".join(lines)
