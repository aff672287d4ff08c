"""CLEAN of a scan: each component imaged by FFT on the raster's lattice, the kernels' spectra
kept (rfsdf.radar.scan_imaging.ScanLattice), against the exact operator's point responses and
range-profile back-projections (the general path, which every other view takes) on the same
data, grid and settings, in one run: seconds of each, their ratio, and whether they found the
same components.

The set-up is the scanned demo's (preset ``sar-77g``, its four 33 x 33 scans; scene
``handheld``'s box on the scans' 3 mm lattice, 43^3 voxels): --points point targets drawn
on the scene's true surfaces, with random complex amplitudes, measured by the exact
operator (no simulation of the scene). The reference CLEANs scan 0 for --components
components (each costs it about 30 s on 2 cores); then the lattice CLEAN runs all four scans
at the demo's 300 components, the time the demo spends on it.

Usage: python benchmarks/scan_clean.py [--components 5] [--points 200] [--out benchmarks/results/scan-clean.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from unittest import mock

import numpy as np
import torch
import trimesh

import rfsdf.radar.clean as clean_module
from rfsdf.demo import load_scene_and_radar
from rfsdf.jsonio import to_json
from rfsdf.radar import Measurements, SensingOperator
from rfsdf.radar.clean import MAX_COMPONENTS, clean_image, clean_view
from rfsdf.radar.scan_imaging import lattice_grid


def _timed(function):
    """(result, wall seconds) of ``function()``."""
    clock = time.perf_counter()
    result = function()
    return result, time.perf_counter() - clock


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--components", type=int, default=5, help="of the comparison on scan 0")
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-clean.json"))
    args = parser.parse_args()
    inputs = load_scene_and_radar("handheld", "sar-77g")
    acquisition = inputs.radar.acquisition()
    surface = inputs.scene.ground_truth_mesh()
    points, _ = trimesh.sample.sample_surface(surface, args.points, seed=0)
    rng = np.random.default_rng(0)
    amplitudes = rng.uniform(0.2, 1.0, args.points) * np.exp(2j * np.pi * rng.uniform(size=args.points))
    data = SensingOperator(acquisition).forward(torch.from_numpy(points).float(),
                                                torch.from_numpy(amplitudes).to(torch.complex64))
    measurements = Measurements(acquisition, data)
    grid = lattice_grid(acquisition, inputs.scene.lower_m, inputs.scene.upper_m)
    (index, amplitude, residual), lattice_s = _timed(lambda: clean_view(measurements, 0, grid,
                                                                        max_components=args.components))
    with mock.patch.object(clean_module, "_scan_lattice", lambda *_: None):
        (ref_index, ref_amplitude, ref_residual), reference_s = _timed(
            lambda: clean_view(measurements, 0, grid, max_components=args.components))
    result = {"threads": torch.get_num_threads(), "grid": list(grid.shape), "frames_per_scan": 33 * 33,
              "components": args.components, "lattice_s": lattice_s, "reference_s": reference_s,
              "speedup": reference_s / lattice_s, "same_components": bool(torch.equal(index, ref_index)),
              "amplitude_relative_error": float((amplitude - ref_amplitude).abs().max() / ref_amplitude.abs().max()),
              "residual_relative_error": float((residual - ref_residual).abs().max() / ref_residual.abs().max())}
    print(to_json(result), flush=True)
    all_views, all_views_s = _timed(lambda: clean_image(measurements, grid, max_components=MAX_COMPONENTS))
    result.update(all_scans_components=[len(i) for i in all_views.component_index], all_scans_s=all_views_s)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
