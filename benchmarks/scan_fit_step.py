"""A fit step on a scan: the renderer's two fast paths against their plain references, in one run.

The scanned demo (preset ``sar-77g``, scene ``handheld``: four 33 x 33 scans, the renderer's
every 4th frame and frequency, 69 frames x 4 Rx x 16 frequencies a view) spends its fit in
two places a MIMO view hardly feels:

- **the Fresnel mixture of every facet in every frame**: a scan's frames see a facet from
  up to some 15 degrees apart, so each of them reflects it at its own incidence angle, five
  classes, two polarisations, complex128 square roots, and their gradients. The reference is
  the closed form (``materials.mixture_fresnel``); the renderer reads a table
  (``materials.FresnelTable``).
- **the sub-band images of the split loss**: the reference forms each band's adjoint apart
  (the data masked, B adjoints); the renderer sums the bands out of one adjoint
  (``SensingOperator.adjoint(..., bands=)``).

Each pair is timed on the same surface (the facets of a fitted field's zero set, or of the warm
start's sphere without ``--run``), forward and backward (the Fresnel pair's gradients in the
class probabilities and in the normals, which a step with f free takes), and compared: seconds, their
ratio, and the relative difference of what they compute. Then whole fit steps of the
renderer as it is, f held (the first 70 % of the demo's steps) and free with the split
loss (the rest).

Usage: python benchmarks/scan_fit_step.py [--data DEMO/measurements.h5] [--run DEMO/run]
       [--out benchmarks/results/scan-fit-step.json]
(without --data the scene is simulated first, 2-4 minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from rfsdf.demo import demo_grid, demo_settings, load_scene_and_radar
from rfsdf.jsonio import to_json
from rfsdf.materials import mixture_fresnel
from rfsdf.radar import simulate
from rfsdf.radar.io import read_measurements
from rfsdf.recon import ReconConfig, load_field
from rfsdf.recon.render import CoherentRenderer
from rfsdf.recon.trainer import initial_field

BANDS = 4  # the split loss's
VOXELS = 4096  # a step's data batch


def _timed(function):
    """(result, wall seconds) of ``function()``."""
    clock = time.perf_counter()
    result = function()
    return result, time.perf_counter() - clock


def _relative(a: torch.Tensor, b: torch.Tensor) -> float:
    return float((a - b).detach().norm() / b.detach().norm())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", type=Path, help="a sar-77g demo's measurements.h5 (default: simulate)")
    parser.add_argument("--run", type=Path, help="a run folder whose checkpoint's field gives the surface")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-fit-step.json"))
    args = parser.parse_args()
    settings = demo_settings("sar-77g")
    inputs = load_scene_and_radar(settings.scene, settings.radar)
    scene = inputs.scene
    if args.data is not None:
        measurements = read_measurements(args.data)
    else:
        measurements = simulate(scene, inputs.radar, seed=settings.seed, max_samples=settings.max_surface_samples)
    grid = demo_grid(scene.lower_m, scene.upper_m, measurements.acquisition, settings.voxel_m)
    config = ReconConfig.model_validate(settings.recon)
    field = load_field(args.run) if args.run is not None else initial_field(grid, config, "cpu")
    rc = config.render
    renderer, build_s = _timed(lambda: CoherentRenderer(measurements, grid, element_step=rc.element_step,
                                                        frequency_step=rc.frequency_step, bands=BANDS))
    renderer.refresh(field.sdf, torch.Generator().manual_seed(0))
    generator = torch.Generator().manual_seed(0)
    voxels = torch.randperm(len(renderer.voxels), generator=generator)[:VOXELS]
    targets = renderer.voxels[voxels]
    views = range(renderer.num_views)
    points, normals, area, corners = renderer.surface_geometry(field, geometry=False)
    probabilities = renderer.surface_materials(field, geometry=False).detach()
    table = renderer.fresnel_table(tuple(field.materials))
    eps = renderer.class_permittivities(field.materials)

    def reflected(mixture):
        """Every view's data of the lit facets with ``mixture``, and their gradient in the
        class probabilities and the normals (which turn each frame's incidence angle)."""
        p, n = probabilities.clone().requires_grad_(True), normals.clone().requires_grad_(True)
        data = []
        for v in views:
            lit = renderer.lit[v]
            data.append(renderer.predict_data(v, points[lit], n[lit], area[lit],
                                              lambda cos, lit=lit: mixture(cos, p[lit]), corners[lit]))
        sum(y.abs().sum() for y in data).backward()
        return [y.detach() for y in data], torch.cat([p.grad.ravel(), n.grad.ravel()])

    (exact, exact_grad), exact_s = _timed(lambda: reflected(
        lambda cos, p: mixture_fresnel(cos, p, eps).to(torch.complex64)))
    (data, tabulated_grad), table_s = _timed(lambda: reflected(table.mixture))  # the band images' data too

    def band_images(one_pass: bool):
        """Each view's sub-band images at the batch's voxels, and their gradient in the data."""
        ys = [y.clone().requires_grad_(True) for y in data]
        masks = renderer.band_masks.to(torch.float32)
        images = [renderer.operators[v].adjoint(ys[v], targets, bands=masks) if one_pass else
                  torch.stack([renderer.operators[v].adjoint(ys[v] * mask, targets) for mask in masks])
                  for v in views]
        sum(image.abs().sum() for image in images).backward()
        return torch.stack(images), torch.cat([y.grad.ravel() for y in ys])

    (separate, separate_grad), separate_s = _timed(lambda: band_images(False))
    (together, together_grad), together_s = _timed(lambda: band_images(True))

    def step(free: bool) -> float:
        field.zero_grad(set_to_none=True)
        chosen = torch.arange(renderer.num_views)
        clock = time.perf_counter()
        p = renderer.surface_materials(field, geometry=free)
        predicted = renderer(field, chosen, voxels, geometry=free, probabilities=p, bands=free)
        predicted.abs().sum().backward()
        return round(time.perf_counter() - clock, 2)

    result = {
        "threads": torch.get_num_threads(), "surface": "fitted field" if args.run else "warm start's sphere",
        "facets": len(renderer.candidates), "view_shape": list(renderer.operators[0].acq.shape),
        "renderer_build_s": round(build_s, 2),
        "fresnel": {"closed_form_s": round(exact_s, 2), "table_s": round(table_s, 2),
                    "speedup": round(exact_s / table_s, 2),
                    "data_relative_difference": _relative(torch.cat([y.ravel() for y in data]),
                                                          torch.cat([y.ravel() for y in exact])),
                    "gradient_relative_difference": _relative(tabulated_grad, exact_grad)},
        "bands": {"separate_adjoints_s": round(separate_s, 2), "one_adjoint_s": round(together_s, 2),
                  "speedup": round(separate_s / together_s, 2),
                  "image_relative_difference": _relative(together, separate),
                  "gradient_relative_difference": _relative(together_grad, separate_grad)},
        "step_f_held_s": step(False), "step_f_free_split_s": step(True),
    }
    print(to_json(result))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result) + "\n")


if __name__ == "__main__":
    main()
