"""Reconstruction quality on the default demo data: `objects` scene, `near-77g` radar,
matched filter at 6 mm voxels, GeRaF fit, mesh, metrics against the true surfaces.

Usage: python benchmarks/quality.py [--renderer physics|local] [--steps 150] [--init-radius 0.09]
                                    [--out benchmarks/results/quality-RENDERER.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import torch

from rfsdf.geometry import Grid
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import compare_meshes
from rfsdf.radar import load_radar, matched_filter, simulate
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.scene import load_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--renderer", choices=("physics", "local"), default="physics")
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--init-radius", type=float, default=0.09, help="initial sphere radius [m]")
    parser.add_argument("--voxel", type=float, default=0.006, help="MF image voxel [m]")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/quality-{args.renderer}.json")

    scene, radar = load_scene("objects"), load_radar("near-77g")
    start = time.perf_counter()
    measurements = simulate(scene, radar, seed=0)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, args.voxel)
    image = matched_filter(measurements, grid)
    prepared = time.perf_counter()
    config = ReconConfig.model_validate({
        "render": {"renderer": args.renderer}, "field": {"init_radius_m": args.init_radius},
        "train": {"steps": args.steps},
    })
    with tempfile.TemporaryDirectory() as run:
        field = Trainer(Problem.from_image(image, measurements.acquisition), config, run).fit()
    fitted = time.perf_counter()
    try:
        mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, 100)
        metrics = compare_meshes(mesh, scene.ground_truth_mesh()).as_dict()
    except ValueError as exc:  # no surface left inside the box: a result, not a crash
        metrics = {"error": str(exc)}

    result = {
        "problem": {"scene": "objects", "radar": "near-77g", "grid": list(grid.shape), "voxel_mm": args.voxel * 1e3},
        "settings": {"renderer": args.renderer, "steps": args.steps, "init_radius_m": args.init_radius},
        "threads": torch.get_num_threads(),
        "simulate_and_image_s": prepared - start, "fit_s": fitted - prepared,
        "metrics": metrics,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
