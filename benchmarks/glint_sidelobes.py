"""The glints' sidelobes out of the warm start (`[init] glint_sidelobes`, rfsdf.radar.glint_sidelobes):
on a scene's simulated data (the demo's settings), the default fit from its warm start with the
rule and without it, on the same data and CLEAN image, for each seed. Per run: how many range
peaks the rule drops and how far they lie from the true surface (beyond 2 mm, within 1 mm),
the amplitude-weighted distance of the peaks kept, and the warm start's and the fit's
observed-surface and whole-surface Chamfer-L1 (distances to the surfaces) with each object's.

Usage: python benchmarks/glint_sidelobes.py [--scene objects] [--seeds 0,1,2] [--device cpu]
       [--out benchmarks/results/glint-sidelobes-SCENE.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
import torch
from demo_data import demo_data

from rfsdf.demo import DemoSettings, with_scene_reference
from rfsdf.device import resolve_device
from rfsdf.jsonio import to_json
from rfsdf.material_estimates import scene_reference
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.recon import Problem, ReconConfig, Trainer

VARIANTS = {"glint sidelobes out (the default)": {}, "kept": {"init": {"glint_sidelobes": False}}}


def _peak_distances(trainer: Trainer, scene) -> dict[str, float]:
    """How far the range peaks the fit holds lie from the true surface."""
    points, amplitude = (a.cpu().double() for a in trainer.peaks[:2])
    distance = scene.sdf(points).abs().numpy()
    return {"peaks": len(distance), "beyond_2mm": int((distance > 2e-3).sum()), "within_1mm": int((distance < 1e-3).sum()),
            "amplitude_weighted_mm": float(np.average(distance, weights=amplitude.numpy()) * 1e3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    device = resolve_device(args.device, "--device")
    out = args.out or Path(f"benchmarks/results/glint-sidelobes-{Path(args.scene).stem}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    settings = dataclasses.replace(DemoSettings(), scene=args.scene)
    clock = time.perf_counter()
    data = demo_data(settings, device)
    scene, grid = data.scene, data.image.grid
    clean = clean_image(data.measurements, grid, device=device, max_components=settings.clean_components)
    print(f"data and CLEAN {time.perf_counter() - clock:.0f} s", flush=True)
    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=partial(observed_mask, acquisition=data.measurements.acquisition, occluder=scene.sdf))

    def scores(field) -> dict:
        metrics = score(extract_mesh(field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution, device=device))
        return {"observed_mm": metrics.observed.chamfer_l1_mm, "whole_mm": metrics.full.chamfer_l1_mm,
                "objects_mm": {name: o.chamfer_l1_mm for name, o in metrics.objects.items()}}

    rows = []
    for seed in (int(s) for s in args.seeds.split(",")):
        for variant, overrides in VARIANTS.items():
            recon = {**settings.recon, **overrides, "train": {"seed": seed, "device": str(device)}}
            config = with_scene_reference(ReconConfig.model_validate(recon), scene, settings)
            reference = (None if config.calibration.reference is None
                         else scene_reference(scene, config.calibration, data.measurements.acquisition))
            problem = Problem(data.measurements, grid, clean=clean, image=data.image,
                              known_materials=None if reference is None else reference.labels(tuple(config.field.materials)))
            with tempfile.TemporaryDirectory() as folder:
                trainer = Trainer(problem, config, folder)
                clock = time.perf_counter()
                fit = trainer.fit()
                row = {"seed": seed, "variant": variant, "fit_s": round(time.perf_counter() - clock, 1),
                       **_peak_distances(trainer, scene), "warm_start": scores(fit.warm_field), "fit": scores(fit.field)}
            rows.append(row)
            print(to_json(row, indent=None), flush=True)
            out.write_text(to_json({"scene": settings.scene, "radar": settings.radar, "device": str(device),
                                    "threads": torch.get_num_threads(), "rows": rows}))


if __name__ == "__main__":
    main()
