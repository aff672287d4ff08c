"""Where each glint's carrier phase says the surface lies. Along the line of sight of every range
peak the demo's warm start finds (the lines of `peak_match.py`, five points within +-6 mm), the
renderer's image of a surface against the data's gives the surface's offset along the line
three ways: the envelope (the difference of the two parabola vertices), alone and smoothed over
the view's lines (amplitude-weighted, 10 mm Gaussian); the carrier phase (the argument of their
product summed over the five points, over 2 k at the band's centre: exact to hundredths of a
millimetre, but it repeats every lambda / 2); and the phase unwrapped by the smoothed envelope.
Each against the surface's true offset where it crosses the line (the true SDF at x - f(x) t, t
the line's direction towards its view), over the lines that cross an object. Surfaces: the truth,
the truth moved by the basin study's smooth field (20 mm correlation) of 0.25-2 mm rms, dilated
by 1 mm, and the demo's warm start (CLEAN, as `rfsdf demo` builds it); every material and the
gain known, the phase calibrated (simulated data).

Then what holding the surface where the phase says would do, with a smooth field standing in for
the network: from the smooth 1 and 2 mm surfaces, eight rounds, each subtracting the lines'
estimates spread over a 2 mm grid by a 10 mm Gaussian kernel (the phase unwrapped by the
envelope in the first round, wrapped after it); per round the offset at the lines' crossings and
at the true surface within 5 mm of a line.

Usage: python benchmarks/glint_phase.py [--out benchmarks/results/glint-phase.json]  (~8 min on 2 cores)
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np
import torch
from demo_data import demo_data
from peak_match import line_images
from scipy import ndimage

from rfsdf.geometry import Grid, interpolated_sdf
from rfsdf.jsonio import to_json
from rfsdf.radar.clean import clean_image
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.recon.losses import peak_offset
from rfsdf.studies.basin import TrueMaterials, smooth_displacement

SMOOTHING_M = 0.01  # the envelope's smoothing over a view's lines, and the rounds' spread
GRID_M = 0.002  # the rounds' displacement grid
ROUNDS = ["unwrapped"] + ["wrapped"] * 7


def _stats(error_m: np.ndarray, weight: np.ndarray) -> dict[str, float]:
    """|error| in mm: median, amplitude-weighted mean, 90th percentile, share within 0.25 mm."""
    a = np.abs(error_m) * 1e3
    return {"median_mm": float(np.median(a)), "weighted_mm": float((a * weight).sum() / weight.sum()),
            "p90_mm": float(np.quantile(a, 0.9)), "within_0.25_mm": float((a < 0.25).mean())}


class Lines:
    """The warm start's peak lines and the data along them; ``estimates`` reads a surface's offset."""

    def __init__(self, trainer: Trainer, known: TrueMaterials, wavenumber: float):
        self.trainer, self.known = trainer, known
        self.lines, self.observed, self.offsets = trainer.peak_lines()
        self.points, amplitude, self.view, self.towards = trainer.peaks
        self.centre = self.lines[:, self.lines.shape[1] // 2].numpy().astype(float)
        self.amplitude = amplitude.numpy().astype(float)
        self.data_vertex, self.data_valid = peak_offset(self.observed.abs() ** 2, self.offsets)
        self.half_wavelength = math.pi / wavenumber
        self.wavenumber = wavenumber

    def smoothed(self, values: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """Each line's amplitude-weighted Gaussian mean of ``values`` over its view's valid lines."""
        out = np.zeros_like(values)
        view = self.view.numpy()
        for v in np.unique(view):
            mine = np.nonzero(view == v)[0]
            distance2 = ((self.centre[mine][:, None] - self.centre[mine][None]) ** 2).sum(-1)
            weight = self.amplitude[mine][None] * np.exp(-distance2 / (2 * SMOOTHING_M**2)) * valid[mine][None]
            out[mine] = (weight * np.where(valid[mine], values[mine], 0.0)[None]).sum(1) / np.maximum(weight.sum(1), 1e-30)
        return out

    def estimates(self, sdf) -> dict[str, np.ndarray]:
        """Offsets [m] (N,) of ``sdf``'s surface towards each view against the data's: envelope,
        smoothed envelope, wrapped and unwrapped phase; ``valid``: both images peak on the line."""
        predicted = line_images(self.trainer.renderer, self.known, self.lines, self.view, sdf)
        vertex, valid = peak_offset(predicted.abs() ** 2, self.offsets)
        valid = (valid & self.data_valid).numpy()
        envelope = (vertex - self.data_vertex).numpy().astype(float)
        smoothed = self.smoothed(envelope, valid)
        wrapped = (torch.angle((predicted * self.observed.conj()).sum(1)) / (2 * self.wavenumber)).numpy().astype(float)
        unwrapped = wrapped + self.half_wavelength * np.round((smoothed - wrapped) / self.half_wavelength)
        return {"envelope": envelope, "envelope smoothed": smoothed, "wrapped": wrapped, "unwrapped": unwrapped,
                "valid": valid}

    def true_offsets(self, sdf, scene_sdf) -> np.ndarray:
        """(N,) [m] the true SDF where ``sdf``'s surface crosses each line (+: outside the truth)."""
        with torch.no_grad():
            crossing = self.points - sdf(self.points).float()[:, None] * self.towards
            return scene_sdf(crossing.double()).numpy().astype(float)


def offsets_report(lines: Lines, sdf, scene) -> dict:
    """Each estimate's error against the true offset, over the lines that cross an object (within 2 cm)."""
    found, true = lines.estimates(sdf), lines.true_offsets(sdf, scene.sdf)
    keep = found["valid"] & (np.abs(true) < 0.02)
    half = lines.half_wavelength
    report = {"lines": int(keep.sum()), "true offset": _stats(true[keep], lines.amplitude[keep])}
    for name in ("envelope", "envelope smoothed", "wrapped", "unwrapped"):
        report[name] = _stats((found[name] - true)[keep], lines.amplitude[keep])
    oracle = found["wrapped"] + half * np.round((true - found["wrapped"]) / half)
    report["wrapped, unwrapped by the truth"] = _stats((oracle - true)[keep], lines.amplitude[keep])
    return report


def rounds(lines: Lines, scene, smooth, rms_m: float, surface: torch.Tensor) -> list[dict]:
    """The smooth surface moved, round by round, by the lines' estimates spread over a grid."""
    lower = np.asarray(scene.lower_m) - 0.02
    grid = Grid.from_voxel(lower, np.asarray(scene.upper_m) + 0.02, GRID_M)
    index = tuple(np.clip(np.floor((lines.centre - lower) / grid.voxel_m).astype(int), 0,
                          np.asarray(grid.shape) - 1).T)
    near = torch.cdist(surface.float(), torch.as_tensor(lines.centre, dtype=torch.float32)).min(1).values < 0.005
    correction = np.zeros(grid.shape)

    def moved(values):
        field = interpolated_sdf(torch.as_tensor(values, dtype=torch.float32).flatten(), grid)
        return lambda p: rms_m * smooth(p) + field(p.float()).to(p.dtype)

    def state(values) -> dict:
        displacement = moved(values)
        sdf = lambda p: scene.sdf(p) - displacement(p)  # noqa: E731
        true = lines.true_offsets(sdf, scene.sdf)
        on = np.abs(true) < 0.02
        with torch.no_grad():
            seen = displacement(surface[near].double()).numpy()
        return {"lines": _stats(true[on], lines.amplitude[on]), "seen surface": _stats(seen, np.ones(len(seen)))}

    history = [state(correction)]
    for mode in ROUNDS:
        displacement = moved(correction)
        found = lines.estimates(lambda p: scene.sdf(p) - displacement(p))
        numerator, denominator = np.zeros(grid.shape), np.zeros(grid.shape)
        np.add.at(numerator, index, lines.amplitude * found[mode])
        np.add.at(denominator, index, lines.amplitude)
        numerator = ndimage.gaussian_filter(numerator, SMOOTHING_M / GRID_M)
        denominator = ndimage.gaussian_filter(denominator, SMOOTHING_M / GRID_M)
        correction = correction - numerator / (denominator + 0.05 * denominator.max())
        history.append({"round": mode, **state(correction)})
        print(rms_m * 1e3, "mm", mode, history[-1]["seen surface"]["median_mm"], flush=True)
    return history


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/glint-phase.json"))
    args = parser.parse_args()
    data = demo_data()
    scene, known = data.scene, TrueMaterials(data.scene)
    problem = Problem(data.measurements, data.image.grid, clean=clean_image(data.measurements, data.image.grid),
                      gain=SIMULATED_GAIN, known_materials=known)
    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(problem, ReconConfig(), folder)
        trainer.warm_start()
    wavenumber = 2 * math.pi / data.measurements.acquisition.wavelength_m
    lines = Lines(trainer, known, wavenumber)
    smooth = smooth_displacement(scene, 0.02, torch.Generator().manual_seed(1))
    surfaces = {"truth": scene.sdf}
    surfaces.update({f"smooth {mm} mm": (lambda p, mm=mm: scene.sdf(p) - mm * 1e-3 * smooth(p))
                     for mm in (0.25, 0.5, 1.0, 2.0)})
    surfaces["dilated 1 mm"] = lambda p: scene.sdf(p) - 1e-3
    surfaces["warm start"] = lambda p: trainer.field.sdf(p.float()).to(p.dtype)
    result = {"lines": len(lines.centre), "half_wavelength_mm": lines.half_wavelength * 1e3, "surfaces": {}}
    for name, sdf in surfaces.items():
        result["surfaces"][name] = offsets_report(lines, sdf, scene)
        print(name, result["surfaces"][name]["true offset"]["median_mm"],
              result["surfaces"][name]["unwrapped"]["median_mm"], flush=True)
    surface = scene.sample_surface(0.002, seed=0, max_samples=50_000).points
    result["rounds"] = {f"smooth {mm} mm": rounds(lines, scene, smooth, mm * 1e-3, surface) for mm in (1.0, 2.0)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
