"""How far the optimum of the GeRaF loss sits from the truth: f is pre-fitted to the *true*
SDF of the default demo scene, the default fit then runs on the demo's data, and the mesh
is scored before and after (and each object's median signed distance, + outward: which way
the fit moves it). A renderer that models the data exactly would stay at the start; the
drift measures what the renderer's approximations (and the optimiser's noise) cost.

Usage: python benchmarks/model_bias.py [--out benchmarks/results/model_bias.json]
       [--recon '{"train": {"geometry_delay": 0}}']   (reconstruction settings over the defaults)
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.jsonio import to_json
from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_mesh, evaluate_scene
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.warm_start import fit_to_image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/model_bias.json"))
    parser.add_argument("--recon", type=json.loads, default={}, help="ReconConfig overrides (JSON tables).")
    args = parser.parse_args()

    data = demo_data()
    demo, scene, grid = data.settings, data.scene, data.image.grid
    # The truth replaces the image warm start: method "sphere" makes fit() skip its own.
    config = ReconConfig.model_validate({**args.recon, "init": {**args.recon.get("init", {}), "method": "sphere"}})
    ic = config.init

    def score(field) -> dict:
        mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, demo.mesh_resolution)
        objects = evaluate_scene(mesh, scene, samples=demo.metric_samples).objects
        return {**evaluate_mesh(mesh, scene, samples=demo.metric_samples).as_dict(),
                "bias_mm": {name: m.bias_mm for name, m in objects.items()}}

    with tempfile.TemporaryDirectory() as run:
        trainer = Trainer(Problem(data.measurements, grid), config, run)
        fit_to_image(trainer.field, grid.lower_m, grid.upper_m, scene.sdf, None, steps=3 * ic.steps, lr=ic.lr,
                     batch=ic.batch, eikonal_weight=ic.eikonal_weight, generator=torch.Generator().manual_seed(0))
        start = score(trainer.field)
        fit = trainer.fit()
        end = score(fit.field)
    result = {"steps": config.train.steps, "recon_overrides": args.recon, "start_from_truth": start, "after_fit": end,
              "drift_chamfer_mm": end["chamfer_l1_mm"] - start["chamfer_l1_mm"]}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
