"""How exactly must the geometry be known before a coherent renderer pays off? Render the
*true* scene coherently (the simulator's own surface reflectivity on a fresh surface
sampling, through A, then imaged by the same matched filter), perturb the surface, and
compare each view's predicted MF amplitude with the observed one: the mean per-view
correlation (the deleted incoherent physics renderer scored 0.72 on the exact surface)
and the fit's relative data loss (amplitude L2 after a least-squares gain). With no
perturbation the correlation is not 1: the fresh lambda/3 sampling has its own speckle
(``radar/simulate.py``).

Perturbations, each sample moved along its normal (or rigidly):
* ``white``: independent Gaussian errors per sample (a rough surface), std lambda/16..lambda/4;
* ``dilation``: every sample by the same distance (the object grown);
* ``shift``: the whole scene translated (along a fixed oblique direction);
* ``smooth``: a smooth Gaussian random field of 20 mm correlation length, by its std.
White jitter is what a neural SDF does *not* produce; its errors are smooth. The dilation
is also scanned finely on both sides of the truth (``dilation_scan``): the landscape the fit
descends, which on a 6-view toy radar ripples with period lambda/2 (``tests/test_recon.py``).

Usage: python benchmarks/coherent_model.py [--out benchmarks/results/coherent_model.json]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from demo_data import demo_data
from scipy import ndimage

from rfsdf.jsonio import to_json
from rfsdf.radar import Measurements, SensingOperator, matched_filter
from rfsdf.radar.simulate import view_reflectivities

AMOUNTS_MM = (0.5, 1.0, 2.0, 4.0, 8.0)
SCAN_MM = tuple(np.arange(-3.0, 3.01, 0.5))
WHITE_IN_WAVELENGTHS = (1 / 16, 1 / 8, 1 / 4)
CORRELATION_LENGTH_M = 0.02
SHIFT_DIRECTION = (0.6, 0.48, 0.64)  # unit, oblique to every axis


def smooth_field(points: torch.Tensor, lower_m, upper_m, generator: torch.Generator) -> torch.Tensor:
    """(Q,) unit-std Gaussian random field with autocorrelation exp(-r^2 / 2 l^2), l = 20 mm,
    at ``points``: white noise on a 2 mm grid, Gaussian-filtered, interpolated."""
    step = 0.002
    lower, upper = np.asarray(lower_m) - 0.05, np.asarray(upper_m) + 0.05
    shape = tuple(int(np.ceil(e / step)) + 1 for e in upper - lower)
    noise = torch.randn(shape, generator=generator, dtype=torch.float64).numpy()
    field = ndimage.gaussian_filter(noise, CORRELATION_LENGTH_M / np.sqrt(2) / step, mode="wrap")
    field /= field.std()
    coords = ((points.double().numpy() - lower) / step).T
    return torch.from_numpy(ndimage.map_coordinates(field, coords, order=1)).float()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/coherent_model.json"))
    args = parser.parse_args()

    data = demo_data()
    acq, image, scene = data.measurements.acquisition, data.image, data.scene
    wavelength = acq.wavelength_m
    samples = scene.sample_surface(wavelength / 3, seed=data.settings.seed + 1,
                                   max_samples=data.settings.max_surface_samples)
    c = view_reflectivities(scene, samples, acq)
    operator = SensingOperator(acq)
    observed = image.per_view.flatten(1).abs()
    observed = observed / observed.max()
    generator = torch.Generator().manual_seed(0)
    points, normals = samples.points, samples.normals

    def score(moved: torch.Tensor) -> dict:
        with torch.no_grad():
            y = operator.forward(moved, c)
        predicted = matched_filter(Measurements(acq, y), image.grid).per_view.flatten(1).abs()
        correlation = [float(torch.corrcoef(torch.stack([p, o]))[0, 1]) for p, o in zip(predicted, observed)]
        gain = float((predicted * observed).sum() / (predicted**2).sum())
        loss = float(((gain * predicted - observed) ** 2).sum() / (observed**2).sum())  # relative, as the fit
        return {"correlation": float(np.mean(correlation)), "loss": loss}

    field = smooth_field(points, scene.lower_m, scene.upper_m, generator)
    shift = torch.tensor(SHIFT_DIRECTION)
    moves = {
        "dilation": lambda a: points + a * normals,
        "shift": lambda a: points + a * shift,
        "smooth": lambda a: points + (a * field)[:, None] * normals,
    }
    result: dict = {"wavelength_mm": wavelength * 1e3, "surface_samples": len(points),
                    "correlation_length_mm": CORRELATION_LENGTH_M * 1e3, "none": score(points)}
    print("none", result["none"], flush=True)
    white = torch.randn(len(points), 1, generator=generator)
    result["white"] = {}
    for error in WHITE_IN_WAVELENGTHS:
        key = f"{error * wavelength * 1e3:.2f} mm (lambda * {error:g})"
        result["white"][key] = score(points + error * wavelength * white * normals)
        print("white", key, result["white"][key], flush=True)
    for kind, move in moves.items():
        result[kind] = {}
        for amount in AMOUNTS_MM:
            result[kind][f"{amount:g} mm"] = score(move(amount * 1e-3))
            print(kind, amount, result[kind][f"{amount:g} mm"], flush=True)
    result["dilation_scan"] = {f"{amount:+.1f} mm": score(moves["dilation"](amount * 1e-3)) for amount in SCAN_MM}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
