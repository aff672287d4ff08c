"""Which view-weight lobe max(0, n.u)^e best explains the simulator's MF images: render the
*true* scene (f = its SDF, Gamma = 1, sigma = 1 voxel) with each renderer and exponent, and
correlate each view's predicted MF amplitude with the observed one (default demo data).

Usage: python benchmarks/facing_lobe.py [--out benchmarks/results/facing_lobe.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.geometry import normals
from rfsdf.recon import Problem, delta_sigma, facing_weights, make_renderer

EXPONENTS = (0, 1, 4, 16, 64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/facing_lobe.json"))
    args = parser.parse_args()

    data = demo_data()
    demo, scene, measurements, grid = data.settings, data.scene, data.measurements, data.image.grid
    problem = Problem.from_image(data.image, measurements.acquisition)
    points = grid.points()
    with torch.no_grad():
        surface = delta_sigma(scene.sdf(points), demo.voxel_m) ** 2
    unit_normals = normals(scene.sdf, points)
    observed = problem.observed.flatten(1).sqrt()
    views = torch.arange(len(problem.view_centres_m))
    result: dict = {"views": len(views), "voxel_mm": demo.voxel_m * 1e3, "mean_amplitude_correlation": {}}
    for name in ("physics", "local"):
        renderer = make_renderer(name, measurements.acquisition, grid, 0.06)
        for exponent in EXPONENTS:
            intensity = facing_weights(points, unit_normals, problem.view_centres_m, exponent) * surface
            predicted = renderer(intensity.reshape(len(views), *grid.shape), views).flatten(1).sqrt()
            correlation = [float(torch.corrcoef(torch.stack([p, o]))[0, 1]) for p, o in zip(predicted, observed)]
            result["mean_amplitude_correlation"][f"{name} e={exponent}"] = sum(correlation) / len(correlation)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
