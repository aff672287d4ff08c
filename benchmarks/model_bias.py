"""How far the optimum of the GeRaF loss sits from the truth, per renderer: f is pre-fitted to
the *true* SDF of the default demo scene, the default fit then runs on the demo's MF image,
and the mesh is scored before and after. A renderer that models the data exactly would stay
at the start; the drift measures what the renderer's approximations cost.

Usage: python benchmarks/model_bias.py [--renderer physics|local] [--out benchmarks/results/bias-RENDERER.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.mesh import extract_mesh
from rfsdf.metrics import evaluate_mesh
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.warm_start import fit_to_image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--renderer", choices=("physics", "local"), default="physics")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/bias-{args.renderer}.json")

    data = demo_data()
    demo, scene, measurements, grid = data.settings, data.scene, data.measurements, data.image.grid
    problem = Problem.from_image(data.image, measurements.acquisition)
    # The truth replaces the image warm start: method "sphere" makes fit() skip its own.
    config = ReconConfig.model_validate({"render": {"renderer": args.renderer}, "init": {"method": "sphere"}})
    ic = ReconConfig().init

    def score(field) -> dict:
        mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, demo.mesh_resolution)
        return evaluate_mesh(mesh, scene, samples=demo.metric_samples).as_dict()

    with tempfile.TemporaryDirectory() as run:
        trainer = Trainer(problem, config, run)
        truth = scene.sdf(grid.points()).float()
        fit_to_image(trainer.field, grid.points(), truth, None, steps=ic.steps,
                        lr=ic.lr, batch=ic.batch, eikonal_weight=config.loss.eikonal_weight,
                        generator=torch.Generator().manual_seed(0))
        start = score(trainer.field)
        end = score(trainer.fit())
    result = {"renderer": args.renderer, "steps": config.train.steps, "start_from_truth": start, "after_fit": end}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
