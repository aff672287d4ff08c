"""Why more views can blur the image the warm start thresholds: the point-spread function
of the view-mean power image (what CLEAN and the detection use: each view's MF power,
averaged incoherently over views) against the coherent sum over views, for the default
radar (12 views on one horizontal ring) and the dense one (36 views on three elevation
rings). Widths are the extent of the -6 dB region of power along lines in x, y and z
through a point target at the scene centre [mm], sampled every 1 mm.

Usage: python benchmarks/psf_views.py [--out benchmarks/results/psf_views.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar
from rfsdf.radar.imaging import point_spread

HALF_M, VOXEL_M = 0.06, 0.001


def _line(axis: int) -> Grid:
    """Voxels along one axis through the centre (2 cells 1 mm apart across it)."""
    lower, upper, shape = [-0.001] * 3, [0.001] * 3, [2, 2, 2]
    lower[axis], upper[axis], shape[axis] = -HALF_M, HALF_M, int(round(2 * HALF_M / VOXEL_M))
    return Grid(tuple(lower), tuple(upper), tuple(shape))


def _width_mm(power: np.ndarray, axis: int) -> float:
    """Extent [mm] of the -6 dB region (power >= 1/4 of the peak) along the line."""
    line = np.moveaxis(power, axis, 0)[:, 0, 0]
    return float((line >= 0.25 * line.max()).sum() * VOXEL_M * 1e3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/psf_views.json"))
    args = parser.parse_args()
    result = {}
    for name in ("near-77g", "dense-77g"):
        acquisition = load_radar(name).acquisition()
        images = [point_spread(acquisition, (0.0, 0.0, 0.0), _line(axis)) for axis in range(3)]
        result[name] = {"views": int(acquisition.shape[0]), **{
            key: {"xyz"[a]: _width_mm(image.power(coherent=coherent).numpy(), a) for a, image in enumerate(images)}
            for key, coherent in (("view_mean_power_6db_mm", False), ("coherent_power_6db_mm", True))}}
        print(name, to_json(result[name], indent=None))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
