"""Does the fit's renderer predict a scan as the simulator measures it? The preset ``sar-77g``
simulates each frame's scattering from that frame's own phase centres (lobe, Fresnel angle),
and so does the renderer (since the thirtieth session; before, one set of reflectivities
for all of a scan's frames, seen from its centre, rendered the true scene 12-19 % dimmer
than the data). This renders the true scene (its exact shapes and catalogue materials, as a
primitive model with nothing free) through the renderer and compares each view's predicted
image with the data's: correlation |<p, o>| / |p| |o| over the grid and the amplitude ratio
|p| / |o|, for the thinnings a fit would use. The default radar's demo scene is the
reference (MIMO views of one frame each).

Usage: python benchmarks/scan_model.py [--scene handheld] [--radar sar-77g] [--out benchmarks/results/scan-model.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import torch

from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar, simulate
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.radar.scan_imaging import lattice_grid
from rfsdf.recon.primitive import PrimitiveField
from rfsdf.recon.render import CoherentRenderer
from rfsdf.scene import load_scene
from rfsdf.scene_model import SceneModel

THINNINGS = ((2, 1), (4, 1), (4, 4))  # (element_step, frequency_step)


def agreement(scene_name: str, radar_name: str, thinnings) -> dict:
    scene = load_scene(scene_name)
    radar = dataclasses.replace(load_radar(radar_name), snr_db=None)
    clock = time.perf_counter()
    data = simulate(scene, radar)
    simulate_s = time.perf_counter() - clock
    acq = data.acquisition
    grid = (lattice_grid(acq, scene.lower_m, scene.upper_m) if acq.scans is not None
            else Grid.from_voxel(scene.lower_m, scene.upper_m, 0.004))
    truth = PrimitiveField(SceneModel.from_scene(scene, 1e-9, 0))  # lengths free within a nanometre: the truth
    rows = {}
    for element_step, frequency_step in thinnings:
        clock = time.perf_counter()
        renderer = CoherentRenderer(data, grid, element_step=element_step, frequency_step=frequency_step,
                                    dtype=torch.float64)
        with torch.no_grad():
            renderer.refresh(truth.sdf, torch.Generator().manual_seed(0))
            predicted = renderer(truth, torch.arange(renderer.num_views), torch.arange(len(renderer.voxels)),
                                 probabilities=truth.material(renderer.candidates.anchors))
        predicted = predicted * (SIMULATED_GAIN / renderer.observed_peak)  # into the observed images' units, as a fit
        observed = renderer.observed
        correlation = (predicted.conj() * observed).sum(1).abs() / (predicted.norm(dim=1) * observed.norm(dim=1))
        ratio = predicted.norm(dim=1) / observed.norm(dim=1)
        rows[f"element_step {element_step}, frequency_step {frequency_step}"] = {
            "frames_per_view": [len(f) for f in renderer.frames], "correlation": correlation.tolist(),
            "amplitude_ratio": ratio.tolist(), "seconds": time.perf_counter() - clock}
        print(scene_name, radar_name, element_step, frequency_step, [round(c, 4) for c in correlation.tolist()],
              [round(r, 3) for r in ratio.tolist()], flush=True)
    return {"scene": scene_name, "radar": radar_name, "grid": list(grid.shape), "voxel_mm": float(grid.voxel_m[0]) * 1e3,
            "simulate_s": simulate_s, "thinnings": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="handheld")
    parser.add_argument("--radar", default="sar-77g")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-model.json"))
    args = parser.parse_args()
    result = {"scan": agreement(args.scene, args.radar, THINNINGS),
              "mimo reference": agreement("objects", "near-77g", THINNINGS[:1])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
