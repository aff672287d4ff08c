"""Does a smooth surface read materials where the fitted network does not? The default fit on a
scene's simulated data (the demo's settings, one fit seed), then each object's |Gamma| read
three ways, with the simulator's gain known (the absolute scale a calibration capture gives):

- ``head``: the fit's material head, as the demo reports it (the scene's calibration
  reference where it names one, else relative);
- ``network``: in closed form through the fitted network's surface: every object's part of
  the surface rendered with its true material, the bright voxels' powers split over the
  objects by NNLS (``object_brightness.object_gains``), so that object's |Gamma| reads
  |Gamma_true| a_i x the renderer's peak (1.000 on the exact surfaces: printed);
- ``primitives``: the same through the primitives that explain their fragments
  (``[init] primitives``), the network elsewhere (``rfsdf.recon.material_readout.with_primitives``).

The objects are told apart by the true scene (which object's surface a sample is nearest), as
the demo's per-object rows are; a run without a scene would split by the reconstruction's
components. Counted: objects at least 15 % observed, not the calibration reference.

Usage: python benchmarks/primitive_readout.py --scene tabletop [--seed 0]
       [--out benchmarks/results/primitive-readout-SCENE.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

from demo_data import calibrated_problem, demo_data
from object_brightness import object_gains
from seeds import _materials

from rfsdf.demo import DemoSettings, with_calibration
from rfsdf.jsonio import to_json
from rfsdf.material_estimates import _observed_objects, counts
from rfsdf.materials import class_reflectivities, reflectivity_class
from rfsdf.mesh import extract_mesh
from rfsdf.radar.clean import clean_image
from rfsdf.recon import ReconConfig, Trainer
from rfsdf.recon.material_readout import with_primitives
from rfsdf.recon.render import CoherentRenderer

def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/primitive-readout-{Path(args.scene).stem}.json")
    settings = dataclasses.replace(DemoSettings(), scene=args.scene)
    data = demo_data(settings)
    scene, acquisition = data.scene, data.measurements.acquisition
    clean = clean_image(data.measurements, data.image.grid, max_components=settings.clean_components)
    train = {**settings.recon.get("train", {}), "seed": args.seed}
    config = with_calibration(ReconConfig.model_validate({**settings.recon, "train": train}), scene, settings)
    problem, reference = calibrated_problem(data, config, clean)
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(problem, config, folder)
        fit = trainer.fit()
        mesh = extract_mesh(fit.field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution)
        head = _materials(trainer, fit, mesh, reference, scene, settings.seed)["objects"]
    network = fit.field.eval().sdf
    primitives = trainer.primitives
    peak = CoherentRenderer(data.measurements, data.image.grid).observed_peak
    frequency_hz = acquisition.center_frequency_hz
    truth = [obj.material.name for obj in scene.objects]
    true_gamma = class_reflectivities(tuple(truth), frequency_hz).numpy()
    exact = object_gains(scene, data.measurements, settings)[0] * peak
    readouts = {"network": object_gains(scene, data.measurements, settings,
                                        sdf=with_primitives(network, []))[0] * peak * true_gamma,
                "primitives": object_gains(scene, data.measurements, settings,
                                           sdf=with_primitives(network, primitives))[0] * peak * true_gamma}
    _, rows = _observed_objects(scene, acquisition, 0.002, 40_000, 0)
    objects, right = {}, {"head": 0, "network": 0, "primitives": 0}
    for i, (obj, (_, _, fraction)) in enumerate(zip(scene.objects, rows)):
        counted = counts(fraction, head[obj.name]["reference"])
        row = {"true": truth[i], "observed_fraction": fraction, "counted": counted, "exact_gain": float(exact[i]),
               "head": {"reflectivity": head[obj.name]["reflectivity"], "predicted": head[obj.name]["predicted"]}}
        for name, values in readouts.items():
            row[name] = {"reflectivity": float(values[i]),
                         "predicted": str(reflectivity_class(float(values[i]), config.field.materials, frequency_hz))}
        for name in right:
            right[name] += counted and row[name]["predicted"] == truth[i]
        objects[obj.name] = row
        print(f"{obj.name:<22}{truth[i]:<13}seen {fraction:.2f} " + "  ".join(
            f"{name} {row[name]['reflectivity']:.3f} {row[name]['predicted']:<12}" for name in right), flush=True)
    counted = sum(o["counted"] for o in objects.values())
    print(f"right of {counted}: {right}")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": args.scene, "radar": settings.radar, "seed": args.seed,
                            "primitives": [p.kind for p in primitives], "counted": counted, "right": right,
                            "metal_read_as_dielectric": {name: sum(o["true"] == "metal" and o["counted"]
                                                                   and o[name]["predicted"] != "metal"
                                                                   for o in objects.values()) for name in right},
                            "objects": objects}))


if __name__ == "__main__":
    main()
