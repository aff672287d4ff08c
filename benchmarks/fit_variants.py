"""The default fit against variants of its settings, each from its own warm start: on a scene's
simulated data (the demo's settings), every variant (ReconConfig overrides, the warm start's
included) fitted on the same data and CLEAN image, for each seed of the fit. Per run: its time
(the warm start's with any primitives, and the fit's steps'), the range peaks the fit holds and
how far they lie from the true surface (beyond 2 mm, within 1 mm, amplitude-weighted), each
fragment's primitive where they are fitted, the warm start's and the fit's observed-surface and
whole-surface Chamfer-L1 with each object's (and its part of the observed one), the share of the
warm start's observed error the fit removes, and with a material head the demo's material readout
(the head's and the closed-form readout's, ``rfsdf.material_estimates.read_materials``; a
relative fit's also in the simulator's gain given after the fit, ``readout_known_gain``).
A variant's ``"gain"`` (beside its ReconConfig tables) holds that radar gain in the loss (1.0 for
simulated data) instead of fitting one at each step; a capture's gain as ``reconstruct --gain``
gives it, after the relative fit, is the table ``{"calibration": {"gain": 1.0}}``.

Usage: python benchmarks/fit_variants.py --variants '{"name": {recon overrides}, ...}'
       [--scene objects] [--seeds 0,1,2] [--device cpu] [--out benchmarks/results/fit-variants-SCENE.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
import torch
from demo_data import calibrated_problem, demo_data
from seeds import _materials

from rfsdf.demo import DemoSettings, with_calibration
from rfsdf.device import resolve_device
from rfsdf.jsonio import to_json
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.recon import ReconConfig, Trainer
from rfsdf.recon.material_readout import PRIMITIVE_BAND_M, primitive_union


def _peak_distances(trainer: Trainer, scene) -> dict[str, float]:
    """How far the range peaks the fit holds lie from the true surface."""
    if trainer.peaks is None:
        return {"peaks": 0}
    points, amplitude = (a.cpu().double() for a in trainer.peaks[:2])
    distance = scene.sdf(points).abs().numpy()
    return {"peaks": len(distance), "beyond_2mm": int((distance > 2e-3).sum()), "within_1mm": int((distance < 1e-3).sum()),
            "amplitude_weighted_mm": float(np.average(distance, weights=amplitude.numpy()) * 1e3)}


def _primitives(trainer: Trainer) -> list[dict]:
    """Each fragment's best primitive (``[init] primitives``): its kind, the fragments it stands
    for, their peaks, the median gap at them and the warm start's [mm], and whether it replaced
    them."""
    return [{"kind": fit.primitive.kind, "fragments": len(fit.fragment.labels), "peaks": len(fit.fragment.peaks),
             "median_mm": fit.peaks_median_m * 1e3, "warm_median_mm": fit.fragment.warm_median_m * 1e3,
             "replaces": fit.explains}
            for fit in trainer.primitive_fits or []]


@torch.no_grad()
def _covered(trainer: Trainer, scene) -> dict[str, float]:
    """Each object's share of the surface samples the materials' readout rendered last (the
    objects told apart by the true scene) within ``PRIMITIVE_BAND_M`` of a primitive that replaced
    its fragment: where the read surface is a primitive's."""
    anchors = trainer.renderer.candidates.anchors.double().cpu()
    owner = scene.object_index(anchors)
    near = torch.zeros(len(anchors), dtype=torch.bool)
    if trainer.primitives:
        near = primitive_union(anchors, trainer.primitives).abs() < PRIMITIVE_BAND_M
    return {obj.name: float(near[owner == i].double().mean()) if bool((owner == i).any()) else 0.0
            for i, obj in enumerate(scene.objects)}


def run_variants(variants: dict[str, dict], *, scene_name: str, seeds: list[int], device: str, out: Path) -> list[dict]:
    """Fit every variant on every seed (see the module docstring); each row is printed and the
    JSON at ``out`` rewritten as it comes. Returns the rows."""
    device = resolve_device(device, "--device")
    out.parent.mkdir(parents=True, exist_ok=True)
    settings = dataclasses.replace(DemoSettings(), scene=scene_name)
    clock = time.perf_counter()
    data = demo_data(settings, device)
    scene, grid = data.scene, data.image.grid
    clean = clean_image(data.measurements, grid, device=device, max_components=settings.clean_components)
    print(f"data and CLEAN {time.perf_counter() - clock:.0f} s", flush=True)
    score = partial(evaluate_scene, scene=scene, samples=settings.metric_samples, seed=settings.seed,
                    observed=partial(observed_mask, acquisition=data.measurements.acquisition, occluder=scene.sdf))

    def scores(field) -> tuple[dict, object]:
        mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution, device=device)
        metrics = score(mesh)
        return {"observed_mm": metrics.observed.chamfer_l1_mm, "whole_mm": metrics.full.chamfer_l1_mm,
                "fscore": metrics.full.fscore, "completeness_seen_mm": metrics.completeness_observed_mm,
                "objects_mm": {name: o.chamfer_l1_mm for name, o in metrics.objects.items()},
                "objects_observed_share_mm": {name: o.observed_share_mm for name, o in metrics.objects.items()}}, mesh

    rows = []
    for seed in seeds:
        for variant, overrides in variants.items():
            overrides = dict(overrides)
            gain = overrides.pop("gain", None)
            train = {**settings.recon.get("train", {}), **overrides.get("train", {}), "seed": seed, "device": str(device)}
            config = with_calibration(ReconConfig.model_validate({**settings.recon, **overrides, "train": train}),
                                          scene, dataclasses.replace(settings, gain=gain))
            problem, reference = calibrated_problem(data, config, clean, gain=gain)
            with tempfile.TemporaryDirectory() as folder:
                trainer = Trainer(problem, config, folder)
                clock = time.perf_counter()
                fit = trainer.fit()
                seconds = round(time.perf_counter() - clock, 1)
                (warm, _), (fitted, mesh) = scores(fit.warm_field), scores(fit.field)
                steps_s = round(sum(record.seconds for record in trainer.log), 1)
                row = {"seed": seed, "variant": variant, "overrides": overrides, "gain": gain, "fit_s": seconds,
                       "start_s": round(seconds - steps_s, 1), "steps_s": steps_s,
                       **_peak_distances(trainer, scene), "primitives": _primitives(trainer),
                       "warm_start": warm, "fit": fitted,
                       "removed": 1 - fitted["observed_mm"] / warm["observed_mm"]}
                if fit.field.material_head is not None:
                    row["materials"] = _materials(trainer, fit, mesh, reference, scene, settings.seed)
                    row["covered"] = _covered(trainer, scene)
            rows.append(row)
            print(to_json(row, indent=None), flush=True)
            out.write_text(to_json({"scene": settings.scene, "radar": settings.radar, "device": str(device),
                                    "threads": torch.get_num_threads(), "rows": rows}))
    return rows


def main(variants: dict[str, dict] | None = None, name: str = "fit-variants") -> None:
    """The command line; ``variants`` and ``name`` (of the output) set by a benchmark of one rule."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, default=None)
    if variants is None:
        parser.add_argument("--variants", type=json.loads, required=True, help="{name: ReconConfig overrides}")
    args = parser.parse_args()
    run_variants(variants or args.variants, scene_name=args.scene, seeds=[int(s) for s in args.seeds.split(",")],
                 device=args.device, out=args.out or Path(f"benchmarks/results/{name}-{Path(args.scene).stem}.json"))


if __name__ == "__main__":
    main()
