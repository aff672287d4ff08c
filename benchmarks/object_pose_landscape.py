"""How far each data loss sees one object's pose: the converged model's landscape, object by object.

The demo's data (facets, SNR 30 dB) against the true scene with one object rotated about
its centre (by 0.5-8 degrees about a fixed oblique axis) or translated (by 0.5-4 mm along
(1, 1, 1) / sqrt 3), every other object true, each scored as the basin study scores a
surface (`rfsdf.studies.basin.SurfaceLosses`: the fit's renderer and facets, every view,
the true materials and the radar's gain; the voxels any view shows above 2 % of its
peak). A loss whose value stops rising with the error (or falls again) gives a fit no
gradient back from there: that error is beyond its basin for that object.

Usage: python benchmarks/object_pose_landscape.py [--out benchmarks/results/object-pose-landscape.json]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.geometry.transforms import rotation_matrix
from rfsdf.jsonio import write_json
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import Problem, ReconConfig
from rfsdf.studies.basin import SurfaceLosses, TrueMaterials

TILTS_DEG = (0.5, 1.0, 2.0, 4.0, 8.0)
SHIFTS_MM = (0.5, 1.0, 2.0, 4.0)
TILT_AXIS = (1.0, 1.0, 0.3)


def moved(scene, index: int, centre: torch.Tensor, turn: torch.Tensor, shift: torch.Tensor):
    """The scene's SDF with object ``index`` turned by ``turn`` about ``centre`` [m], then shifted."""
    def sdf(points: torch.Tensor) -> torch.Tensor:
        p = points.double()
        values = [o.sdf(p) for o in scene.objects]
        values[index] = scene.objects[index].sdf((p - centre - shift) @ turn + centre)  # turn^T on rows
        return torch.stack(values).min(0).values.float()
    return sdf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/object-pose-landscape.json"))
    args = parser.parse_args()
    data = demo_data()
    scene = data.scene
    known = TrueMaterials(scene)
    problem = Problem(data.measurements, data.image.grid, known_materials=known, gain=SIMULATED_GAIN)
    losses = SurfaceLosses(problem, ReconConfig.model_validate({"train": {"device": "cpu"}}), known)
    surface = scene.sample_surface(0.002, seed=0, max_samples=200_000)
    result = {"truth": losses(lambda p: scene.sdf(p.double()).float()), "tilt_axis": TILT_AXIS, "objects": {}}
    still, none = torch.eye(3, dtype=torch.float64), torch.zeros(3, dtype=torch.float64)
    for index, obj in enumerate(scene.objects):
        centre = surface.points[surface.object_index == index].double().mean(0)
        tilts = {str(deg): losses(moved(scene, index, centre, rotation_matrix(TILT_AXIS, math.radians(deg)), none))
                 for deg in TILTS_DEG}
        shifts = {str(mm): losses(moved(scene, index, centre, still, torch.full((3,), mm * 1e-3 / math.sqrt(3),
                                                                                dtype=torch.float64)))
                  for mm in SHIFTS_MM}
        result["objects"][obj.name] = {"tilt_deg": tilts, "shift_mm": shifts}
        print(obj.name, {d: round(v["amplitude"], 4) for d, v in tilts.items()},
              {d: round(v["amplitude"], 4) for d, v in shifts.items()}, flush=True)
    write_json(args.out, result)


if __name__ == "__main__":
    main()
