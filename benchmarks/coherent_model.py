"""How exactly must the geometry be known before a coherent renderer pays off? Render the
*true* scene coherently (the simulator's own surface reflectivity on a fresh surface
sampling, through A, then imaged by the same matched filter) with each sample moved along its normal by Gaussian errors of
standard deviation 0, lambda/16, lambda/8 and lambda/4, and correlate each view's
predicted MF amplitude with the observed one (the metric of ``facing_lobe.py``, where the
incoherent physics renderer of the true scene scores 0.72).

Usage: python benchmarks/coherent_model.py [--out benchmarks/results/coherent_model.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch
from demo_data import demo_data

from rfsdf.radar import Measurements, SensingOperator, matched_filter
from rfsdf.radar.simulate import view_reflectivities

ERRORS_IN_WAVELENGTHS = (0.0, 1 / 16, 1 / 8, 1 / 4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/coherent_model.json"))
    args = parser.parse_args()

    data = demo_data()
    acq, image = data.measurements.acquisition, data.image
    wavelength = acq.wavelength_m
    samples = data.scene.sample_surface(wavelength / 3, seed=data.settings.seed + 1,
                                        max_samples=data.settings.max_surface_samples)
    c = view_reflectivities(data.scene, samples, acq)
    operator = SensingOperator(acq)
    observed = image.per_view.flatten(1).abs()
    result: dict = {"wavelength_mm": wavelength * 1e3, "surface_samples": len(samples.points),
                    "mean_amplitude_correlation": {}}
    generator = torch.Generator().manual_seed(0)
    for error in ERRORS_IN_WAVELENGTHS:
        offset = error * wavelength * torch.randn(len(samples.points), 1, generator=generator)
        with torch.no_grad():
            y = operator.forward(samples.points + offset * samples.normals, c)
        predicted = matched_filter(Measurements(acq, y), image.grid).per_view.flatten(1).abs()
        correlation = [float(torch.corrcoef(torch.stack([p, o]))[0, 1]) for p, o in zip(predicted, observed)]
        key = f"error {error * wavelength * 1e3:.2f} mm (lambda * {error:g})"
        result["mean_amplitude_correlation"][key] = sum(correlation) / len(correlation)
        print(key, round(result["mean_amplitude_correlation"][key], 3), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
