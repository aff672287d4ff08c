"""What a fitted neural surface's errors look like, so that an experiment modelling them
(`brightness_under_errors.py`) uses their real size and smoothness: the fitted SDF at points
of the true surface (its signed distance to the fitted surface, positive where the fitted
surface lies inside the true one), over all of it and over the part some view observes,
per object, and its correlation between two points of one object against their distance.

Usage: python benchmarks/fit_errors.py DEMO_FOLDER --scene tabletop
       [--out benchmarks/results/fit-errors-tabletop.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
import trimesh

from rfsdf.jsonio import to_json
from rfsdf.radar import read_measurements
from rfsdf.radar.coverage import observed_mask
from rfsdf.recon import load_field
from rfsdf.scene import load_scene

SAMPLES = 12_000  # of the true surface
PAIRS = 200_000
BINS_MM = (0, 3, 6, 10, 15, 20, 30, 50)


def _statistics(points: np.ndarray, error: np.ndarray, owner: np.ndarray) -> dict:
    """rms, mean and mean |.| of ``error`` [m] in mm, and its correlation against distance
    over random pairs of points of one object."""
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, len(error), PAIRS), rng.integers(0, len(error), PAIRS)
    same = owner[i] == owner[j]
    distance = np.linalg.norm(points[i] - points[j], axis=1)[same]
    a, b = (error[i] - error.mean())[same], (error[j] - error.mean())[same]
    correlation = {}
    for lo, hi in zip(BINS_MM[:-1], BINS_MM[1:]):
        pair = (distance >= lo * 1e-3) & (distance < hi * 1e-3)
        if pair.sum() > 50:
            correlation[f"{lo}-{hi} mm"] = float(np.corrcoef(a[pair], b[pair])[0, 1])
    return {"samples": len(error), "rms_mm": float(1e3 * np.sqrt((error ** 2).mean())),
            "mean_mm": float(1e3 * error.mean()), "std_mm": float(1e3 * error.std()),
            "mean_abs_mm": float(1e3 * np.abs(error).mean()), "correlation": correlation}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("folder", type=Path)
    parser.add_argument("--scene", required=True)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/fit-errors-{Path(args.scene).stem}.json")
    field, scene = load_field(args.folder / "run"), load_scene(args.scene)
    mesh = scene.ground_truth_mesh()
    points, faces = trimesh.sample.sample_surface_even(mesh, SAMPLES, seed=0)
    points = torch.tensor(np.asarray(points))
    acquisition = read_measurements(args.folder / "measurements.h5").acquisition
    seen = observed_mask(points, torch.tensor(mesh.face_normals[faces]), acquisition=acquisition,
                         occluder=scene.sdf).numpy()
    with torch.no_grad():
        error = torch.cat([field.sdf(chunk.float()).double() for chunk in points.split(4096)]).numpy()
        owner = torch.stack([obj.sdf(points) for obj in scene.objects]).abs().argmin(0).numpy()
    points = points.numpy()
    result = {"folder": str(args.folder), "scene": args.scene,
              "all": _statistics(points, error, owner), "observed": _statistics(points[seen], error[seen], owner[seen]),
              "observed_by_object": {obj.name: _statistics(points[seen & (owner == k)], error[seen & (owner == k)],
                                                           owner[seen & (owner == k)])
                                     for k, obj in enumerate(scene.objects) if (seen & (owner == k)).sum() > 1}}
    for part in ("all", "observed"):
        row = result[part]
        print(f"{part}: rms {row['rms_mm']:.2f} mm (mean {row['mean_mm']:.2f}, std {row['std_mm']:.2f}); "
              f"correlation {', '.join(f'{k} {v:.2f}' for k, v in row['correlation'].items())}")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(result))


if __name__ == "__main__":
    main()
