"""Reconstruction quality and wall time of `rfsdf demo` (default: scene `objects`, radar
`near-77g`, 6 mm image voxels): the GeRaF fit and every baseline, scored against the true
surfaces (full surface, observed surface, per object), with the time of each stage and of
a fit step.

Usage: python benchmarks/quality.py [--scene S] [--radar R] [--out benchmarks/results/quality-SCENE-RADAR.json]
       [--recon '{"train": {"geometry_delay": 0}}']   (reconstruction settings over the defaults)
       [--voxel-mm 4]   (image voxel edge; the default is the demo's)
       [--samples-per-wavelength 6] [--random-samples]   (the simulator's surface quadrature; stratified
       is the default)  [--known-gain]   (the simulator's radar gain given after the fit: absolute materials)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

from rfsdf.demo import DemoSettings, metrics_table, run_demo
from rfsdf.jsonio import to_json
from rfsdf.radar.simulate import SIMULATED_GAIN


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--radar", default=DemoSettings.radar)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--recon", type=json.loads, default={}, help="ReconConfig overrides (JSON tables).")
    parser.add_argument("--voxel-mm", type=float, default=DemoSettings.voxel_m * 1e3, help="image voxel edge [mm]")
    parser.add_argument("--samples-per-wavelength", type=float, default=DemoSettings.samples_per_wavelength,
                        help="the simulator's surface samples per wavelength")
    parser.add_argument("--random-samples", action="store_true",
                        help="the simulator's earlier independent random samples instead of stratified ones")
    parser.add_argument("--known-gain", action="store_true",
                        help="read the materials in the simulator's radar gain, given after the relative fit "
                             "(before 2026-12-06: held in the fit)")
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/quality-{Path(args.scene).stem}-{Path(args.radar).stem}.json")

    settings = dataclasses.replace(DemoSettings(), scene=args.scene, radar=args.radar, recon=args.recon,
                                   voxel_m=args.voxel_mm * 1e-3, samples_per_wavelength=args.samples_per_wavelength,
                                   stratified_samples=not args.random_samples,
                                   gain=SIMULATED_GAIN if args.known_gain else None)
    with tempfile.TemporaryDirectory() as folder:
        result = run_demo(folder, settings, progress=False, log=lambda _: None)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(result.as_dict()))
    print(metrics_table(result))
    print(to_json({"timings_s": result.timings_s, "seconds_per_step": result.seconds_per_step}, indent=None))


if __name__ == "__main__":
    main()
