"""Is the coherent renderer's brightness of one object against another the data's, given
the true geometry and materials? (The materials issue's readout reads |Gamma| from those ratios.)

The scene is simulated (the demo's settings), the renderer's surface samples are drawn from
the scene's exact SDF (a PrimitiveField of the scene with nothing free, each sample its
object's true material), and the predicted image of each object alone is rendered at the
bright voxels of every view. The data's powers are then split over the objects by
non-negative least squares, |o|^2 ~ sum_i a_i^2 |p_i|^2 (the calibration's split, per
object): a_i / a_ref is how much brighter than the renderer the data want object i,
relative to the reference. 1 everywhere means the renderer's amplitude model is right and
a material readout can only fail through the fitted geometry.

Usage: python benchmarks/object_brightness.py [--scene benchmarks/scenes/counter.toml]
       [--reference calibration_sphere] [--out benchmarks/results/object-brightness-counter.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from rfsdf.demo import DemoSettings
from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar, simulate
from rfsdf.recon import CoherentRenderer
from rfsdf.recon.calibration import BRIGHT, split_powers
from rfsdf.recon.primitive import PrimitiveField
from rfsdf.scene import load_scene
from rfsdf.scene_model import SceneModel



def object_gains(scene, data, settings: DemoSettings, sdf=None, sample_seed: int | None = None
                 ) -> tuple[np.ndarray, int]:
    """(objects,) a_i, how much brighter than the renderer the data want each object of
    ``scene`` by the NNLS split of the bright voxels' powers, and how many voxels those were. The renderer's surface samples
    lie on ``sdf`` ((N, 3) -> (N,) [m]; default the scene's exact SDF, a surface with errors
    otherwise), each reflecting by its own object's true material, drawn with ``sample_seed``
    (default the demo's seed)."""
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    renderer = CoherentRenderer(data, grid)
    field = PrimitiveField(SceneModel.from_table(scene.spec.model_dump(mode="json"), f"{scene.name} (nothing free)"))
    sdf = sdf or field.sdf
    renderer.refresh(sdf, torch.Generator().manual_seed(settings.seed if sample_seed is None else sample_seed))
    anchors = renderer.candidates.anchors.double()
    probabilities = field.material(anchors).float()
    with torch.no_grad():
        owner = torch.stack([obj.sdf(anchors) for obj in scene.objects]).abs().argmin(0)
    index = (renderer.observed.abs().max(0).values >= BRIGHT).nonzero().squeeze(1)
    views = torch.arange(renderer.num_views)

    def image(mask: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            return torch.cat([renderer(field, views, chunk, geometry=False, probabilities=probabilities * mask[:, None])
                              for chunk in index.split(1 << 14)], dim=1)

    parts = [image((owner == i).float()) for i in range(len(scene.objects))]
    return split_powers(parts, renderer.observed[:, index].abs()), len(index)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="benchmarks/scenes/counter.toml")
    parser.add_argument("--reference", default="calibration_sphere")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/object-brightness-{Path(args.scene).stem}.json")
    settings = DemoSettings()
    scene = load_scene(args.scene)
    data = simulate(scene, load_radar(settings.radar), seed=settings.seed, max_samples=settings.max_surface_samples)
    gains, bright = object_gains(scene, data, settings)
    names = [obj.name for obj in scene.objects]
    reference = gains[names.index(args.reference)]
    rows = {name: float(gain / reference) for name, gain in zip(names, gains)}
    for name, ratio in rows.items():
        print(f"{name:<22} the data want {ratio:.2f} x the renderer's brightness (relative to {args.reference})")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": args.scene, "reference": args.reference, "bright_voxels": bright,
                            "want_relative_to_reference": rows}))


if __name__ == "__main__":
    main()
