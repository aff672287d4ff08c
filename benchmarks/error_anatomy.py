"""What a demo's observed-surface Chamfer is made of, method by method. The metric
(`rfsdf.metrics.evaluate_scene`) is half the *accuracy* of every sample of the predicted
surface (its distance to the true surface, wherever it lies) and half the
*completeness* of the true surface some view observes. So its accuracy half also scores the
predicted surface over true faces no view sees, which the data do not constrain. Split here:
the accuracy by where the predicted sample lies against the true solids (inside one by
more than ``--band-mm``: a back collapsed into the object or a sheet inside it; within the
band; outside by more: bloated faces and floaters) and by whether its nearest true sample
is seen, with each part's share of the samples and of the mean,
the floaters alone (connected components of the predicted mesh none of whose samples
comes within ``--floater-mm`` of a true surface), and the completeness of the seen surface by
object (mean and median), and that completeness, and the tilt of the nearest predicted
face's normal against the true one, again on the surface each view's cone
holds within tolerances narrower than the mask's 10 degrees (``--tolerances-deg``): the
tolerance is a cross-range cell's specular beamwidth, but a flat face larger than the cell
tilted beyond the cone returns only from its edges (its phase cancels across it), so what the
strict cone holds is the surface whose glints are in the data. Reads the meshes, settings
and measurements a demo folder holds; reconstructs nothing.

Usage: python benchmarks/error_anatomy.py DEMO_DIR [--out benchmarks/results/error-anatomy.json]
"""

from __future__ import annotations

import argparse
import json
import math
from functools import partial
from pathlib import Path
from typing import Iterable

import numpy as np
import torch
import trimesh

from rfsdf.jsonio import to_json
from rfsdf.metrics import nearest, to_surface, true_surface_samples
from rfsdf.radar import read_measurements
from rfsdf.radar.coverage import observed_mask
from rfsdf.scene import load_scene

METHODS = ("neural", "neural-warm-start", "clean-detection", "clean-threshold", "mf-threshold")
SAMPLES = 50_000  # as the demo's metrics, with the same seed: the same samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("folder", type=Path)
    parser.add_argument("--band-mm", type=float, default=2.0)
    parser.add_argument("--floater-mm", type=float, default=5.0)
    parser.add_argument("--tolerances-deg", type=float, nargs="*", default=[0.0, 2.5, 5.0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/error-anatomy.json"))
    args = parser.parse_args()
    settings = json.loads((args.folder / "demo-settings.json").read_text())
    scene = load_scene(settings["scene"])
    acquisition = read_measurements(args.folder / "measurements.h5").acquisition
    truth = TrueSurface(scene, acquisition, seed=settings.get("seed", 0), tolerances_deg=args.tolerances_deg)
    result = {"folder": str(args.folder), "scene": settings["scene"], "radar": settings["radar"],
              "band_mm": args.band_mm, "floater_mm": args.floater_mm,
              "seen_share_of_true_surface": float(truth.seen.mean()), "methods": {}}
    for method in METHODS:
        path = args.folder / f"{method}.ply"
        if path.exists():
            row = anatomy(trimesh.load(path, force="mesh"), truth, band_m=args.band_mm * 1e-3,
                          floater_m=args.floater_mm * 1e-3, seed=settings.get("seed", 0))
            result["methods"][method] = row
            print(method, to_json({k: row[k] for k in ("observed_chamfer_mm", "accuracy_mm", "completeness_seen_mm",
                                                       "accuracy_parts_mm")}, indent=None),
                  {t: round(part["all"]["mean"], 3) for t, part in row["completeness_seen_within_deg"].items()},
                  {t: round(tilt["median"], 1) for t, tilt in row["tilt_seen_within_deg"].items()}, flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


class TrueSurface:
    """Area-uniform samples of a scene's objects (as ``evaluate_scene`` draws them), their
    owner object and whether some view of ``acquisition`` observes them (``seen``; and
    ``seen_within`` {tolerance [deg]: (N,) bool} with the cone widened by each tolerance)."""

    def __init__(self, scene, acquisition, *, seed: int, tolerances_deg: Iterable[float] = ()):
        self.scene = scene
        self.points, self.normals, self.owner = true_surface_samples(scene, SAMPLES, seed)
        self.mesh = scene.ground_truth_mesh()
        seen = partial(observed_mask, torch.as_tensor(self.points), torch.as_tensor(self.normals), acquisition,
                       scene.sdf)
        self.seen = np.asarray(seen(), bool)
        self.seen_within = {t: np.asarray(seen(tolerance_rad=math.radians(t)), bool) for t in tolerances_deg}

    def signed_m(self, points: np.ndarray) -> np.ndarray:
        """(N,) the scene SDF [m] at ``points`` (N, 3): negative inside an object."""
        return self.scene.sdf(torch.as_tensor(points, dtype=torch.float64)).double().numpy()


def anatomy(mesh: trimesh.Trimesh, truth: TrueSurface, *, band_m: float, floater_m: float, seed: int) -> dict:
    """The observed Chamfer of ``mesh`` and its parts [mm] (see the module docstring)."""
    predicted, faces = trimesh.sample.sample_surface(mesh, SAMPLES, seed=seed)
    predicted = np.asarray(predicted)
    accuracy = to_surface(predicted, truth.mesh)[0]
    completeness, nearest_face = to_surface(truth.points, mesh)
    cosine = np.clip((mesh.face_normals[nearest_face] * truth.normals).sum(1), -1.0, 1.0)
    tilt_deg = np.degrees(np.arccos(cosine))  # the nearest predicted face's normal against the true one
    nearest_true = nearest(truth.points, predicted)[1]
    signed = truth.signed_m(predicted)
    parts = {"inside the true solids": signed < -band_m, "within the band": np.abs(signed) <= band_m,
             "outside the true solids": signed > band_m,
             "nearest a seen true sample": truth.seen[nearest_true], "nearest an unseen one": ~truth.seen[nearest_true]}
    component_of_face = np.empty(len(mesh.faces), int)
    for index, face_indices in enumerate(trimesh.graph.connected_components(mesh.face_adjacency,
                                                                           nodes=np.arange(len(mesh.faces)))):
        component_of_face[face_indices] = index
    component = component_of_face[faces]
    floating = np.isin(component, [c for c in np.unique(component)
                                   if np.abs(signed[component == c]).min() > floater_m])
    seen = completeness[truth.seen]
    objects = _by_object(completeness, truth.seen, truth)
    return {
        "observed_chamfer_mm": 0.5e3 * float(accuracy.mean() + seen.mean()),
        "accuracy_mm": _summary(accuracy),
        "completeness_seen_mm": _summary(seen),
        "accuracy_parts_mm": {name: {"share": float(mask.mean()), "of_the_mean": 1e3 * float(accuracy[mask].sum())
                                     / len(accuracy)} for name, mask in parts.items()},
        "floaters": {"share": float(floating.mean()),
                     "of_the_accuracy_mean_mm": 1e3 * float(accuracy[floating].sum()) / len(accuracy)},
        "completeness_seen_by_object": objects,
        "completeness_seen_within_deg": {f"{t:g}": {"share_of_true_surface": float(mask.mean()),
                                                    "all": _summary(completeness[mask]),
                                                    "by_object": _by_object(completeness, mask, truth)}
                                         for t, mask in truth.seen_within.items()},
        "tilt_seen_within_deg": {f"{t:g}": _tilt(tilt_deg[mask]) for t, mask in
                                 {**truth.seen_within, 10: truth.seen}.items()},
    }


def _by_object(completeness: np.ndarray, seen: np.ndarray, truth: TrueSurface) -> dict:
    """{object: mean and median [mm] of ``completeness`` over its ``seen`` samples, or None}."""
    objects = {}
    for index, obj in enumerate(truth.scene.objects):
        own = completeness[seen & (truth.owner == index)]
        objects[obj.name] = ({"mean_mm": 1e3 * float(own.mean()), "median_mm": 1e3 * float(np.median(own)),
                              "seen_samples": len(own)} if len(own) else None)
    return objects


def _tilt(degrees: np.ndarray) -> dict:
    """Median and 90th percentile [deg] of the tilts, and the share within a 4 cm face's
    specular lobe (lambda / L, 2.7 degrees, rounded up to 4: beyond it a flat face's glint
    leaves the views that see it)."""
    median, p90 = np.percentile(degrees, [50, 90])
    return {"median": float(median), "p90": float(p90), "within_4": float((degrees < 4).mean())}


def _summary(distances_m: np.ndarray) -> dict:
    q = np.percentile(distances_m, [50, 90, 99]) * 1e3
    return {"mean": 1e3 * float(distances_m.mean()), "median": float(q[0]), "p90": float(q[1]), "p99": float(q[2])}


if __name__ == "__main__":
    main()
