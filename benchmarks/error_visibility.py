"""What the data see of each kind of error a fit leaves, against what the metric charges for it.

The demo's true scene with every material and the radar's gain known (the losses of `rfsdf
study basin`, `rfsdf.studies.basin.SurfaceLosses`: the fit's facet renderer, every view),
one object altered at a time, each kind at three sizes:

- the wood block's seen face (-x, head-on to a view) moved in along its range;
- its rims moved in: the block narrowed in y and z, so its seen face's edges come in;
- its edges rounded (a box of radius r);
- the notched block's -x face, tilted beyond every view's cone (only its edges return),
  recessed between 5 mm rims;
- every object hollowed behind a wall (inner faces: no line of sight reaches them).

Per variant: each data loss, in all and at the voxels within 3 cm of the altered object (and
the true scene's there: the floor of noise and model error); the
amplitude loss there with the altered object's material free to read as a blend with the
next brighter or dimmer class (the best of a few blends: what a fit's material head could
absorb of it); and the variant's observed-surface and whole Chamfer-L1 (meshed at 256 voxels
along the box, twice the demo's resolution, so that millimetres show). About 20 minutes on 2 cores.

Usage: python benchmarks/error_visibility.py [--out benchmarks/results/error-visibility.json]
"""

from __future__ import annotations

import argparse
import time
from functools import partial
from pathlib import Path

import torch

from rfsdf.geometry import Box
from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene
from rfsdf.radar import load_radar
from rfsdf.radar.coverage import observed_mask
from rfsdf.studies import basin

WOOD, NOTCHED = 1, 4  # the demo scene's objects altered
WOOD_CENTRE, WOOD_HALF = (-0.05, 0.05, 0.0), (0.04, 0.025, 0.02)
NEAR_M = 0.03  # the voxels counted as the altered object's
BLENDS = (0.25, 0.5, 0.75)  # towards a neighbouring class (MATERIAL_CLASSES runs bright to dim)
MESH_RESOLUTION = 256


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/error-visibility.json"))
    args = parser.parse_args()
    clock = time.perf_counter()
    settings = basin.Settings(device="cpu")
    scene, losses = basin.surface_losses(settings)
    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=partial(observed_mask, acquisition=load_radar(settings.radar).acquisition(),
                                     occluder=scene.sdf))
    centres = losses.renderer.voxels[losses.voxels].double().cpu()
    rows, truth = [], losses(scene.sdf, per_voxel=True)
    for kind, size_mm, index, sdf in variants(scene):
        near = scene.objects[index].sdf(centres) < NEAR_M if index is not None else torch.ones(len(centres), dtype=torch.bool)
        per_voxel = losses(sdf, per_voxel=True)
        row = {"kind": kind, "size_mm": size_mm,
               "loss": {name: float(value.sum()) for name, value in per_voxel.items()},
               "loss_near": {name: float(value[near].sum()) for name, value in per_voxel.items()},
               "truth_near": {name: float(value[near].sum()) for name, value in truth.items()}}
        if index is not None:
            row["amplitude_near_material_free"] = min(
                [row["loss_near"]["amplitude"]]
                + [float(losses(sdf, per_voxel=True, reading=partial(blended, own=own, other=other, beta=beta))
                         ["amplitude"][near].sum())
                   for own, other in neighbours(scene, index) for beta in BLENDS])
        metrics = score(extract_mesh(sdf, scene.lower_m, scene.upper_m, MESH_RESOLUTION))
        row |= {"observed_chamfer_mm": metrics.observed.chamfer_l1_mm, "chamfer_mm": metrics.full.chamfer_l1_mm}
        rows.append(row)
        print(to_json(row, indent=None), f"{time.perf_counter() - clock:.0f} s", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"scene": settings.scene, "radar": settings.radar, "near_m": NEAR_M,
                                 "blends": BLENDS, "rows": rows, "seconds": time.perf_counter() - clock}))


def variants(scene):
    """(kind, size [mm], the altered object's index or None for all, sdf) of each variant."""
    def with_object(index, shape):
        others = [obj.sdf for i, obj in enumerate(scene.objects) if i != index]
        return lambda p: torch.stack([shape(p)] + [sdf(p) for sdf in others]).min(0).values

    def wood(half=WOOD_HALF, centre=WOOD_CENTRE, radius_m=0.0):
        box = Box([h - radius_m for h in half], centre)
        return with_object(WOOD, lambda p: box(p) - radius_m)

    def face_in(d):  # the -x face moved in by d, the +x face held
        return wood((WOOD_HALF[0] - d / 2, *WOOD_HALF[1:]), (WOOD_CENTRE[0] + d / 2, *WOOD_CENTRE[1:]))

    def recessed(depth):  # a recess of ``depth`` in the notched block's -x face (x = -20 mm), 5 mm rims kept
        cut = Box([depth / 2 + 0.001, 0.015, 0.015], [-0.02 + depth / 2 - 0.001, 0.0, -0.09])
        return with_object(NOTCHED, scene.objects[NOTCHED].sdf - cut)

    def hollow(wall):
        return lambda p: (lambda f: torch.maximum(f, -f - wall))(scene.sdf(p))

    for d in (0.25, 0.5, 1.0):
        yield "wood block: seen face moved in", d, WOOD, face_in(d * 1e-3)
    for d in (1.0, 2.0, 4.0):
        yield "wood block: rims moved in", d, WOOD, wood((WOOD_HALF[0], WOOD_HALF[1] - d * 1e-3, WOOD_HALF[2] - d * 1e-3))
    for r in (2.0, 4.0, 6.0):
        yield "wood block: edges rounded", r, WOOD, wood(radius_m=r * 1e-3)
    for depth in (1.5, 3.0, 6.0):
        yield "notched block: -x face recessed", depth, NOTCHED, recessed(depth * 1e-3)
    for wall in (6.0, 12.0):
        yield "every object hollow behind a wall", wall, None, hollow(wall * 1e-3)


def neighbours(scene, index) -> list[tuple[int, int]]:
    """(own class, neighbouring class) pairs: the object's class and each class next to it in
    brightness."""
    own = MATERIAL_CLASSES.index(scene.objects[index].material.name)
    return [(own, other) for other in (own - 1, own + 1) if 0 <= other < len(MATERIAL_CLASSES)]


def blended(classes: torch.Tensor, *, own: int, other: int, beta: float) -> torch.Tensor:
    """(N, C) one-hot probabilities of ``classes`` (N,), those of class ``own`` blended
    ``beta`` towards ``other``."""
    probabilities = torch.nn.functional.one_hot(classes, len(MATERIAL_CLASSES)).float()
    mine = classes == own
    probabilities[mine, own], probabilities[mine, other] = 1.0 - beta, beta
    return probabilities


if __name__ == "__main__":
    main()
