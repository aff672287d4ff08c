"""Where the predicted range peaks lie against the data's (`[loss] peak_match_weight`): along
the line of sight of every range peak the default warm start finds in the demo's data, the
vertex of the parabola through the renderer's image at five points within +-6 mm, for the
data and for a surface (`rfsdf.recon.losses.peak_offset`). Per surface: the share of lines
where both peak, and the distance between the two vertices (median, amplitude-weighted mean,
90th percentile). Surfaces: the truth, the truth moved by smooth normal errors of 0.5-4 mm
rms (20 mm correlation, the basin study's field), dilated by 1 and 2 mm, and the warm start;
every material known, the radar's gain held. Also the peaks' own signed distance to the
truth (the bias the held peaks keep, `[loss] peak_weight`).

Usage: python benchmarks/peak_match.py [--out benchmarks/results/peak-match.json]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.losses import peak_offset
from rfsdf.studies.basin import FixedSurface, TrueMaterials, smooth_displacement

SMOOTH_MM = (0.5, 1.0, 2.0, 4.0)
DILATION_MM = (1.0, 2.0)


def line_images(renderer, known, lines: torch.Tensor, view: torch.Tensor, sdf) -> torch.Tensor:
    """(N, S) complex: the renderer's image of the surface ``sdf`` at the points ``lines`` (N, S,
    3) [m] of each line's view ``view`` (N,), every material known (``known``, a TrueMaterials),
    the renderer's surface samples refreshed on ``sdf``."""
    per_view = [torch.nonzero(view == v).squeeze(1) for v in range(renderer.num_views)]
    with torch.no_grad():
        renderer.refresh(sdf, torch.Generator().manual_seed(0))
        classes = known(renderer.candidates.anchors)
        probabilities = torch.nn.functional.one_hot(classes, len(MATERIAL_CLASSES)).float()
        _, images = renderer(FixedSurface(sdf), torch.arange(renderer.num_views), torch.arange(1), geometry=False,
                             probabilities=probabilities,
                             lines=[lines[i].reshape(-1, 3) if len(i) else None for i in per_view])
    predicted = torch.zeros(lines.shape[:2], dtype=torch.complex64, device=lines.device)
    for index, image in zip(per_view, images):
        if image is not None:
            predicted[index] = image.reshape(len(index), -1)
    return predicted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/peak-match.json"))
    args = parser.parse_args()
    data = demo_data()
    scene = data.scene
    known = TrueMaterials(scene)
    problem = Problem(data.measurements, data.image.grid, image=data.image, gain=SIMULATED_GAIN, known_materials=known)
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(problem, ReconConfig.model_validate({"loss": {"peak_match_weight": 1.0}}), folder)
        trainer.warm_start()
    lines, observed, offsets = trainer.peak_lines()
    points, amplitude, view, _ = trainer.peaks
    with torch.no_grad():
        signed = scene.sdf(points.double()).float() * 1e3
    result = {"peaks": len(points), "peaks_signed_mm": {
        "median": float(signed.median()), "abs_median": float(signed.abs().median()),
        "abs_weighted": float((signed.abs() * amplitude).sum() / amplitude.sum())}}
    data_vertex, data_valid = peak_offset(observed.abs() ** 2, offsets)

    def residuals(sdf) -> dict[str, float]:
        predicted = line_images(trainer.renderer, known, lines, view, sdf)
        vertex, valid = peak_offset(predicted.abs() ** 2, offsets)
        both = valid & data_valid
        distance, weight = (vertex - data_vertex)[both].abs() * 1e3, amplitude[both]
        return {"valid": float(both.float().mean()), "median_mm": float(distance.median()),
                "weighted_mm": float((distance * weight).sum() / weight.sum()), "p90_mm": float(distance.quantile(0.9))}

    surfaces = {"truth": scene.sdf}
    smooth = smooth_displacement(scene, 0.02, torch.Generator().manual_seed(1))
    surfaces.update({f"smooth {mm} mm": (lambda p, mm=mm: scene.sdf(p) - mm * 1e-3 * smooth(p)) for mm in SMOOTH_MM})
    surfaces.update({f"dilated {mm} mm": (lambda p, mm=mm: scene.sdf(p) - mm * 1e-3) for mm in DILATION_MM})
    surfaces["warm start"] = trainer.field.sdf
    result["surfaces"] = {}
    for name, sdf in surfaces.items():
        result["surfaces"][name] = residuals(sdf)
        print(name, result["surfaces"][name], flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
