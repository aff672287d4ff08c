"""What the CLEAN image shows of each object's surface, by how the views see it. Per object
of the default demo, its true surface (area-uniform samples) is split three ways: observed
(some view sees it within its bistatic cone, unshadowed: `radar.coverage.observed_mask`),
shadowed (it faces some view's cone but another object stands in the way) and facing no
view. For each part: its share of the object's surface, the CLEAN image's view-mean
amplitude at the voxel holding each sample (median, over the image's peak), and the share
the warm start's detection rule admits there (amplitude >= CLEAN's residual floor of the
peak and >= `[init] local_threshold` of the local peak). What the detection cannot admit,
the warm start cannot place, and the fit has only the data's silence to go on.

Usage: python benchmarks/unseen_surface.py [--samples 5000] [--out benchmarks/results/unseen_surface.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
import trimesh
from demo_data import demo_data

from rfsdf.jsonio import to_json
from rfsdf.radar.clean import clean_image
from rfsdf.radar.coverage import observed_mask
from rfsdf.radar.detection import amplitude_of, detection_level, window_voxels
from rfsdf.recon.config import InitConfig


def _part(amplitude: np.ndarray, admitted: np.ndarray, mask: np.ndarray) -> dict:
    return {"share": float(mask.mean()),
            "median_amplitude": float(np.median(amplitude[mask])) if mask.any() else None,
            "admitted": float(admitted[mask].mean()) if mask.any() else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=5000, help="true surface samples per object")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/unseen_surface.json"))
    args = parser.parse_args()

    data = demo_data()
    scene, grid, acquisition = data.scene, data.image.grid, data.measurements.acquisition
    clean = clean_image(data.measurements, grid)
    power, init = clean.power.numpy(), InitConfig()
    floor = clean.residual_floor()
    level = detection_level(power, threshold=floor, local_threshold=init.local_threshold,
                            window_voxels=window_voxels(init.window_m, grid))
    amplitude = amplitude_of(power)
    peak = float(amplitude.max())
    result = {"scene": scene.name, "radar": data.settings.radar, "residual_floor": floor,
              "local_threshold": init.local_threshold, "objects": {}}
    for obj, mesh in zip(scene.objects, scene.object_meshes()):
        points, faces = trimesh.sample.sample_surface(mesh, args.samples, seed=data.settings.seed)
        p, n = torch.as_tensor(np.asarray(points)), torch.as_tensor(np.asarray(mesh.face_normals[faces]))
        observed = observed_mask(p, n, acquisition, scene.sdf).numpy()
        facing = observed_mask(p, n, acquisition, None).numpy()
        voxel = np.clip(np.floor((np.asarray(points) - grid.lower_m) / grid.voxel_m).astype(int), 0,
                        np.array(grid.shape) - 1)
        at = tuple(voxel.T)
        relative, admitted = amplitude[at] / peak, amplitude[at] >= level[at]
        result["objects"][obj.name] = {
            "material": obj.material.name,
            "observed": _part(relative, admitted, observed),
            "shadowed": _part(relative, admitted, facing & ~observed),
            "facing_no_view": _part(relative, admitted, ~facing)}
        print(obj.name, to_json(result["objects"][obj.name]), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
