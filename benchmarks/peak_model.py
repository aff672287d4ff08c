"""What a view's range peak measures: the surface along its own line of sight, or the range of
a glint within the line's main lobe. The range peaks of the demo's warm start (seed 0) held
against the true surface by three models of a peak at range rho from its view's centre c along
the unit direction u [residual rho - model, mm; negative: the peak stands in front]:

- ``line``: the first surface the ray c + s u meets (what the warm start's peaks and the fit's
  held peaks assume: f = 0 at the peak);
- ``nearest THETA``: the nearest true surface sample within a cone of half-angle THETA [deg]
  about the line;
- ``specular THETA``: the range of the sample within that cone that faces the view most
  squarely (largest n . (c - x) / |c - x|): the glint that dominates the line's return.

Per object (each peak's nearest) and over all: the count, the median |residual| and the median
residual. The array's main lobe is about lambda / (2 D) = 0.9 degrees at 79 GHz for the
near-77g's 12 cm aperture. No occlusion is modelled (the cones are narrow).

Usage: python benchmarks/peak_model.py [--scene objects] [--angles 0.25,0.5,1,2]
       [--out benchmarks/results/peak-model-SCENE.json]   (~3 min on 2 cores)
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np
import torch
from demo_data import demo_data, demo_warm_start

from rfsdf.demo import DemoSettings
from rfsdf.geometry import sphere_trace
from rfsdf.jsonio import write_json

SURFACE_SPACING_M = 4e-4  # the true surface's samples [m]
TRACE_STEPS, HIT_M, TRACE_MAX_M = 400, 1e-5, 2.0  # sphere tracing of the line model: steps, hit tolerance, miss range [m]


def line_ranges(scene, centres: torch.Tensor, directions: torch.Tensor) -> torch.Tensor:
    """(N,) range [m] where each ray (centres (N, 3), unit directions (N, 3)) first meets the
    scene's surface; NaN where it does not."""
    trace = sphere_trace(scene.sdf, centres, directions, eps=HIT_M, max_steps=TRACE_STEPS, t_max=TRACE_MAX_M)
    return torch.where(trace.hit, trace.t, torch.full_like(trace.t, float("nan")))


def cone_ranges(surface: torch.Tensor, normals: torch.Tensor, centres: torch.Tensor, directions: torch.Tensor,
                angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) ranges [m] of the nearest and of the most squarely facing surface sample (points and
    outward normals (S, 3)) within the cone of ``angle_deg`` about each ray; NaN where none is."""
    cos_angle = math.cos(math.radians(angle_deg))
    nearest, specular = np.full(len(centres), np.nan), np.full(len(centres), np.nan)
    for i, (centre, direction) in enumerate(zip(centres, directions)):
        offset = surface - centre
        distance = offset.norm(dim=1)
        inside = offset @ direction >= cos_angle * distance
        if inside.any():
            within, facing = distance[inside], -(normals[inside] * offset[inside]).sum(1) / distance[inside]
            nearest[i], specular[i] = float(within.min()), float(within[facing.argmax()])
    return nearest, specular


def _summary(residual_mm: np.ndarray) -> dict:
    kept = residual_mm[np.isfinite(residual_mm)]
    return {"count": int(len(kept)), "median_abs_mm": float(np.median(np.abs(kept))) if len(kept) else None,
            "median_mm": float(np.median(kept)) if len(kept) else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--angles", default="0.25,0.5,1,2", help="the cones' half-angles [deg], comma-separated")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    angles = [float(a) for a in args.angles.split(",")]
    out = args.out or Path(f"benchmarks/results/peak-model-{Path(args.scene).stem}.json")
    data = demo_data(dataclasses.replace(DemoSettings(), scene=args.scene))
    scene = data.scene
    trainer, _ = demo_warm_start(data)
    points, _, view, towards = (t.cpu() for t in trainer.peaks)
    points, directions = points.double(), -towards.double()
    centres = data.measurements.acquisition.view_centres()[0].cpu().double()[view.long()]
    ranges = (points - centres).norm(dim=1)
    samples = scene.sample_surface(SURFACE_SPACING_M)
    surface, normals = samples.points.double(), samples.normals.double()
    residuals = {"line": (ranges - line_ranges(scene, centres, directions)).numpy() * 1e3}
    for angle in angles:
        nearest, specular = cone_ranges(surface, normals, centres, directions, angle)
        residuals[f"nearest {angle:g}"] = (ranges.numpy() - nearest) * 1e3
        residuals[f"specular {angle:g}"] = (ranges.numpy() - specular) * 1e3
    owner = scene.object_index(points).numpy()
    groups = {obj.name: owner == k for k, obj in enumerate(scene.objects)}
    groups["all"] = np.ones(len(points), bool)
    rows = {name: {model: _summary(r[mask]) for model, r in residuals.items()} for name, mask in groups.items() if mask.any()}
    print(f"{'object':<18}{'peaks':>6} " + " ".join(f"{m:>16}" for m in residuals))
    for name, row in rows.items():
        print(f"{name:<18}{int(groups[name].sum()):>6} " + " ".join(
            f"{r['median_abs_mm']:>8.2f} ({r['median_mm']:+5.2f})" for r in row.values()))
    write_json(out, {"scene": args.scene, "radar": data.settings.radar, "peaks": len(points),
                     "surface_spacing_m": SURFACE_SPACING_M, "objects": rows})


if __name__ == "__main__":
    main()
