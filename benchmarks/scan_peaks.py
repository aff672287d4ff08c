"""Where a scan's range peaks lie: the warm start's surface points on preset ``sar-77g``.

A scan sees a face specularly: every frame's return comes from the frame's own foot on it,
a wave that the whole aperture, focusing on points, places behind the face. This simulates
the scene (default ``handheld``), images each scan by FFT on its lattice, takes the warm
start's detection (matched filter, threshold 0.1) and its range ridges, and refines each
along its line of sight three ways: on the whole scan towards its centre (the MIMO views'
rule, until the thirty-second session), on the sub-aperture before it along the raster's
normal by the range-profile adjoint (`--method fast`), and by the exact adjoint (now). Per
variant: how far the peaks lie from the true surface (signed: negative inside), all and
the strong ones (amplitude over 0.3 of their view's largest), in mm. About 10 minutes on
2 cores.

Usage: python benchmarks/scan_peaks.py [--scene handheld] [--radar sar-77g] [--out benchmarks/results/scan-peaks.json]
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path
from unittest import mock

import numpy as np
import torch

import rfsdf.radar.range_peaks as range_peaks_module
from rfsdf.demo import load_scene_and_radar
from rfsdf.jsonio import to_json
from rfsdf.radar import matched_filter, simulate
from rfsdf.radar.scan_imaging import lattice_grid
from rfsdf.recon import ReconConfig
from rfsdf.recon.warm_start import excluded_voxels

THRESHOLD = 0.1  # the scanned demo's (rfsdf.demo.SCANNED)


def _distances(peaks, scene) -> dict:
    with torch.no_grad():
        signed = scene.sdf(torch.from_numpy(peaks.points)).numpy() * 1e3
    strong = peaks.amplitude > 0.3
    weights = peaks.amplitude
    return {"peaks": len(signed), "median_abs_mm": float(np.median(np.abs(signed))),
            "amplitude_weighted_abs_mm": float((np.abs(signed) * weights).sum() / weights.sum()),
            "signed_percentiles_mm": {str(p): float(v) for p, v in zip((5, 25, 50, 75, 95),
                                                                       np.percentile(signed, [5, 25, 50, 75, 95]))},
            "strong": int(strong.sum()), "strong_median_abs_mm": float(np.median(np.abs(signed[strong]))),
            "strong_median_signed_mm": float(np.median(signed[strong]))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="handheld")
    parser.add_argument("--radar", default="sar-77g")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-peaks.json"))
    args = parser.parse_args()
    inputs = load_scene_and_radar(args.scene, args.radar)
    scene = inputs.scene
    measurements = simulate(scene, inputs.radar, seed=0)
    acq = measurements.acquisition
    grid = lattice_grid(acq, scene.lower_m, scene.upper_m)
    per_view = (matched_filter(measurements, grid).per_view.abs() ** 2).numpy()
    init = ReconConfig().init.model_copy(update={"method": "mf", "threshold": THRESHOLD})
    keep = ~excluded_voxels(init, per_view, acq, grid, THRESHOLD)
    rule = {"threshold": THRESHOLD, "local_threshold": init.local_threshold, "window_m": init.window_m, "keep": keep}
    correlation = range_peaks_module.view_correlation

    def by_method(method):
        return lambda *args, **kwargs: correlation(*args, **{**kwargs, "method": method})

    variants = {
        "whole scan, towards its centre (fast adjoint)": {"_raster_normal": lambda *_: None,
                                                         "view_correlation": by_method("fast")},
        "sub-aperture, along the raster's normal (fast adjoint)": {"view_correlation": by_method("fast")},
        "sub-aperture, along the raster's normal (exact adjoint: now)": {},
    }
    rows = {}
    for name, patches in variants.items():
        clock = time.perf_counter()
        with mock.patch.multiple(range_peaks_module, **patches) if patches else contextlib.nullcontext():
            peaks = range_peaks_module.range_peaks(measurements, per_view, grid, **rule)
        rows[name] = _distances(peaks, scene) | {"seconds": round(time.perf_counter() - clock, 1)}
        print(name, to_json(rows[name], indent=None), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"scene": args.scene, "radar": args.radar, "threshold": THRESHOLD, "variants": rows}))


if __name__ == "__main__":
    main()
