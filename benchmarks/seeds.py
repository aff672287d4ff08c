"""How much of a GeRaF score is the method and how much the luck of one fit: the default
demo's data (simulated, imaged and CLEANed once), fitted with several seeds of the fit's
own random draws (`[train] seed`: the warm start's points, the views, voxels and surface
samples of each step). Per seed: the warm start's and the fit's full, observed-surface and
per-object scores, and with a material head each object's material readout and the class
accuracy; then their mean, standard deviation, min and max.

Usage: python benchmarks/seeds.py [--seeds 0,1,2] [--scene S] [--radar R] [--out PATH]
       [--recon '{"init": {"threshold": "auto"}}']   (reconstruction settings over the defaults)
       [--as-demo]   (calibrated as `rfsdf demo` is: the scene's calibration_reference rendered as
       its material; without it one gain is fitted at each step, relative materials)
       [--gain G]   (hold the radar gain G instead, e.g. a calibration capture's: absolute materials)
The default output is benchmarks/results/seeds.json for the demo's scene and radar, else
seeds-SCENE-RADAR.json.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from functools import partial
from pathlib import Path

import numpy as np
from demo_data import demo_data

from rfsdf.demo import DemoSettings, with_calibration
from rfsdf.jsonio import to_json
from rfsdf.material_estimates import Reading, estimate_materials, fit_materials, known_gain, scene_reference
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_scene
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.calibration import check_reference, fitted_gain


def _scores(metrics) -> dict[str, float]:
    row = {"chamfer_l1_mm": metrics.full.chamfer_l1_mm, "fscore": metrics.full.fscore,
           "precision": metrics.full.precision, "recall": metrics.full.recall,
           "observed_chamfer_l1_mm": metrics.observed.chamfer_l1_mm, "observed_fscore": metrics.observed.fscore}
    row.update({f"recall_{name}": m.recall for name, m in metrics.objects.items()})
    row["objects_found"] = sum(m.found for m in metrics.objects.values())
    return row


def _materials(trainer: Trainer, fit, mesh, reference, scene, seed: int) -> dict:
    """The fit's material readout as the demo reports it (``fit_materials``): per object its true
    and predicted class, what predicted it (the data's closed-form readout or the head), the head's
    reflectivity and the readout (its spread over views and the classes its interval reaches), the
    observed share, and the class accuracy over the objects counted. A relative fit (no reference, no known gain) is also read in the simulator's gain,
    given after the fit as a calibration capture's would be (``calibration.gain``: every reading
    times the fitted gain over it): each object's ``readout_known_gain``, ``predicted_known_gain``
    and ``readout_classes_known_gain`` (the same rule), and their ``accuracy_known_gain``."""
    calibration = None if reference is None else check_reference(trainer, reference)
    reported = fit_materials(trainer, mesh, scene=scene, calibration=calibration, seed=seed)
    row = {"accuracy": reported.accuracy, "calibration": reported.calibration,
           "objects": {o.name: {"true": o.true, "predicted": o.predicted, "source": o.source,
                                "reflectivity": o.reflectivity, "readout": o.readout,
                                "readout_spread": o.readout_spread, "readout_classes": o.readout_classes,
                                "observed_fraction": o.observed_fraction, "reference": o.reference}
                       for o in reported.objects}}
    if reference is None and known_gain(trainer) is None:
        scale = fitted_gain(trainer) / SIMULATED_GAIN
        readout = tuple(Reading(*(np.array([np.nan if v is None else v * scale for v in values])
                                  for values in ([e.readout for e in part], [e.readout_spread for e in part])))
                        for part in (reported.objects, reported.components))
        known = estimate_materials(fit.field, mesh, trainer.problem.measurements.acquisition, scene=scene, seed=seed,
                                   calibration="known", readout=readout, head_scale=scale)
        row["accuracy_known_gain"] = known.accuracy
        for o in known.objects:
            row["objects"][o.name].update(readout_known_gain=o.readout, predicted_known_gain=o.predicted,
                                          readout_classes_known_gain=o.readout_classes)
    return row


def _spread(rows: list[dict[str, float]]) -> dict[str, dict[str, float]]:
    return {key: {"mean": float(np.mean(v)), "std": float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
                  "min": float(np.min(v)), "max": float(np.max(v))}
            for key, v in ((key, [r[key] for r in rows]) for key in rows[0])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", default="0,1,2", help="Comma-separated fit seeds.")
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--radar", default=DemoSettings.radar)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--recon", type=json.loads, default={}, help="ReconConfig overrides (JSON tables).")
    parser.add_argument("--as-demo", action="store_true",
                        help="calibrate as rfsdf demo does, by the scene's calibration_reference")
    parser.add_argument("--gain", type=float, default=None, help="hold this radar gain in the fit")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]

    settings = DemoSettings(scene=args.scene, radar=args.radar, gain=args.gain, relative=not args.as_demo)
    default = (args.scene, args.radar) == (DemoSettings.scene, DemoSettings.radar)
    out = args.out or Path("benchmarks/results/" + ("seeds.json" if default else
                                                    f"seeds-{Path(args.scene).stem}-{Path(args.radar).stem}.json"))
    data = demo_data(settings)
    demo, scene, grid = data.settings, data.scene, data.image.grid
    clean = clean_image(data.measurements, grid)
    print(f"CLEAN residual floor {clean.residual_floor():.4f}", flush=True)
    score = partial(evaluate_scene, scene=scene, samples=demo.metric_samples, seed=demo.seed,
                    observed=partial(observed_mask, acquisition=data.measurements.acquisition, occluder=scene.sdf))
    mesh = lambda field: extract_mesh(field.sdf, scene.lower_m, scene.upper_m, demo.mesh_resolution)  # noqa: E731
    runs = []
    for seed in seeds:
        overrides = {**args.recon, "train": {**args.recon.get("train", {}), "seed": seed}}
        config = with_calibration(ReconConfig.model_validate(overrides), scene, settings)
        reference = (None if config.calibration.reference is None
                     else scene_reference(scene, config.calibration, data.measurements.acquisition))
        known = None if reference is None else reference.labels(tuple(config.field.materials))
        with tempfile.TemporaryDirectory() as run:
            trainer = Trainer(Problem(data.measurements, grid, clean=clean, gain=args.gain, known_materials=known),
                              config, run)
            fit = trainer.fit()
            neural = mesh(fit.field)
            runs.append({"seed": seed, "warm_start": _scores(score(mesh(fit.warm_field))),
                         "neural": _scores(score(neural)), "seconds_per_step": fit.seconds_per_step})
            if fit.field.material_head is not None:
                runs[-1]["materials"] = _materials(trainer, fit, neural, reference, scene, demo.seed)
        print(to_json(runs[-1], indent=None), flush=True)
    result = {"scene": args.scene, "radar": args.radar, "seeds": seeds, "recon": args.recon, "as_demo": args.as_demo,
              "gain": args.gain, "runs": runs,
              "warm_start": _spread([r["warm_start"] for r in runs]), "neural": _spread([r["neural"] for r in runs])}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(result))
    print(to_json({k: result[k] for k in ("warm_start", "neural")}))


if __name__ == "__main__":
    main()
