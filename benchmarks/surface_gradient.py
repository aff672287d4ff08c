"""Does the fit's own gradient move a surface where the data say? The basin study's quick
set-up (the 2 cm metal ball, the tests' six-view toy radar, a 32 x 4 field regressed onto
the true surface displaced by smooth errors) or its full one (``--size full``: the demo's
scene and radar, its 128 x 6 field), the materials and the radar's gain known so that
only f is free, fitted with each variant of the renderer, sampling and optimiser settings. Measured per
start and variant: the observed-surface Chamfer-L1 before and after, f's mean and rms at
points of the seen true surface (mean > 0: the surface shrank), and each data loss over all
views and voxels (the basin study's) at the start, at the end and at the true surface.

Usage: python benchmarks/surface_gradient.py [--size quick|full] [--errors-mm 0,1,4]
       [--variants '[{"smoothing_m": 0.006, "steps": 30}, ...]'] [--out FILE]
       [--cache DIR]   (each start's regressed field kept there and read back by a later run)
A variant's keys: lr, lr_end, steps, refresh_every, smoothing_m, data (a data loss),
views_per_step, data_batch (the data voxels a step; default the size's), knot_m (f moved
only by a coarse displacement on knots this far apart [m]).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from functools import partial
from pathlib import Path

import torch

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene, surface_offset_mm
from rfsdf.radar import load_radar, simulate
from rfsdf.radar.coverage import observed_mask
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.trainer import initial_field
from rfsdf.scene import load_scene
from rfsdf.studies import basin

VARIANTS = [
    {"lr": 1e-4, "lr_end": 1e-5, "steps": 30, "refresh_every": 1, "smoothing_m": 0.006},
    {"lr": 1e-4, "lr_end": 1e-5, "steps": 40, "refresh_every": 10, "smoothing_m": 0.0},
    {"lr": 3e-4, "lr_end": 3e-5, "steps": 100, "refresh_every": 1, "smoothing_m": 0.006},
    {"lr": 3e-4, "lr_end": 3e-5, "steps": 100, "refresh_every": 1, "smoothing_m": 0.0},
    {"lr": 3e-4, "lr_end": 3e-5, "steps": 100, "refresh_every": 1, "smoothing_m": 0.0, "data": "complex"},
]


def config(settings: basin.Settings, lr=1e-4, lr_end=1e-5, steps=30, refresh_every=10, smoothing_m=0.0,
           data="amplitude", views_per_step=None, data_batch=None, knot_m=None) -> ReconConfig:
    return ReconConfig.model_validate({
        "field": {"width": settings.width, "depth": settings.depth, "displacement_knot_m": knot_m},
        "render": {"element_step": settings.element_step, "refresh_every": refresh_every, "smoothing_m": smoothing_m},
        "loss": {"data": data},
        "sampling": {"data_batch": data_batch or settings.data_batch,
                     "views_per_step": views_per_step or settings.views_per_step},
        "train": {"steps": steps, "checkpoint_every": steps, "geometry_delay": 0.0, "lr": lr, "lr_end": lr_end,
                  "device": "cpu"}})


def _start(cache: Path | None, name: str, problem: Problem, settings: ReconConfig, regress):
    """``regress()``'s field, or the one an earlier run kept in ``cache/name.pt``."""
    path = None if cache is None else cache / f"{name}.pt"
    if path is None or not path.exists():
        field = regress()
        if path is not None:
            cache.mkdir(parents=True, exist_ok=True)
            torch.save(field.state_dict(), path)
        return field
    field = initial_field(problem.grid, settings, torch.device(settings.train.device))
    field.load_state_dict(torch.load(path))
    return field


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--errors-mm", default="0,1,4")
    parser.add_argument("--variants", type=json.loads, default=VARIANTS)
    parser.add_argument("--size", choices=("quick", "full"), default="quick")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--cache", type=Path, help="keep each start's regressed field here for a later run")
    args = parser.parse_args()
    settings = basin.QUICK if args.size == "quick" else basin.Settings(device="cpu")
    out = args.out or Path("benchmarks/results") / (
        "surface-gradient.json" if args.size == "quick" else "surface-gradient-demo.json")
    scene = load_scene(settings.scene)
    radar = basin.small_radar() if settings.radar == "small" else load_radar(settings.radar)
    data = simulate(scene, radar, seed=settings.seed)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    known = basin.TrueMaterials(scene)
    problem = Problem(data, grid, gain=SIMULATED_GAIN, known_materials=known)
    score = partial(evaluate_scene, scene=scene, samples=max(20_000, settings.metric_samples), seed=settings.seed,
                    observed=partial(observed_mask, acquisition=data.acquisition, occluder=scene.sdf))
    resolution = max(64, settings.mesh_resolution)
    chamfer = lambda sdf: score(extract_mesh(sdf, scene.lower_m, scene.upper_m, resolution)).observed.chamfer_l1_mm  # noqa: E731
    losses = basin.SurfaceLosses(problem, config(settings), known)
    samples = scene.sample_surface(0.001, seed=1, max_samples=50_000)
    seen = samples.points[observed_mask(samples.points, samples.normals, data.acquisition, scene.sdf)].float()

    def offset(sdf) -> dict[str, float]:
        mean, rms = surface_offset_mm(sdf, seen)
        return {"mean_mm": mean, "rms_mm": rms}

    displacement = basin.smooth_displacement(scene, settings.correlation_m, torch.Generator().manual_seed(0))
    near = scene.sample_surface(settings.voxel_m / 2, seed=0, max_samples=50_000).points
    rows = []
    for error_mm in (float(e) for e in args.errors_mm.split(",")):
        target = lambda p, e=error_mm * 1e-3: scene.sdf(p) - e * displacement(p)  # noqa: E731
        start = _start(args.cache, f"{args.size}-{error_mm:g}mm", problem, config(settings), partial(
            basin.regressed_field, problem, config(settings), target, near, steps=settings.regress_steps))
        before = {"observed_chamfer_mm": chamfer(start.sdf), **offset(start.sdf), "loss": losses(start.sdf)}
        for variant in args.variants:
            clock = time.perf_counter()
            variant_config = config(settings, **variant)
            begin = initial_field(grid, variant_config, torch.device("cpu"))  # the start, with a zero displacement if any
            begin.load_state_dict(start.state_dict(), strict=False)
            with tempfile.TemporaryDirectory() as folder:
                fit = Trainer(problem, variant_config, folder, start=begin.state_dict()).fit()
            after = {"observed_chamfer_mm": chamfer(fit.field.sdf), **offset(fit.field.sdf),
                     "loss": losses(fit.field.sdf)}
            rows.append({"error_mm": error_mm, "variant": variant, "before": before, "after": after,
                         "seconds": time.perf_counter() - clock})
            print(to_json(rows[-1], indent=None), flush=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"size": args.size, "truth_loss": losses(scene.sdf), "rows": rows}))


if __name__ == "__main__":
    main()
