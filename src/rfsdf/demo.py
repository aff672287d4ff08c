"""The whole pipeline on one scene: simulate, image, reconstruct (GeRaF), mesh, evaluate
against the truth and against the MF-threshold baseline, and picture every stage.

``run_demo`` writes into one folder:

    measurements.h5, image.h5          the data and its matched-filter image
    scene-slices.png, image-mip.png    the true SDF; MF power projections
    run/                               the fit: checkpoint.pt, log.csv, config.toml
    neural.ply, baseline.ply           the two reconstructions
    recon-slices.png, training.png     neural SDF against the truth; loss and sigma curves
    metrics.json                       metrics of both, the baseline sweep, stage timings

A demo run folder is resumable: run again with the same settings and the fit continues
from its last checkpoint (a finished fit is reused).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import torch

from .atomic import atomic_path
from .baseline import best_threshold_mesh
from .geometry import Grid
from .mesh import export_mesh, extract_mesh
from .metrics import evaluate_mesh, with_scene_iou
from .radar import check_radar_for_scene, load_radar, matched_filter, simulate, write_image, write_measurements
from .recon import Problem, ReconConfig, Trainer
from .scene import load_scene
from .viz import plot_mip, plot_sdf_slices, plot_training_curves

__all__ = ["DemoSettings", "QUICK", "run_demo", "metrics_table"]


@dataclass(frozen=True)
class DemoSettings:
    """What the demo runs: the default is the README's demo; ``QUICK`` is a seconds-long smoke run."""

    scene: str = "objects"
    radar: str = "near-77g"
    voxel_m: float = 0.006
    seed: int = 0
    max_surface_samples: int = 150_000  # of the simulator
    recon: dict = field(default_factory=dict)  # ReconConfig overrides (nested tables)
    mesh_resolution: int = 128
    metric_samples: int = 50_000


QUICK = DemoSettings(
    voxel_m=0.015, max_surface_samples=20_000, mesh_resolution=40, metric_samples=5_000,
    recon={"field": {"width": 48, "depth": 4},
           "init": {"steps": 40, "batch": 2048},
           "sampling": {"data_batch": 2048, "eikonal_batch": 512, "views_per_step": 2},
           "train": {"steps": 6, "checkpoint_every": 3}},
)


def run_demo(out, settings: DemoSettings = DemoSettings(), *, log: Callable[[str], None] = print,
             progress: bool = True) -> dict:
    """Run the pipeline into folder ``out``; returns (and writes as metrics.json) the results."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[stage] = round(now - clock, 2)
        clock = now

    scene, radar = load_scene(settings.scene), load_radar(settings.radar)
    check_radar_for_scene(radar, scene.lower_m, scene.upper_m, source=settings.radar)
    log(scene.summary())
    log(radar.summary())
    plot_sdf_slices(scene.sdf, scene.lower_m, scene.upper_m, out / "scene-slices.png",
                    title=f"scene {scene.name!r}: SDF slices")
    measurements = simulate(scene, radar, seed=settings.seed, max_samples=settings.max_surface_samples,
                            progress=progress)
    write_measurements(out / "measurements.h5", measurements)
    lap("simulate_s")

    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    log(f"matched filter on {grid.shape} voxels of {settings.voxel_m * 1e3:.1f} mm")
    image = matched_filter(measurements, grid, progress=progress)
    write_image(out / "image.h5", image)
    power = image.power().numpy()
    plot_mip(power, grid.lower_m, grid.upper_m, out / "image-mip.png", title="matched-filter power (mean over views)")
    lap("image_s")

    config = ReconConfig.model_validate(settings.recon)
    log(f"GeRaF fit: {config.render.renderer} renderer, {config.init.steps} warm-start + {config.train.steps} steps")
    trainer = Trainer(Problem.from_image(image, measurements.acquisition), config, out / "run", progress=progress)
    neural_field = trainer.fit(resume=True)
    lap("fit_s")

    neural = extract_mesh(neural_field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution)
    export_mesh(neural, out / "neural.ply")
    neural_metrics = evaluate_mesh(neural, scene, samples=settings.metric_samples, seed=settings.seed)
    lap("mesh_and_evaluate_s")
    baseline = best_threshold_mesh(power, grid, scene.ground_truth_mesh(), samples=settings.metric_samples,
                                   seed=settings.seed)
    export_mesh(baseline.mesh, out / "baseline.ply")
    baseline_metrics = with_scene_iou(baseline.metrics, baseline.mesh, scene, seed=settings.seed)
    lap("baseline_s")

    plot_sdf_slices(neural_field.sdf, scene.lower_m, scene.upper_m, out / "recon-slices.png", reference=scene.sdf,
                    title="neural SDF (black) against the true surfaces (dashed)")
    plot_training_curves(trainer.log, out / "training.png", title=f"GeRaF fit ({config.render.renderer} renderer)")
    lap("figures_s")

    result = {
        "scene": scene.name, "radar": radar.name, "grid": list(grid.shape), "voxel_mm": settings.voxel_m * 1e3,
        "renderer": config.render.renderer, "threads": torch.get_num_threads(),
        "neural": neural_metrics.as_dict(),
        "baseline": {**baseline_metrics.as_dict(), "fraction": baseline.fraction,
                     "sweep_chamfer_mm": {str(k): v for k, v in baseline.sweep.items()}},
        "timings_s": {**timings, "total_s": round(sum(timings.values()), 2)},
    }
    with atomic_path(out / "metrics.json") as tmp:
        tmp.write_text(json.dumps(result, indent=2))
    return result


def metrics_table(result: dict) -> str:
    """The neural and baseline metrics side by side, as aligned text."""
    rows = [("Chamfer-L1 [mm]", "chamfer_l1_mm", ".2f"), ("F-score @ 5 mm", "fscore", ".3f"),
            ("precision", "precision", ".3f"), ("recall", "recall", ".3f"),
            ("normal consistency", "normal_consistency", ".3f"), ("Hausdorff-95 [mm]", "hausdorff95_mm", ".1f"),
            ("volumetric IoU", "iou", ".3f")]
    baseline_name = f"MF threshold ({result['baseline']['fraction']:g} of peak)"
    lines = [f"{'':<20}{'GeRaF (neural)':>18}{baseline_name:>30}"]
    for label, key, fmt in rows:
        cells = [result[name][key] for name in ("neural", "baseline")]
        lines.append(f"{label:<20}" + "".join(f"{'-' if c is None else format(c, fmt):>{w}}"
                                              for c, w in zip(cells, (18, 30))))
    return "\n".join(lines)
