"""The fit's data loss around the truth, one object at a time: why the fit loses the metal ball.

Render the *true* scene through the fit's own coherent renderer (its surface sampler, the
true normal-incidence Fresnel amplitude of each object's material as Gamma), dilate one
object by d (its SDF minus d; every other object stays true) and score the rendered images
with the fit's amplitude loss on the voxels within 30 mm of that object, all views, for
several surface-sampling seeds. The curve over d is the landscape a fit descends when
that object's size is wrong; the spread over seeds is the noise a fit sees between
refreshes of its samples (the renderer's own sampling speckle).

Usage: python benchmarks/object_landscape.py [--objects metal_ball wood_block]
           [--out benchmarks/results/object_landscape.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from demo_data import demo_data
from tqdm import tqdm

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.materials import fresnel
from rfsdf.recon import CoherentRenderer, ReconConfig, amplitude_loss

DILATIONS_MM = tuple(np.arange(-3.0, 3.01, 0.5))
SEEDS = 2
NEAR_M = 0.03  # voxels this close to the object's surface are scored


class DilatedScene:
    """A field for the renderer: the true scene with object ``index`` dilated by ``dilation_m``,
    and each object's normal-incidence Fresnel amplitude as its reflectivity."""

    def __init__(self, scene, index: int, dilation_m: float, carrier_hz: float):
        self.scene, self.index, self.dilation_m = scene, index, dilation_m
        self.gamma = torch.tensor([float(fresnel(torch.tensor(0.0), o.material.permittivity(carrier_hz)).abs())
                                   for o in scene.objects])

    def _values(self, points: torch.Tensor) -> torch.Tensor:
        values = torch.stack([o.sdf(points) for o in self.scene.objects])
        offset = torch.zeros(len(values), 1, dtype=values.dtype)
        offset[self.index] = self.dilation_m
        return values - offset

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        return self._values(points).min(0).values

    def reflectivity(self, points: torch.Tensor) -> torch.Tensor:
        return self.gamma.to(points)[self._values(points).argmin(0)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--objects", nargs="+", default=["metal_ball", "wood_block"])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/object_landscape.json"))
    args = parser.parse_args()

    data = demo_data()
    scene, settings = data.scene, data.settings
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    renderer = CoherentRenderer(data.measurements, grid, element_step=ReconConfig().render.element_step)
    observed = renderer.observed.abs()
    views = torch.arange(renderer.num_views)
    carrier_hz = float(data.measurements.acquisition.frequencies_hz.mean())
    names = [o.name for o in scene.objects]
    result = {"dilations_mm": list(DILATIONS_MM), "seeds": SEEDS, "near_mm": NEAR_M * 1e3,
              "wavelength_mm": data.measurements.acquisition.wavelength_m * 1e3, "objects": {}}
    for name in args.objects:
        index = names.index(name)
        near = (scene.objects[index].sdf(renderer.voxels).abs() < NEAR_M).nonzero().squeeze(1)
        losses = np.zeros((len(DILATIONS_MM), SEEDS))
        for i, d in enumerate(tqdm(DILATIONS_MM, desc=name)):
            field = DilatedScene(scene, index, d / 1e3, carrier_hz)
            with torch.no_grad():
                for seed in range(SEEDS):
                    renderer.refresh(field.sdf, torch.Generator().manual_seed(seed))
                    losses[i, seed] = float(amplitude_loss(renderer(field, views, near), observed[:, near]))
        mean = losses.mean(1)
        result["objects"][name] = {"loss_mean": mean.round(4).tolist(), "loss_seed_std": losses.std(1).round(4).tolist(),
                                   "best_dilation_mm": DILATIONS_MM[int(mean.argmin())]}
        print(name, " ".join(f"{d:+.1f}:{m:.3f}" for d, m in zip(DILATIONS_MM, mean)))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
