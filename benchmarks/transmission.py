"""Seeing into a box: the `boxed` scene (three objects in a closed 3 mm cardboard box)
simulated with opaque lines of sight (the default) and through its dielectrics, in one run.

Per run: the simulator's wall time and surface samples, and the matched-filter image's
strongest voxel within 5 mm of each object's surface (outside the other objects) over the
box's own strongest, the objects' brightness as an image shows it. The ratio of the two
runs' times is what transmission costs the simulator on this machine.

The box's 0.19 m^2 at the simulator's lambda/3 facets are 316,000 (20 minutes a run on 2
cores); the benchmark sums lambda/1.5 facets (``--samples-per-wavelength``), exact on flat
faces, four times fewer.

Usage: python benchmarks/transmission.py [--samples-per-wavelength 1.5]
       [--out benchmarks/results/transmission.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar, matched_filter, simulate
from rfsdf.scene import load_scene

NEAR_M = 0.005  # a voxel belongs to an object within this distance of its surface
VOXEL_M = 0.003
MAX_SAMPLES = 400_000


def brightness(scene, image, grid: Grid) -> dict[str, float]:
    """Per object, the image's strongest voxel within ``NEAR_M`` of it (and nearer it than
    any other object) over the box's strongest."""
    points = grid.points()
    power = image.power().reshape(-1)
    with torch.no_grad():
        values = torch.stack([o.sdf(points).abs() for o in scene.objects])  # (objects, voxels)
    nearest = values.argmin(0)
    peaks = {o.name: float(power[(nearest == i) & (values[i] < NEAR_M)].max()) for i, o in enumerate(scene.objects)}
    return {name: round(value / peaks["box"], 4) for name, value in peaks.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples-per-wavelength", type=float, default=1.5)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/transmission.json"))
    args = parser.parse_args()
    scene, radar = load_scene("boxed"), load_radar("near-77g")
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, VOXEL_M)
    result = {"scene": scene.name, "radar": radar.name, "threads": torch.get_num_threads(), "voxel_m": VOXEL_M,
              "near_m": NEAR_M, "samples_per_wavelength": args.samples_per_wavelength, "runs": {}}
    for transmission in (False, True):
        start = time.perf_counter()
        data = simulate(scene, radar, seed=0, max_samples=MAX_SAMPLES, transmission=transmission,
                        samples_per_wavelength=args.samples_per_wavelength)
        seconds = time.perf_counter() - start
        image = matched_filter(data, grid, method="fast")
        result["runs"]["through" if transmission else "opaque"] = {
            "simulate_s": round(seconds, 1), "surface_samples": int(data.metadata["surface_samples"]),
            "peak_over_box": brightness(scene, image, grid)}
        print(result["runs"])
    runs = result["runs"]
    result["time_ratio"] = round(runs["through"]["simulate_s"] / runs["opaque"]["simulate_s"], 2)
    args.out.write_text(to_json(result))
    print(f"wrote {args.out}: transmission costs the simulator {result['time_ratio']}x")


if __name__ == "__main__":
    main()
