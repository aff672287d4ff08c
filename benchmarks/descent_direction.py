"""Does the fit's gradient point at the truth? From the demo's true surface displaced by the
basin study's smooth error (20 mm correlation, rms ``--errors-mm``), with every material and
the radar's gain known: each data loss over every view and every voxel some view shows
(the basin study's :class:`~rfsdf.studies.basin.SurfaceLosses`) along the straight path to the
truth (the error scaled by 1, 0.5 and 0), and each loss's exact gradient in a coarse
displacement of the surface (:class:`~rfsdf.field.displacement.KnotDisplacement`, knots
``--knot-m`` apart, the fewest degrees of freedom a fit of a smooth error needs) against the
correction the truth needs there: their cosine, the share of the knots (weighted by |gradient|)
where the two agree in sign (0.5: no better than a coin), and the loss after steps along the
gradient (its largest knot moved 0.25, 0.5, 1 mm).

Usage: python benchmarks/descent_direction.py [--errors-mm 0.5,1] [--knot-m 0.015] [--radar near-77g] [--out FILE]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from rfsdf.field import KnotDisplacement
from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.studies import basin

LOSSES = ("amplitude", "split", "complex")
STEPS_M = (0.25e-3, 0.5e-3, 1e-3)


class DisplacedSurface(torch.nn.Module):
    """f(p) = start(p) - d(p): a start surface and a coarse displacement d of it, zero at first."""

    materials = MATERIAL_CLASSES

    def __init__(self, start, lower_m, upper_m, knot_m: float):
        super().__init__()
        self.start = start
        self.displacement = KnotDisplacement(lower_m, upper_m, knot_m)

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        return self.start(points) - self.displacement(points)


def _misfit(name: str, predicted: torch.Tensor, observed: torch.Tensor) -> torch.Tensor:
    """The numerator of each data loss (``rfsdf.recon.losses``, the gain known) over one
    view's voxels: predicted and observed (1, X), or (1, 2, X) for ``split``."""
    if name == "amplitude":
        return ((predicted.abs() - observed.abs()) ** 2).sum()
    if name == "split":
        predicted, observed = predicted[:, 0] * predicted[:, 1].conj(), observed[:, 0] * observed[:, 1].conj()
        return ((predicted - observed).abs() ** 2).sum()
    with torch.no_grad():  # complex: each view turned by its best phase, held for the gradient
        inner = (predicted.conj() * observed).sum()
        turn = inner / inner.abs()
    return ((turn * predicted - observed).abs() ** 2).sum()


def gradient(losses: basin.SurfaceLosses, surface: DisplacedSurface, name: str, known) -> torch.Tensor:
    """d loss / d (the knots' offsets), every view and every shown voxel, the surface meshed afresh."""
    renderer, voxels, split = losses.renderer, losses.voxels, name == "split"
    renderer.refresh(surface.sdf, torch.Generator().manual_seed(0))
    probabilities = torch.nn.functional.one_hot(known(renderer.candidates.anchors), len(MATERIAL_CLASSES)).float()
    observed = renderer.band_observed[:, :, voxels] if split else renderer.observed[:, voxels]
    denominator = (((observed[:, 0] * observed[:, 1].conj()) if split else observed).abs() ** 2).sum()
    surface.zero_grad()
    for view in range(renderer.num_views):
        predicted = renderer(surface, torch.tensor([view]), voxels, probabilities=probabilities, bands=split)
        predicted = predicted * (SIMULATED_GAIN / renderer.observed_peak)
        (_misfit(name, predicted, observed[view:view + 1]) / denominator).backward()
    return surface.displacement.offsets_m.grad.clone()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--errors-mm", default="0.5,1")
    parser.add_argument("--knot-m", type=float, default=0.015)
    parser.add_argument("--radar", default=basin.Settings.radar)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/descent-direction.json"))
    args = parser.parse_args()
    settings = basin.Settings(device="cpu", radar=args.radar)
    scene, losses = basin.surface_losses(settings)
    known = losses.known
    error_field = basin.smooth_displacement(scene, settings.correlation_m, torch.Generator().manual_seed(0))
    rows = []
    for error_mm in (float(e) for e in args.errors_mm.split(",")):
        clock = time.perf_counter()
        error = error_mm * 1e-3
        path = {share: losses(lambda p, e=share * error: scene.sdf(p) - e * error_field(p)) for share in (1.0, 0.5, 0.0)}
        surface = DisplacedSurface(lambda p: scene.sdf(p) - error * error_field(p), scene.lower_m, scene.upper_m,
                                   args.knot_m)
        knots = surface.displacement.grid.points()
        with torch.no_grad():
            correction = -error * error_field(knots).reshape(surface.displacement.grid.shape)  # d that gives the truth
        per_loss = {}
        for name in LOSSES:
            g = gradient(losses, surface, name, known)
            used = g.abs() > 1e-3 * g.abs().max()
            descent, needed = -g[used], correction[used]
            stepped = []
            for step_m in STEPS_M:
                with torch.no_grad():
                    surface.displacement.offsets_m.copy_(step_m * -g / g.abs().max())
                    stepped.append({"largest_step_mm": step_m * 1e3, "loss": losses(surface.sdf)[name]})
                    surface.displacement.offsets_m.zero_()
            per_loss[name] = {
                "cosine": float((descent * needed).sum() / (descent.norm() * needed.norm())),
                "sign_agreement": float((descent.sign() == needed.sign()).float().mul(descent.abs()).sum()
                                        / descent.abs().sum()),
                "knots": int(used.sum()), "along_gradient": stepped}
            print(error_mm, name, to_json(per_loss[name], indent=None), flush=True)
        rows.append({"error_mm": error_mm, "path": {f"{share:g} of the error": v for share, v in path.items()},
                     "gradient": per_loss, "seconds": time.perf_counter() - clock})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"knot_m": args.knot_m, "rows": rows}))


if __name__ == "__main__":
    main()
