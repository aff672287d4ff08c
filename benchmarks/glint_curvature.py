"""How curved is a fitted sphere where each view sees its glint, and how bright does it render?

A sphere's specular return grows with its local radii of curvature at the glint, amplitude
~ sqrt(R1 R2) (the Fresnel zone's area), so a surface placed right but a little flat there
renders too bright, and a readout of |Gamma| from brightness reads it as the wrong material.
For one sphere object of the scene and each view, the renderer's facets (the fit's, on the
image grid) within ``PATCH_M`` of the true sphere's specular point towards the view's centre
are fitted with a quadric in the local tangent frame: its principal radii and its offset
along the normal there. The sphere's rendered power in the bright voxels (its true
material; object_brightness.py's voxels), in all and per view, is compared with the true
sphere's. Read for the run folder's warm start and its fit (a `rfsdf demo` output folder).

Usage: python benchmarks/glint_curvature.py rfsdf-demo [--object metal_ball]
       [--out benchmarks/results/glint-curvature.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch
from object_brightness import BRIGHT

from rfsdf.field import RadarField
from rfsdf.geometry import Grid, Sphere
from rfsdf.jsonio import to_json
from rfsdf.radar import read_measurements
from rfsdf.recon import CoherentRenderer
from rfsdf.recon.checkpoint import CHECKPOINT_NAME, read_checkpoint
from rfsdf.recon.primitive import PrimitiveField
from rfsdf.scene import load_scene
from rfsdf.scene_model import SceneModel

PATCH_M = 0.007  # the facets fitted around a glint: about the first Fresnel zone's radius on the demo's ball [m]


def glint_radii(anchors: np.ndarray, centre: np.ndarray, radius_m: float, towards: np.ndarray) -> list[dict | None]:
    """Per view (``towards`` (V, 3) [m], the views' centres): the quadric z(x, y) fitted to the
    ``anchors`` (N, 3) [m] within PATCH_M of the sphere's point facing the view, its principal
    radii [mm] (positive convex) and its offset along the normal [mm]; None where fewer than 20."""
    rows = []
    for look in towards:
        normal = (look - centre) / np.linalg.norm(look - centre)
        glint = centre + radius_m * normal
        near = anchors[np.linalg.norm(anchors - glint, axis=1) < PATCH_M] - glint
        if len(near) < 20:
            rows.append(None)
            continue
        e1 = np.cross(normal, [0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.cross(normal, [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)
        x, y, z = near @ e1, near @ e2, near @ normal
        c = np.linalg.lstsq(np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], 1), z, rcond=None)[0]
        curvatures = -np.linalg.eigvalsh(np.array([[2 * c[0], c[1]], [c[1], 2 * c[2]]]))  # z = -r^2 / 2R: +1/R
        rows.append({"radii_mm": sorted(float(1e3 / k) for k in curvatures), "offset_mm": float(1e3 * c[5])})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("folder", type=Path)
    parser.add_argument("--object", default="metal_ball")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/glint-curvature.json"))
    args = parser.parse_args()
    for name in ("demo-settings.json", "measurements.h5", f"run/{CHECKPOINT_NAME}"):
        if not (args.folder / name).is_file():
            raise SystemExit(f"{args.folder}: no {name}; is this a `rfsdf demo` output folder?")
    settings = json.loads((args.folder / "demo-settings.json").read_text())
    scene = load_scene(settings["scene"])
    names = [obj.name for obj in scene.objects]
    if args.object not in names or not isinstance(scene.objects[names.index(args.object)].sdf, Sphere):
        raise SystemExit(f"--object {args.object}: not a sphere of {settings['scene']} ({', '.join(names)})")
    k = names.index(args.object)
    sphere = scene.objects[k].sdf
    centre, radius_m = sphere.center.double().numpy(), float(sphere.radius)
    data = read_measurements(args.folder / "measurements.h5")
    renderer = CoherentRenderer(data, Grid.from_voxel(scene.lower_m, scene.upper_m, settings["voxel_m"]))
    truth = PrimitiveField(SceneModel.from_table(scene.spec.model_dump(mode="json"), f"{scene.name} (nothing free)"))
    voxels = (renderer.observed.abs().max(0).values >= BRIGHT).nonzero().squeeze(1)
    views = torch.arange(renderer.num_views)
    tx, rx = data.acquisition.view_centres()
    towards = (0.5 * (tx + rx)).double().numpy()

    def read(sdf) -> dict:
        renderer.refresh(sdf, torch.Generator().manual_seed(0))
        anchors = renderer.candidates.anchors.double()
        mine = scene.object_index(anchors) == k
        with torch.no_grad():
            image = torch.cat([renderer(truth, views, chunk, geometry=False,
                                        probabilities=truth.material(anchors).float() * mine.float()[:, None])
                               for chunk in voxels.split(1 << 14)], 1)
        rows = glint_radii(anchors[mine].numpy(), centre, radius_m, towards)
        means = [float(np.sqrt(np.prod(row["radii_mm"]))) for row in rows if row and min(row["radii_mm"]) > 0]
        view_powers = (image.abs() ** 2).sum(1)
        return {"power": float(view_powers.sum()), "view_powers": view_powers.tolist(), "views": rows,
                "mean_radius_mm": {"median": float(np.median(means)), "min": min(means), "max": max(means),
                                   "convex_views": len(means)},
                "offset_mm_median": float(np.median([row["offset_mm"] for row in rows if row])),
                "abs_offset_mm_median": float(np.median([abs(row["offset_mm"]) for row in rows if row]))}

    state = read_checkpoint(args.folder / "run" / CHECKPOINT_NAME, "cpu")
    result = {"folder": str(args.folder), "object": args.object, "radius_mm": 1e3 * radius_m, "patch_mm": 1e3 * PATCH_M,
              "truth": read(truth.sdf)}
    for key, label in (("warm_field", "warm_start"), ("field", "fit")):
        field = RadarField(**state["field_kwargs"])
        field.load_state_dict(state[key])
        result[label] = read(lambda p, field=field: field.sdf(p.float()).double())
        result[label]["power_over_truth"] = result[label]["power"] / result["truth"]["power"]
        result[label]["view_powers_over_truth"] = [mine / true for mine, true in
                                                   zip(result[label]["view_powers"], result["truth"]["view_powers"])]
    for label in ("truth", "warm_start", "fit"):
        row = result[label]
        print(f"{label:<10} sqrt(R1 R2) at the glints, median {row['mean_radius_mm']['median']:.1f} mm "
              f"({row['mean_radius_mm']['min']:.1f}-{row['mean_radius_mm']['max']:.1f}, "
              f"{row['mean_radius_mm']['convex_views']} of {sum(map(bool, row['views']))} views convex); offset "
              f"{row['offset_mm_median']:+.2f} mm median, |offset| {row['abs_offset_mm_median']:.2f}; "
              f"power {row.get('power_over_truth', 1.0):.2f}x the truth's")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
