"""What `[init] primitives` makes of a scene's warm start (the demo's by default). The warm
start as `rfsdf demo` builds it (the fit's ``--seed``, 0 by default; calibrated by the scene's
reference where it names one); its fragments (`recon.object_primitives.fragments`), each fitted by every primitive
(`explain_all`: near fragments also as one), with the true object it lies on, its peaks, the
best primitive and whether it replaces the fragment, the warm start's own median |f| over the
same peaks (read as glints), and over the warm surface the views saw (within 6 mm of its peaks)
how far the primitive lies from it and which of the two the truth is nearer to; then the warm
start and the target (`primitive_target`) scored as the demo scores a mesh (whole and observed
Chamfer, per object), and the network regressed onto the target (`regress_to_primitives`) at
each of ``--regressions`` (steps, a scale of the warm start's rate, whether it decays, the seed
of its draws; timed), scored the same way. The fit from it:
`python benchmarks/seeds.py --as-demo --recon '{"init": {"primitives": true}}'`.

Usage: python benchmarks/primitive_start.py [--scene objects] [--seed 0] [--cone 0]
       [--regressions '[{"steps": 100, "lr_scale": 1, "decay": true}]']
       [--out benchmarks/results/primitive-start-SCENE.json]
       (~8 min on 2 cores; the demo's scene at seed 0 writes primitive-start.json, another seed
       primitive-start-seedN.json)
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import time
from functools import partial
from pathlib import Path

import torch
from demo_data import demo_data, demo_warm_start
from seeds import _scores

from rfsdf.demo import DemoSettings
from rfsdf.geometry import project_to_zero_set
from rfsdf.jsonio import to_json
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene
from rfsdf.radar.coverage import observed_mask
from rfsdf.recon.object_primitives import (REGRESSION_STEPS, explain_all, fragments, free_space, primitive_target,
                                          regress_to_primitives)


def _seen_agreement(fit, scene, reach_m: float = 0.006) -> dict:
    """Over the fragment's warm surface within ``reach_m`` of its peaks (the part the views saw):
    the median |f| of its primitive there [mm], and the median distance to the true surface of
    those points and of their projections onto the primitive [mm] (which of the two is nearer)."""
    surface = fit.fragment.surface
    if not len(surface) or not len(fit.fragment.peaks):
        return {}
    seen = surface[torch.cdist(surface, fit.fragment.peaks).min(1).values < reach_m]
    if not len(seen):
        return {}
    with torch.no_grad():
        agreement = fit.primitive(seen).abs().median()
    projected = project_to_zero_set(fit.primitive, seen)
    with torch.no_grad():
        truth = [scene.sdf(x).abs().median() for x in (seen, projected)]
    return {"seen_points": len(seen), "seen_agreement_mm": float(agreement) * 1e3,
            "seen_warm_truth_mm": float(truth[0]) * 1e3, "seen_primitive_truth_mm": float(truth[1]) * 1e3}


def object_of(fit, scene) -> str:
    """The name of the true object most of ``fit``'s fragment's warm surface lies nearest to."""
    with torch.no_grad():
        nearest = torch.stack([o.sdf(fit.fragment.surface).abs() for o in scene.objects]).argmin(0)
    return scene.objects[int(nearest.mode().values)].name


def scorer(data, settings):
    """sdf -> the demo's scores of its mesh on ``data``'s scene (whole and observed Chamfer, ...,
    and each object's Chamfer [mm])."""
    scene = data.scene
    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=partial(observed_mask, acquisition=data.measurements.acquisition, occluder=scene.sdf))

    def scored(sdf) -> dict:
        metrics = score(extract_mesh(sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution))
        return {**_scores(metrics), "object_chamfer_mm": {name: m.chamfer_l1_mm for name, m in metrics.objects.items()}}

    return scored


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--seed", type=int, default=0, help="the fit's seed (`[train] seed`): its warm start's draws")
    parser.add_argument("--regressions", type=json.loads,
                        default=[{"steps": REGRESSION_STEPS, "lr_scale": 1.0, "decay": True}],
                        help="[{steps, lr_scale[, decay, seed]}, ...]: the network's regressions onto the target "
                             "(by default `[init] primitives`' own)")
    parser.add_argument("--cone", type=float, default=0.0,
                        help="read the peaks as glints within this cone [deg] (`[init] peak_cone_deg`); "
                             "0: on their lines")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    settings = dataclasses.replace(DemoSettings(), scene=args.scene)
    scene_part = "" if args.scene == DemoSettings.scene else f"-{Path(args.scene).stem}"
    suffix = scene_part + (f"-seed{args.seed}" if args.seed else "")
    out = args.out or Path(f"benchmarks/results/primitive-start{suffix}.json")
    data = demo_data(settings)
    scene = data.scene
    trainer, config = demo_warm_start(data, args.seed)
    warm = trainer.field.requires_grad_(False)
    points, _, _, towards = trainer.peaks
    caps = trainer.peak_caps(args.cone)
    labels, fragment_grid, pieces = fragments(warm.sdf, scene.lower_m, scene.upper_m, points, caps)
    free = free_space(points, towards, scene.lower_m, scene.upper_m, occluder=warm.sdf)
    labels, fits = explain_all(pieces, warm.sdf, labels, fragment_grid, free)
    for fit in fits:
        print(fit.primitive.kind, f"{fit.peaks_median_m * 1e3:.2f} mm", fit.explains, flush=True)
    rows = [{"object": object_of(fit, scene), "fragments": len(fit.fragment.labels), "peaks": len(fit.fragment.peaks),
             **fit.primitive.describe(), "peaks_median_mm": fit.peaks_median_m * 1e3,
             "peaks_within_1mm": fit.peaks_within, "carved": fit.carved, "replaces": fit.explains,
             "warm_peaks_median_mm": fit.fragment.warm_median_m * 1e3, **_seen_agreement(fit, scene)} for fit in fits]
    scored = scorer(data, settings)

    target = primitive_target(warm.sdf, labels, fragment_grid, fits)
    result = {"fragments": rows, "warm start": scored(warm.sdf), "target": scored(target), "regressions": []}
    print(to_json({key: result[key]["observed_chamfer_l1_mm"] for key in ("warm start", "target")}))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(result))
    chosen, ic = [fit for fit in fits if fit.explains], config.init
    for regression in args.regressions if chosen else []:
        field, clock = copy.deepcopy(warm).requires_grad_(True), time.perf_counter()
        regress_to_primitives(field, warm, target, chosen, fragment_grid, steps=regression["steps"],
                              lr=regression["lr_scale"] * ic.lr, batch=ic.batch, eikonal_weight=ic.eikonal_weight,
                              near_share=ic.near_share, decay=regression.get("decay", False),
                              generator=torch.Generator().manual_seed(regression.get("seed", 0)))
        row = {**regression, "seconds": time.perf_counter() - clock, **scored(field.requires_grad_(False).sdf)}
        result["regressions"].append(row)
        print(to_json({key: row[key] for key in (*regression, "seconds", "observed_chamfer_l1_mm")}))
        out.write_text(to_json(result))


if __name__ == "__main__":
    main()
