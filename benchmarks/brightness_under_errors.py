"""How accurate must the geometry be for the material readout? The true surfaces moved by a
smooth random error, the kind a neural SDF makes (not per-sample jitter, which is a rough
surface), and rendered per object as in `object_brightness.py`.

A fit holds the data and reads |Gamma| from how bright its surface renders: where its surface
renders b times dimmer than the true one per unit |Gamma|, its |Gamma| reads b times too high.
So with the gain known an object's readout is its true |Gamma(0)| times a_i(errors) / a_i(exact),
a_i the data's brightness over the renderer's for object i (NNLS split of the bright voxels'
powers), and its class the catalogue's nearest in |Gamma|. Here the surface's error is
known, a Gaussian random field added to the scene's exact SDF:

    delta(x) = sigma sqrt(2 / M) sum_m cos(k_m . x + phi_m),  k_m ~ N(0, I / L^2),

so its covariance is sigma^2 exp(-|r|^2 / (2 L^2)): the surface moves by sigma (rms) along its
normal, smoothly over about L. Per (sigma, L): each object's factor a_i(errors) / a_i(exact)
over ``--fields`` random fields, and the readout's class accuracy over the objects. The
first row (sigma 0) is the control: the exact surface with the renderer's random surface
samples drawn anew (seeds 1..fields), the spread the renderer's own quadrature adds.
``--run DEMO_DIR`` adds the errors a fit made: that demo's data instead of a fresh
simulation, and its warm start's and fitted surfaces (``run/checkpoint.pt``) in place of
the random fields, each object still rendered with its true material.

Usage: python benchmarks/brightness_under_errors.py [--scene objects] [--sigma-mm 0.25,0.5,1,2,4]
       [--correlation-mm 10] [--fields 3] [--run DEMO_DIR]
       [--out benchmarks/results/brightness-under-errors-objects.json]
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
import torch
from object_brightness import object_gains

from rfsdf.demo import DemoSettings
from rfsdf.field import RadarField
from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES, class_reflectivities, reflectivity_class
from rfsdf.radar import load_radar, read_measurements, simulate
from rfsdf.recon import read_checkpoint
from rfsdf.scene import load_scene

MODES = 256  # plane waves in each random field


def smooth_error(sigma_m: float, correlation_m: float, seed: int):
    """delta: (N, 3) [m] -> (N,) [m], a stationary Gaussian random field of rms ``sigma_m``
    and squared-exponential correlation of length ``correlation_m``."""
    generator = torch.Generator().manual_seed(seed)
    k = torch.randn(MODES, 3, generator=generator, dtype=torch.float64) / correlation_m
    phase = 2 * np.pi * torch.rand(MODES, generator=generator, dtype=torch.float64)
    return lambda x: sigma_m * np.sqrt(2 / MODES) * torch.cos(x.double() @ k.T + phase).sum(-1)


def run_surfaces(folder: Path) -> dict:
    """{"warm start": sdf, "fit": sdf} of a demo folder's run: (N, 3) -> (N,) [m]."""
    state = read_checkpoint(folder / "run" / "checkpoint.pt", "cpu")
    surfaces = {}
    for name, weights in (("warm start", state["warm_field"]), ("fit", state["field"])):
        field = RadarField(**state["field_kwargs"])
        field.load_state_dict(weights)
        surfaces[name] = lambda x, f=field.eval(): f.sdf(x.float())
    return surfaces


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="objects")
    parser.add_argument("--sigma-mm", default="0.25,0.5,1,2,4")
    parser.add_argument("--correlation-mm", default="10")
    parser.add_argument("--fields", type=int, default=3)
    parser.add_argument("--run", type=Path, default=None, help="a demo folder of --scene: its data and surfaces too")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/brightness-under-errors-{Path(args.scene).stem}.json")
    settings = DemoSettings()
    scene, radar = load_scene(args.scene), load_radar(settings.radar)
    if args.run is None:
        data = simulate(scene, radar, seed=settings.seed, max_samples=settings.max_surface_samples)
    else:
        data = read_measurements(args.run / "measurements.h5")
    names = [obj.name for obj in scene.objects]
    truth = np.array([obj.material.name for obj in scene.objects])
    frequency_hz = data.acquisition.center_frequency_hz
    true_gamma = class_reflectivities(tuple(truth), frequency_hz).numpy()
    exact, bright = object_gains(scene, data, settings)
    print(f"exact surfaces: data / renderer per object {np.round(exact, 3).tolist()} ({bright} bright voxels)")

    def gains_with_errors(sigma_mm: float, correlation_mm: float, seed: int) -> np.ndarray:
        """a_i on the true surfaces moved by one random field (sigma 0: resampled only)."""
        if sigma_mm == 0:
            return object_gains(scene, data, settings, sample_seed=seed + 1)[0]
        delta = smooth_error(sigma_mm * 1e-3, correlation_mm * 1e-3, seed)
        return object_gains(scene, data, settings, sdf=lambda x: scene.sdf(x.double()) + delta(x))[0]

    def row(label: str, factors: np.ndarray, **extra) -> dict:
        """The readout's classes and accuracy for factors (fields, objects)."""
        classes = reflectivity_class(true_gamma * factors, MATERIAL_CLASSES, frequency_hz)
        result = {"surface": label, **extra, "accuracy": float((classes == truth).mean()),
                  "metal_read_as_dielectric": int(((truth == "metal") & (classes != "metal")).sum()),
                  "objects": {name: {"factor": factors[:, i].tolist(), "classes": classes[:, i].tolist()}
                              for i, name in enumerate(names)},
                  "factor_spread": [float(np.quantile(factors, q)) for q in (0.1, 0.5, 0.9)]}
        print(f"{label}: readout factor 10/50/90 % {np.round(result['factor_spread'], 2).tolist()}, "
              f"accuracy {result['accuracy']:.2f}", flush=True)
        return result

    rows = []
    errors = itertools.product(*(map(float, a.split(",")) for a in (args.sigma_mm, args.correlation_mm)))
    for sigma_mm, correlation_mm in [(0.0, 0.0), *errors]:  # the control first
        factors = np.array([gains_with_errors(sigma_mm, correlation_mm, seed) / exact for seed in range(args.fields)])
        rows.append(row(f"sigma {sigma_mm:g} mm, L {correlation_mm:g} mm", factors,
                        sigma_mm=sigma_mm, correlation_mm=correlation_mm))
    for label, sdf in (run_surfaces(args.run) if args.run is not None else {}).items():
        rows.append(row(label, object_gains(scene, data, settings, sdf=sdf)[0][None] / exact))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": args.scene, "radar": settings.radar, "fields": args.fields,
                            "run": None if args.run is None else str(args.run),
                            "true": dict(zip(names, truth.tolist())), "exact_gains": exact.tolist(),
                            "bright_voxels": bright, "rows": rows}))


if __name__ == "__main__":
    main()
