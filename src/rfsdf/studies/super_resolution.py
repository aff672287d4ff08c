"""Finer than the point-spread function: the fitted surface against the matched filter's.

A matched-filter image blurs every point by its point-spread function: c / 2B in range and
lambda R / 2D across, centimetres for a near-range radar. A surface thresholded from that
image inherits the blur; the GeRaF fit instead moves a surface until its *predicted* image
matches the observed one, so it can place the surface far finer than the PSF, as long as
the data pin it down: enough signal over the noise, and enough views that no other surface
explains them as well (study `ambiguity`).

Measured: the `sphere` scene's 2 cm metal ball seen by a small radar (a boundary array
0.3 m away, 79 GHz carrier, 6 views unless swept), around a centre setting of 4 GHz, a
4 cm array, 40 dB and 6 views, one quantity swept at a time: bandwidth, array size (its
elements kept 2 cm apart), SNR (per measurement sample), views. For each: the PSF's -3 dB widths of one view along its range and across it
(measured on the image of a point at the centre, and c / 2B, lambda R / 2D), the
Chamfer-L1 of the best global threshold of the view-mean MF power (chosen against the
truth: generous to it), and of a small GeRaF fit (`ball_fit`, 40 steps) from a field
initialised as a ball 3 mm too large (lumpy: its Chamfer is recorded too; no detection
step, so this measures how well the data pin the surface, not how it is found).
"""

from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass

import numpy as np

from ..baseline import best_threshold_mesh
from ..geometry import Grid
from ..mesh import extract_mesh
from ..metrics import compare_meshes
from ..radar import matched_filter
from ..radar.acquisition import swept_bandwidth_hz
from ..radar.imaging import half_power_width, point_spread
from ..radar.waveform import cross_range_resolution_m, range_resolution_m
from ..recon import Problem, Trainer
from ..scene import load_scene
from ..viz.figures import plt, save_figure
from .ball_fit import GRID, SIX_VIEWS, ball_data, fit_config, small_radar

NAME = "super-resolution"
SUMMARY = "the fit's surface error against the MF's PSF widths and threshold, over bandwidth, aperture, SNR and views"

_RINGS = {1: ((1, 0.0),), 2: ((2, 0.0),), 6: SIX_VIEWS}  # view count -> (views, elevation) per ring
_START_M = 0.003


@dataclass(frozen=True)
class Settings:
    bandwidths_ghz: tuple[float, ...] = (1.0, 2.0, 4.0)
    arrays_cm: tuple[float, ...] = (2.0, 4.0, 8.0)
    snrs_db: tuple[float, ...] = (-30.0, -20.0, -10.0, 0.0, 20.0, 40.0)
    view_counts: tuple[int, ...] = (1, 2, 6)
    steps: int = 40
    metric_samples: int = 20_000  # points on each mesh for the Chamfer distances
    seed: int = 0


# 1,000 metric samples: the quick run 11.8 s, 16.5 at 2,000 (the threshold sweep's blurred meshes lie inside the
# ball, where each exact query visits most of its faces), its Chamfer distances within 0.2 mm
QUICK = Settings(bandwidths_ghz=(1.0, 4.0), arrays_cm=(), snrs_db=(), view_counts=(), steps=6, metric_samples=1_000)


@dataclass(frozen=True)
class Point:
    """One radar setting and what it gives."""

    bandwidth_ghz: float
    array_cm: float
    snr_db: float
    views: int
    range_psf_mm: float  # measured -3 dB width of one view's PSF along its range
    cross_psf_mm: float  # ... across it (vertical)
    range_resolution_mm: float  # c / 2B
    cross_resolution_mm: float  # lambda R / 2D
    mf_chamfer_mm: float  # best global threshold of the view-mean MF power
    start_chamfer_mm: float  # the fit's start: the field initialised as a ball 3 mm too large
    fit_chamfer_mm: float  # GeRaF from there


@dataclass(frozen=True)
class Result:
    sweeps: dict  # "bandwidth_ghz" | "array_cm" | "snr_db" | "views" -> list of Point (as dicts)


_CENTRE = {"bandwidth_ghz": 4.0, "array_cm": 4.0, "snr_db": 40.0, "views": 6}


def _psf_widths(radar, half_length_m: float) -> tuple[float, float]:
    """(-3 dB width along view 0's range, across it (z)) [m] of a point at the centre, from
    profiles over +-``half_length_m``."""
    acquisition = radar.acquisition().view(0)
    axis = int(np.argmax(np.abs(radar.positions_m[0])))  # the views look along a box axis
    line = np.linspace(-half_length_m, half_length_m, 401)
    step = line[1] - line[0]
    widths = []
    for along in (axis, 2):  # a line of voxel centres through the point (grids need 2 voxels across)
        lower, upper = [-1e-4] * 3, [3e-4] * 3  # centres at 0 and 2e-4 m across
        lower[along], upper[along] = line[0] - step / 2, line[-1] + step / 2
        shape = tuple(len(line) if a == along else 2 for a in range(3))
        power = point_spread(acquisition, (0.0, 0.0, 0.0), Grid(tuple(lower), tuple(upper), shape)).power().numpy()
        widths.append(half_power_width(line, np.moveaxis(power, along, 0)[:, 0, 0]))
    return widths[0], widths[1]


def _point(setting: dict, settings: Settings, reference) -> Point:
    radar = small_radar(bandwidth_hz=setting["bandwidth_ghz"] * 1e9, array_m=setting["array_cm"] * 1e-2,
                        elements_per_edge=round(setting["array_cm"] / 2) + 1,  # 2 cm apart at every size
                        snr_db=setting["snr_db"], rings=_RINGS[setting["views"]])
    data = ball_data(radar, settings.seed)
    power = matched_filter(data, GRID, method="exact").power().numpy()
    mf = best_threshold_mesh(power, GRID, reference, samples=settings.metric_samples,
                             seed=settings.seed).metrics.chamfer_l1_mm
    config = fit_config(_START_M, settings.steps, settings.seed, views_per_step=setting["views"])

    def chamfer(field) -> float:
        mesh = extract_mesh(field.sdf, GRID.lower_m, GRID.upper_m, 48)
        return compare_meshes(mesh, reference, samples=settings.metric_samples, seed=settings.seed).chamfer_l1_mm

    with tempfile.TemporaryDirectory() as folder:
        trainer = Trainer(Problem(data, GRID), config, folder)
        start = chamfer(trainer.field)
        fit = chamfer(trainer.fit().field)
    range_resolution = range_resolution_m(swept_bandwidth_hz(radar.frequencies_hz))
    cross_resolution = cross_range_resolution_m(radar.acquisition().wavelength_m, 0.3, radar.aperture_m)
    range_psf, cross_psf = _psf_widths(radar, 2 * max(range_resolution, cross_resolution))
    return Point(**setting, range_psf_mm=range_psf * 1e3, cross_psf_mm=cross_psf * 1e3,
                 range_resolution_mm=range_resolution * 1e3, cross_resolution_mm=cross_resolution * 1e3,
                 mf_chamfer_mm=mf, start_chamfer_mm=start, fit_chamfer_mm=fit)


def run(settings: Settings) -> Result:
    sweeps = {}
    reference = load_scene("sphere").ground_truth_mesh()  # the ball's true surface, meshed once
    for key, values in (("bandwidth_ghz", settings.bandwidths_ghz), ("array_cm", settings.arrays_cm),
                        ("snr_db", settings.snrs_db), ("views", settings.view_counts)):
        if values:
            sweeps[key] = [dataclasses.asdict(_point({**_CENTRE, key: value}, settings, reference)) for value in values]
    return Result(sweeps)


_LABELS = {"bandwidth_ghz": "bandwidth [GHz]", "array_cm": "array edge [cm]", "snr_db": "SNR [dB]",
           "views": "views"}


def plot(result: Result, path) -> None:
    fig, axes = plt.subplots(1, len(result.sweeps), figsize=(4.2 * len(result.sweeps), 4), layout="constrained",
                             squeeze=False)
    for ax, (key, points) in zip(axes[0], result.sweeps.items()):
        x = [p[key] for p in points]
        ax.plot(x, [p["mf_chamfer_mm"] for p in points], "s-", label="MF threshold (best)")
        ax.plot(x, [p["fit_chamfer_mm"] for p in points], "o-", label="GeRaF fit")
        ax.plot(x, [p["start_chamfer_mm"] for p in points], "x:", color="C1", label="the fit's start")
        ax.plot(x, [p["range_psf_mm"] / 10 for p in points], "--", color="0.5", label="range PSF / 10")
        ax.plot(x, [p["cross_psf_mm"] / 10 for p in points], ":", color="0.5", label="cross-range PSF / 10")
        ax.set_xlabel(_LABELS[key])
        ax.set_ylabel("Chamfer-L1 [mm]")
        ax.set_yscale("log")
    axes[0][0].legend(fontsize=8)
    fig.suptitle("a 2 cm metal ball: surface error against the matched filter's resolution")
    save_figure(fig, path)
