"""The per-object material readout restricted to where the fitted surface lies on the true
one: does the readout improve when it reads the head only where the fit put a surface?

For each finished demo folder (SCENE=FOLDER, e.g. the ``capture`` folders that
``capture_gain_scene.py --work`` keeps): the observed true-surface samples of each object,
the share of them where the fitted SDF is within ``--tolerance`` (3 mm, the issue's first
measurement), and the readout (class nearest the fitted |Gamma|) over all observed samples
(what `rfsdf demo` reports) and over the on-surface ones only. An object counts in the
restricted accuracy when it is observed enough (15 %) and at least half its observed
surface is on the fitted surface; with none on it, it is "not reconstructed".

Usage: python benchmarks/material_on_surface.py SCENE=FOLDER [...] [--out PATH]
(default benchmarks/results/material_on_surface.json)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from rfsdf.jsonio import to_json
from rfsdf.material_estimates import MIN_OBSERVED_FRACTION, _estimate, _observed_objects, _probabilities
from rfsdf.radar import read_measurements
from rfsdf.recon import load_field
from rfsdf.scene import load_scene


def _scene_rows(scene_name: str, folder: Path, tolerance_m: float) -> dict:
    field, scene = load_field(folder / "run"), load_scene(scene_name)
    acquisition = read_measurements(folder / "measurements.h5").acquisition
    samples, rows = _observed_objects(scene, acquisition, 0.002, 40_000, 0)
    with torch.no_grad():
        distance = torch.cat([field.sdf(chunk.float()) for chunk in samples.points.split(65536)]).double().abs()
    on_surface = distance < tolerance_m

    def readout(use, obj, fraction):
        return _estimate(obj.name, _probabilities(field, samples.points[use]), samples.area_m2[use], field.materials,
                         acquisition.center_frequency_hz, fraction, obj.material)

    objects = []
    for obj, (mine, seen, fraction) in zip(scene.objects, rows):
        use = seen & on_surface
        share = float(samples.area_m2[use].sum() / samples.area_m2[seen].sum()) if bool(seen.any()) else 0.0
        every = readout(seen if bool(seen.any()) else mine, obj, fraction)
        near = readout(use, obj, fraction) if bool(use.any()) else None
        objects.append({"name": obj.name, "true": every.true, "observed_fraction": fraction, "on_surface_share": share,
                        "all_observed": {"predicted": every.predicted, "reflectivity": every.reflectivity},
                        "on_surface": None if near is None else {"predicted": near.predicted,
                                                                 "reflectivity": near.reflectivity}})
    counted = [o for o in objects if o["observed_fraction"] >= MIN_OBSERVED_FRACTION]
    gated = [o for o in counted if o["on_surface_share"] >= 0.5]
    return {"folder": str(folder), "objects": objects,
            "right_all_observed": [sum(o["all_observed"]["predicted"] == o["true"] for o in counted), len(counted)],
            "right_on_surface": [sum(o["on_surface"]["predicted"] == o["true"] for o in gated), len(gated)]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="SCENE=FOLDER: a scene name or file and its finished demo folder")
    parser.add_argument("--tolerance", type=float, default=0.003, help="[m] the fitted SDF's |f| on the true surface")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "material_on_surface.json")
    args = parser.parse_args()
    scenes = {}
    for run in args.runs:
        scene_name, folder = run.split("=", 1)
        scenes[scene_name] = _scene_rows(scene_name, Path(folder), args.tolerance)
        row = scenes[scene_name]
        print(f"{scene_name}: {row['right_all_observed'][0]} of {row['right_all_observed'][1]} over every observed "
              f"sample, {row['right_on_surface'][0]} of {row['right_on_surface'][1]} on the fitted surface", flush=True)
    args.out.write_text(to_json({"tolerance_m": args.tolerance, "scenes": scenes}))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
