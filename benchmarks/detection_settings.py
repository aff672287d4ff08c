"""What the warm start's target can score: the closed detection set of the demo's CLEAN image
(the surface f is regressed onto, `recon.warm_start.detection_target`), meshed and scored
for a grid of detection settings, with and without the voxels in front of each view's
range ridge (`[init] carve_front`, `radar.detection.in_front_of_ridges`) and the range
sidelobes (`[init] blank_range_sidelobes`, `radar.detection.on_range_sidelobes`), without
any fit. Per setting: full and observed-surface Chamfer, the accuracy near seen / unseen
true surface, objects found, the shares of the target's surface more than 5 mm outside and
inside the true objects (where the off surface lies), and its area more than 2 cm from any
object (floaters). About 7 minutes on 2 cores (CLEAN once).

Usage: python benchmarks/detection_settings.py [--out benchmarks/results/detection_settings.json]
"""

from __future__ import annotations

import argparse
import itertools
from functools import partial
from pathlib import Path

import numpy as np
import torch
import trimesh
from demo_data import demo_data

from rfsdf.jsonio import to_json
from rfsdf.mesh import mesh_from_volume
from rfsdf.metrics import evaluate_scene
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.recon import ReconConfig
from rfsdf.recon.warm_start import detection_target, excluded_voxels

LOCAL_THRESHOLDS = (0.5, 0.6, 0.7)
CLOSINGS_M = (0.0, 0.006, 0.012)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/detection_settings.json"))
    args = parser.parse_args()
    data = demo_data()
    scene, grid, settings, init = data.scene, data.image.grid, data.settings, ReconConfig().init
    clean = clean_image(data.measurements, grid)
    power, per_view = clean.power.numpy(), clean.per_view_power.numpy()
    observed = partial(observed_mask, acquisition=data.measurements.acquisition, occluder=scene.sdf)
    settings_grid = [(local, carve, blank, init.closing_m) for local, carve, blank
                     in itertools.product(LOCAL_THRESHOLDS, (False, True), (False, True))]
    settings_grid += [(init.local_threshold, False, True, closing)
                      for closing in CLOSINGS_M if closing != init.closing_m]
    rows = []
    for local, carve, blank, closing in settings_grid:
        row_init = init.model_copy(update={"local_threshold": local, "carve_front": carve,
                                           "blank_range_sidelobes": blank})
        exclude = excluded_voxels(row_init, per_view, data.measurements.acquisition, grid, init.threshold)
        rows.append(_scored(detection_target(power, grid, threshold=init.threshold, local_threshold=local,
                                             window_m=init.window_m, closing_m=closing, exclude=exclude),
                            grid, scene, observed, settings)
                    | {"threshold": init.threshold, "local_threshold": local, "closing_m": closing,
                       "carve_front": carve, "blank_range_sidelobes": blank})
        print(to_json(rows[-1], indent=None), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"scene": settings.scene, "radar": settings.radar, "rows": rows}))


def _scored(signed, grid, scene, observed, settings) -> dict:
    """Scores of the zero set of the signed distance ``signed`` (grid.shape) [m]."""
    mesh = mesh_from_volume(signed, grid, level=0.0)
    metrics = evaluate_scene(mesh, scene, observed=observed, samples=settings.metric_samples, seed=settings.seed)
    points = torch.as_tensor(np.asarray(trimesh.sample.sample_surface(mesh, 20_000, seed=0)[0]), dtype=torch.float64)
    with torch.no_grad():
        signed_mm = scene.sdf(points).numpy() * 1e3
        far = scene.sdf(torch.as_tensor(mesh.triangles_center, dtype=torch.float64)).abs().numpy() > 0.02
    return {"chamfer_l1_mm": metrics.full.chamfer_l1_mm, "fscore": metrics.full.fscore,
            "observed_chamfer_l1_mm": metrics.observed.chamfer_l1_mm,
            "accuracy_near_observed_mm": metrics.accuracy_near_observed_mm,
            "accuracy_near_unobserved_mm": metrics.accuracy_near_unobserved_mm,
            "objects_found": sum(m.found for m in metrics.objects.values()),
            "recall": {name: m.recall for name, m in metrics.objects.items()},
            "share_outside_5mm": float(np.mean(signed_mm > 5)), "share_inside_5mm": float(np.mean(signed_mm < -5)),
            "floater_area_cm2": float(mesh.area_faces[far].sum() * 1e4), "area_cm2": float(mesh.area * 1e4)}


if __name__ == "__main__":
    main()
