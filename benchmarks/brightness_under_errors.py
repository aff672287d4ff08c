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

Usage: python benchmarks/brightness_under_errors.py [--scene objects] [--sigma-mm 0.25,0.5,1,2,4]
       [--correlation-mm 10] [--fields 3] [--out benchmarks/results/brightness-under-errors-objects.json]
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
import torch
from object_brightness import object_gains

from rfsdf.demo import DemoSettings
from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES, class_reflectivities, reflectivity_class
from rfsdf.radar import load_radar, simulate
from rfsdf.scene import load_scene

MODES = 256  # plane waves in each random field


def smooth_error(sigma_m: float, correlation_m: float, seed: int):
    """delta: (N, 3) [m] -> (N,) [m], a stationary Gaussian random field of rms ``sigma_m``
    and squared-exponential correlation of length ``correlation_m``."""
    generator = torch.Generator().manual_seed(seed)
    k = torch.randn(MODES, 3, generator=generator, dtype=torch.float64) / correlation_m
    phase = 2 * np.pi * torch.rand(MODES, generator=generator, dtype=torch.float64)
    return lambda x: sigma_m * np.sqrt(2 / MODES) * torch.cos(x.double() @ k.T + phase).sum(-1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="objects")
    parser.add_argument("--sigma-mm", default="0.25,0.5,1,2,4")
    parser.add_argument("--correlation-mm", default="10")
    parser.add_argument("--fields", type=int, default=3)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/brightness-under-errors-{Path(args.scene).stem}.json")
    settings = DemoSettings()
    scene, radar = load_scene(args.scene), load_radar(settings.radar)
    data = simulate(scene, radar, seed=settings.seed, max_samples=settings.max_surface_samples)
    names = [obj.name for obj in scene.objects]
    truth = np.array([obj.material.name for obj in scene.objects])
    true_gamma = class_reflectivities(tuple(truth), data.acquisition.center_frequency_hz).numpy()
    exact, bright = object_gains(scene, data, settings)
    print(f"exact surfaces: data / renderer per object {np.round(exact, 3).tolist()} ({bright} bright voxels)")
    rows = []
    errors = itertools.product(*(map(float, a.split(",")) for a in (args.sigma_mm, args.correlation_mm)))
    for sigma_mm, correlation_mm in [(0.0, 0.0), *errors]:  # the control first
        factors = []
        for seed in range(args.fields):
            if sigma_mm == 0:
                gains, _ = object_gains(scene, data, settings, sample_seed=seed + 1)
            else:
                delta = smooth_error(sigma_mm * 1e-3, correlation_mm * 1e-3, seed)
                gains, _ = object_gains(scene, data, settings, sdf=lambda x, d=delta: scene.sdf(x.double()) + d(x))
            factors.append(gains / exact)
        factors = np.array(factors)  # (fields, objects)
        classes = reflectivity_class(true_gamma * factors, MATERIAL_CLASSES, data.acquisition.center_frequency_hz)
        row = {"sigma_mm": sigma_mm, "correlation_mm": correlation_mm,
               "accuracy": float((classes == truth).mean()),
               "metal_read_as_dielectric": int(((truth == "metal") & (classes != "metal")).sum()),
               "objects": {name: {"factor": factors[:, i].tolist(), "classes": classes[:, i].tolist()}
                           for i, name in enumerate(names)},
               "factor_spread": [float(np.quantile(factors, q)) for q in (0.1, 0.5, 0.9)]}
        rows.append(row)
        print(f"sigma {sigma_mm:g} mm, L {correlation_mm:g} mm: readout factor 10/50/90 % "
              f"{np.round(row['factor_spread'], 2).tolist()}, accuracy {row['accuracy']:.2f}", flush=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({"scene": args.scene, "radar": settings.radar, "fields": args.fields,
                            "true": dict(zip(names, truth.tolist())), "exact_gains": exact.tolist(),
                            "bright_voxels": bright, "rows": rows}))


if __name__ == "__main__":
    main()
