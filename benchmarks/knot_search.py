"""Can a global search find each patch's offset where descent cannot? The stage
``benchmarks/descent_direction.py`` asked for, tested one knot at a time: from the demo's true
surface displaced by a smooth error carried exactly by knots ``--knot-m`` apart (the basin
study's 20 mm field read at the knots, rms ``--error-mm``; every material and the radar's
gain known), each of the ``--knots`` knots with the most data energy near it is moved alone
by each offset of +-``--span-mm`` in 0.5 mm steps: its tent's facets (trilinear weight w > 0)
moved along their normals by delta w and tilted by -delta grad w, their predicted data's
change added to the images at the tent's voxels (the rest of the image is the same
rendering; superposition, as the renderer's sum over facets is linear), and each loss's share
there summed with the weights w; the knot takes the offset of the lowest sum. The rest of
the surface held at the start (a search's first sweep) or at the truth (the best a sweep
could hope for): how far the chosen offsets lie from the truth's, against the start's error.

Usage: python benchmarks/knot_search.py [--error-mm 2] [--span-mm 4] [--knots 30] [--radar near-77g] [--out FILE]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from rfsdf.field import KnotDisplacement
from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES, mixture_fresnel
from rfsdf.recon.losses import DATA_LOSSES
from rfsdf.studies import basin

STEP_MM = 0.5
MIN_FACETS = 20  # a knot whose tent holds fewer facets moves too little surface to be scored


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--error-mm", type=float, default=2.0)
    parser.add_argument("--span-mm", type=float, default=4.0)
    parser.add_argument("--knots", type=int, default=30)
    parser.add_argument("--knot-m", type=float, default=0.015)
    parser.add_argument("--radar", default=basin.Settings.radar)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/knot-search.json"))
    args = parser.parse_args()
    settings = basin.Settings(device="cpu", radar=args.radar)
    scene, losses = basin.surface_losses(settings)
    knots = KnotDisplacement(scene.lower_m, scene.upper_m, args.knot_m)
    field = basin.smooth_displacement(scene, settings.correlation_m, torch.Generator().manual_seed(settings.seed))
    with torch.no_grad():  # the correction the truth needs at each knot; the start is the truth minus it
        needed = -args.error_mm * 1e-3 * field(knots.grid.points()).reshape(knots.grid.shape)
        knots.offsets_m.copy_(needed)
    voxels = losses.renderer.voxels[losses.voxels]
    energy = _per_knot(knots, voxels, (losses.renderer.observed[:, losses.voxels].abs() ** 2).sum(0))
    offsets_mm = np.arange(-args.span_mm, args.span_mm + 1e-9, STEP_MM)
    rows = {}
    for held, surface in (("the start", lambda p: scene.sdf(p) + knots(p)), ("the truth", scene.sdf)):
        clock = time.perf_counter()
        search = _KnotSearch(losses, surface, voxels)
        chosen = []
        for k in energy.argsort(descending=True).tolist():
            sums = search.sweep(knots, k, offsets_mm * 1e-3 - (0.0 if held == "the start" else float(needed.view(-1)[k])))
            if sums is None:
                continue
            truth_mm = float(needed.view(-1)[k]) * 1e3
            chosen.append({"knot": k, "truth_mm": truth_mm,
                           **{name: float(offsets_mm[int(np.argmin(s))]) for name, s in sums.items()}})
            print(held, to_json(chosen[-1], indent=None), f"{time.perf_counter() - clock:.0f} s", flush=True)
            if len(chosen) == args.knots:
                break
        truth = np.array([c["truth_mm"] for c in chosen])
        summary = {name: {"median_miss_mm": float(np.median(np.abs([c[name] for c in chosen] - truth))),
                          "share_within_0.5_mm": float(np.mean(np.abs([c[name] for c in chosen] - truth) <= 0.5))}
                   for name in ("amplitude", "split", "complex")}
        rows[f"the rest held at {held}"] = {"start_median_error_mm": float(np.median(np.abs(truth))),
                                            "losses": summary, "knots": chosen, "seconds": time.perf_counter() - clock}
        print(held, to_json(summary, indent=None), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"error_mm": args.error_mm, "knot_m": args.knot_m, "step_mm": STEP_MM,
                                 "span_mm": args.span_mm, "rows": rows}))


def _per_knot(knots: KnotDisplacement, points: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """(knots,) sum_x w_k(x) values(x): ``values`` (X,) at ``points`` (X, 3) [m] summed into
    each knot with its trilinear weights (the gradient of sum_x d(x) values(x))."""
    offsets = knots.offsets_m.detach().clone().requires_grad_(True)
    total = (torch.func.functional_call(knots, {"offsets_m": offsets}, (points,)) * values).sum()
    return torch.autograd.grad(total, offsets)[0].flatten()


def _tent(knots: KnotDisplacement, k: int, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Knot k's trilinear weight w at ``points`` (X, 3) [m], (X,), and its gradient there, (X, 3) [1/m]."""
    one = torch.zeros(knots.grid.shape)
    one.view(-1)[k] = 1.0
    points = points.detach().clone().requires_grad_(True)
    weight = torch.func.functional_call(knots, {"offsets_m": one}, (points,))
    return weight.detach(), torch.autograd.grad(weight.sum(), points)[0]


class _KnotSearch:
    """One surface rendered once (every view, every shown voxel), then each knot's tent moved
    alone on top of it by superposition."""

    def __init__(self, losses: basin.SurfaceLosses, sdf, voxels: torch.Tensor):
        renderer = self.renderer = losses.renderer
        self.voxels, self.index, self.scale = voxels, losses.voxels, losses.gain / renderer.observed_peak
        surface = basin.FixedSurface(sdf)
        with torch.no_grad():
            renderer.refresh(sdf, torch.Generator().manual_seed(0))
            self.probabilities = torch.nn.functional.one_hot(losses.known(renderer.candidates.anchors),
                                                             len(MATERIAL_CLASSES)).float()
            self.images = renderer(surface, torch.arange(renderer.num_views), self.index, geometry=False,
                                   probabilities=self.probabilities, bands=True) * self.scale  # (V, 2, X)
        self.facets = renderer.surface_geometry(surface, geometry=False)  # points, normals, areas, corners
        whole, observed = renderer.full_band(self.images), renderer.observed[:, self.index]
        inner = (whole.conj() * observed).sum(1, keepdim=True)
        self.turn = inner / inner.abs()  # the complex loss's phase per view, held while one knot moves
        self.permittivities = renderer.class_permittivities(MATERIAL_CLASSES)

    def sweep(self, knots: KnotDisplacement, k: int, deltas_m) -> dict[str, list[float]] | None:
        """Each loss summed over knot k's tent with its weights, its facets moved by each of
        ``deltas_m`` [m] from where the rendered surface has them; None for too few facets."""
        renderer, (points, normals, area, corners) = self.renderer, self.facets
        weight, slope = _tent(knots, k, points)
        moving = (weight > 1e-3).nonzero().squeeze(1)
        local = (_tent(knots, k, self.voxels)[0] > 1e-3).nonzero().squeeze(1)
        if len(moving) < MIN_FACETS or len(local) == 0:
            return None
        voxel_weight = _tent(knots, k, self.voxels[local])[0]
        observed = renderer.band_observed[:, :, self.index[local]]
        sums = {"amplitude": [], "split": [], "complex": []}
        for delta in deltas_m:
            images = self.images[:, :, local].clone()
            with torch.no_grad():
                for view in range(renderer.num_views):
                    lit = moving[renderer.lit[view, moving]]
                    if len(lit) == 0:
                        continue
                    reflection = lambda cos, i=lit: mixture_fresnel(cos, self.probabilities[i],  # noqa: E731
                                                                    self.permittivities).to(torch.complex64)
                    moved = renderer.predict_data(view, points[lit] + delta * weight[lit, None] * normals[lit],
                                                  torch.nn.functional.normalize(normals[lit] - delta * slope[lit], dim=1),
                                                  area[lit], reflection, corners[lit])
                    held = renderer.predict_data(view, points[lit], normals[lit], area[lit], reflection, corners[lit])
                    images[view] += self.scale * renderer._band_images(view, moved - held, self.voxels[local],
                                                                       self.index[local])
            whole, observed_whole = renderer.full_band(images), renderer.full_band(observed)
            shares = {"amplitude": DATA_LOSSES.get("amplitude")(whole, observed_whole, fit_gain=False, per_voxel=True),
                      "split": DATA_LOSSES.get("split")(images, observed, fit_gain=False, per_voxel=True),
                      "complex": ((self.turn * whole - observed_whole).abs() ** 2).sum(0)}
            for name, share in shares.items():
                sums[name].append(float((voxel_weight * share).sum()))
        return sums


if __name__ == "__main__":
    main()
