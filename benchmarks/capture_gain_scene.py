"""Materials read through a separate calibration capture, on a scene (the materials issue's
third calibration: no reference object in the scene, the radar's gain measured once from a
capture of a metal sphere alone).

The demo's scene is simulated as `rfsdf demo` does. The capture is a 2 cm metal sphere at
the centre of the scene's box, simulated by the same radar (its noise, another seed) with
samples lambda/12 apart (the physics, converged); `capture_gain` (what `rfsdf calibrate`
runs) measures the gain against the simulator's sum of that scene, and the demo's fit then
holds that gain (``DemoSettings.gain``), the scene's calibration_reference unused. The
simulator's own gain is 1, so the measured gain says how far the capture route is from the
truth, and the materials table how the classes read with it, beside the reference-calibrated
demo's (``--with-reference``: the same data, the default demo's fit).

Usage: python benchmarks/capture_gain_scene.py [--scene objects] [--with-reference]
       [--out benchmarks/results/capture-gain-objects.json] [--work FOLDER]   (keep the demo
       folders there: a rerun resumes them)
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

from rfsdf.demo import DemoSettings, load_scene_and_radar, metrics_table, run_demo
from rfsdf.jsonio import to_json
from rfsdf.radar import simulate
from rfsdf.radar.capture_gain import capture_gain
from rfsdf.scene import load_scene

SPHERE_RADIUS_M = 0.02


def _sphere_scene(folder: Path, lower: list[float], upper: list[float]):
    """A scene file holding the metal sphere alone, at the centre of the box [lower, upper]."""
    centre = [(a + b) / 2 for a, b in zip(lower, upper)]
    path = folder / "capture-sphere.toml"
    path.write_text(f'name = "capture-sphere"\n[bounds]\nlower_m = {lower}\nupper_m = {upper}\n'
                    '[[objects]]\nname = "sphere"\nmaterial = "metal"\n'
                    f'shape = {{ type = "sphere", radius_m = {SPHERE_RADIUS_M}, center_m = {centre} }}\n')
    return load_scene(str(path))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default=DemoSettings.scene)
    parser.add_argument("--with-reference", action="store_true",
                        help="also the default demo's fit (calibrated by the scene's reference) on the same data")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--work", type=Path, default=None, help="the demo folders (default: a temporary folder)")
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/capture-gain-{Path(args.scene).stem}.json")
    settings = dataclasses.replace(DemoSettings(), scene=args.scene)
    inputs = load_scene_and_radar(settings.scene, settings.radar)
    measurements = simulate(inputs.scene, inputs.radar, seed=settings.seed, max_samples=settings.max_surface_samples,
                            samples_per_wavelength=settings.samples_per_wavelength,
                            stratified=settings.stratified_samples, progress=False)
    with tempfile.TemporaryDirectory() as temporary:
        folder = args.work or Path(temporary)
        folder.mkdir(parents=True, exist_ok=True)
        sphere = _sphere_scene(folder, inputs.scene.lower_m.tolist(), inputs.scene.upper_m.tolist())
        capture = simulate(sphere, inputs.radar, seed=settings.seed + 5, samples_per_wavelength=12, progress=False)
        measured = capture_gain(capture, sphere, capture_name="the sphere's capture")
        print(f"capture gain {measured.gain:.4f} (the simulator's: 1), the sphere explains {measured.explained:.1%}")
        runs = {"capture": dataclasses.replace(settings, gain=measured.gain)}
        if args.with_reference:
            runs["reference"] = settings
        rows = {}
        for name, run in runs.items():
            result = run_demo(folder / name, run, measurements=measurements, progress=False, log=lambda _: None)
            print(f"--- {name} ---\n{metrics_table(result)}")
            rows[name] = result.as_dict()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": settings.scene, "radar": settings.radar,
                            "capture": {**measured.as_dict(), "sphere_radius_m": SPHERE_RADIUS_M,
                                        "samples_per_wavelength": 12},
                            "runs": rows}))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
