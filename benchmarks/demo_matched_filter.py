"""Full matched-filter image of the default demo: every view of `near-77g` onto a 64^3 grid
over the `objects` scene. Reports wall time and peak resident memory.

The measurements are simulated in a child process, so that the peak memory reported here
is that of reading the file and forming the image (plus the Python/torch baseline, which
is reported too).

Usage: python benchmarks/demo_matched_filter.py [--resolution 64] [--out benchmarks/results/demo_mf.json]
"""

from __future__ import annotations

import argparse
import multiprocessing
import resource
import tempfile
import time
from pathlib import Path

import torch

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar, matched_filter, read_measurements, simulate, write_measurements
from rfsdf.scene import load_scene


def _simulate_to(path: str) -> None:
    write_measurements(path, simulate(load_scene("objects"), load_radar("near-77g"), seed=0))


def _peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux reports KiB


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--resolution", type=int, default=64, help="voxels along each axis")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/demo_mf.json"))
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "measurements.h5")
        child = multiprocessing.get_context("spawn").Process(target=_simulate_to, args=(path,))
        child.start()
        child.join()
        measurements = read_measurements(path)
    scene = load_scene("objects")
    grid = Grid(scene.lower_m, scene.upper_m, (args.resolution,) * 3)
    baseline = _peak_rss_mib()
    start = time.perf_counter()
    image = matched_filter(measurements, grid)
    seconds = time.perf_counter() - start
    pairs = measurements.acquisition.num_measurements * grid.size

    result = {
        "problem": {"scene": "objects", "radar": "near-77g", "views": measurements.acquisition.shape[0],
                    "measurements": measurements.acquisition.num_measurements, "grid": list(grid.shape),
                    "voxel_mm": float(grid.voxel_m[0] * 1e3)},
        "threads": torch.get_num_threads(),
        "wall_s": seconds,
        "pairs_per_s": pairs / seconds,
        "peak_rss_mib": _peak_rss_mib(),
        "rss_before_image_mib": baseline,
        "image_bytes_mib": (image.per_view.numel() * 8 + image.column_norms_sq.numel() * 4) / 2**20,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
