"""Range-profile back-projection against the exact matched filter, both timed in the same run.

On the default demo (scene `objects`, radar `near-77g`, the demo's seed and 6 mm grid): the
exact per-view image (the sensing operator's adjoint) and the fast one at several
zero-padding (oversampling) factors; relative error = ||fast - exact|| / ||exact|| over the
complex per-view images, and whether the brightest voxel of the view-mean power is the same.
Then the speed-up against the number of frequencies K on the same array (random data, a
coarser grid), which sets the automatic choice (`FAST_MIN_FREQUENCIES`).

Usage: python benchmarks/fast_imaging.py [--out benchmarks/results/fast_imaging.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from rfsdf.demo import DemoSettings
from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import Acquisition, Measurements, load_radar, matched_filter, simulate
from rfsdf.radar.fast_imaging import DEFAULT_OVERSAMPLING
from rfsdf.scene import load_scene

OVERSAMPLINGS = (4, 8, 16, 32)
FREQUENCY_COUNTS = (2, 4, 8, 16, 64, 256)


def _timed(function):
    start = time.perf_counter()
    result = function()
    return result, time.perf_counter() - start


def _with_frequencies(acquisition: Acquisition, count: int) -> Acquisition:
    """The same array and views with ``count`` frequencies over the same band."""
    f = acquisition.frequencies_hz
    return Acquisition(acquisition.tx_m, acquisition.rx_m, torch.linspace(float(f.min()), float(f.max()), count,
                       dtype=torch.float64), acquisition.boresight, acquisition.pattern_exponent, acquisition.spreading)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/fast_imaging.json"))
    args = parser.parse_args()
    settings = DemoSettings()
    scene = load_scene(settings.scene)
    measurements = simulate(scene, load_radar(settings.radar), seed=settings.seed,
                            max_samples=settings.max_surface_samples)
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    matched_filter(measurements.thinned(8), Grid(scene.lower_m, scene.upper_m, (4, 4, 4)), method="fast")  # compile
    exact, exact_s = _timed(lambda: matched_filter(measurements, grid, method="exact"))
    peak = int(exact.power().argmax())
    rows = []
    for oversampling in OVERSAMPLINGS:
        fast, fast_s = _timed(lambda n=oversampling: matched_filter(measurements, grid, method="fast", oversampling=n))
        error = float((fast.per_view - exact.per_view).norm() / exact.per_view.norm())
        rows.append({"oversampling": oversampling, "seconds": fast_s, "speedup_vs_exact": exact_s / fast_s,
                     "relative_error": error, "peak_same_voxel": int(fast.power().argmax()) == peak})
        print(rows[-1], flush=True)
    default = next(r for r in rows if r["oversampling"] == DEFAULT_OVERSAMPLING)

    coarse = Grid(scene.lower_m, scene.upper_m, (24, 24, 24))
    generator = torch.Generator().manual_seed(0)
    by_frequencies = []
    for count in FREQUENCY_COUNTS:
        acquisition = _with_frequencies(measurements.acquisition.view(slice(0, 2)), count)
        shape = acquisition.shape
        data = torch.complex(torch.randn(shape, generator=generator), torch.randn(shape, generator=generator))
        noise = Measurements(acquisition, data)
        slow, slow_s = _timed(lambda m=noise: matched_filter(m, coarse, method="exact"))
        fast, fast_s = _timed(lambda m=noise: matched_filter(m, coarse, method="fast"))
        by_frequencies.append({"frequencies": count, "exact_s": slow_s, "fast_s": fast_s,
                               "speedup_vs_exact": slow_s / fast_s,
                               "relative_error": float((fast.per_view - slow.per_view).norm() / slow.per_view.norm())})
        print(by_frequencies[-1], flush=True)

    result = {
        "problem": {"scene": settings.scene, "radar": settings.radar, "grid": list(grid.shape),
                    "voxel_mm": settings.voxel_m * 1e3, "shape_vtrk": list(measurements.acquisition.shape)},
        "threads": torch.get_num_threads(),
        "exact_s": exact_s,
        "oversampling": DEFAULT_OVERSAMPLING,
        "speedup_vs_exact": default["speedup_vs_exact"],
        "relative_error": default["relative_error"],
        "peak_same_voxel": default["peak_same_voxel"],
        "by_oversampling": rows,
        "by_frequencies": {"grid": list(coarse.shape), "views": 2, "rows": by_frequencies},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
