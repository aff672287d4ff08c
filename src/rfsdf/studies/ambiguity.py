"""One view against several: which surfaces explain the data as well as the truth.

A metal ball of radius r seen from one view returns one glint, from the point nearest the
radar. The family "radius r + delta, centre moved delta away from that view" keeps that
point where it is, and a brighter or dimmer ball is only a different reflectivity, which
the fit's least-squares gain absorbs (radar data carry no absolute calibration). So from
one view every member of the family explains the data about as well as the truth. Views
from other angles see other points of the ball, and those move by delta (u_v - u_0): only
the truth explains all views at once.

Measured: the data loss of the fit (``amplitude``: MF amplitude images, one gain fitted
over all views) between the noisy data of the true ball and the noise-free data of each
family member, imaged by the same matched filter, against delta, for views spread evenly
on one ring (the first view defines the family). The simulator's converged quadrature
(facets of the zero set, two meshes agreeing per view to 0.9996) covers each ball; the
predictions' facets sit on a grid offset by another seed than the data's, as a fit's
samples are drawn afresh, so the loss of the truth itself (delta = 0) is the floor of the
noise; the contrast is the family's largest loss over that floor (about 1: nothing in the
sweep is told from the truth).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

import numpy as np
import torch

from ..geometry import Grid
from ..radar import Radar, matched_filter, simulate
from ..radar.system import RadarSpec
from ..recon.losses import amplitude_loss
from ..scene import Scene
from ..scene_spec import SceneSpec
from ..viz.figures import plt, save_figure

NAME = "ambiguity"
SUMMARY = "loss along 'bigger ball, moved back' from one view and from several: more views, one answer"

_HALF = 0.06  # half box [m]


@dataclass(frozen=True)
class Settings:
    radius_m: float = 0.02
    deltas_mm: tuple[float, ...] = (-8.0, -6.0, -4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0, 6.0, 8.0)  # with 0: the truth
    view_counts: tuple[int, ...] = (1, 2, 3, 4)
    snr_db: float = 30.0
    voxels: int = 24
    subcarriers: int = 16
    seed: int = 0


QUICK = Settings(deltas_mm=(-6.0, 0.0, 6.0), view_counts=(1, 4), voxels=12, subcarriers=8)


@dataclass(frozen=True)
class Result:
    deltas_mm: list[float]
    view_counts: list[int]
    loss: list[list[float]]  # [view count][delta]: amplitude loss against the noisy truth
    noise_floor: list[float]  # loss of the truth itself (delta = 0: noise and sampling), per view count
    contrast: list[float]  # largest loss of the family over the truth's, per view count


def _ball(radius_m: float, centre_m) -> Scene:
    return Scene(SceneSpec.model_validate({
        "name": "ball", "bounds": {"lower_m": [-_HALF] * 3, "upper_m": [_HALF] * 3},
        "objects": [{"name": "ball", "material": "metal",
                     "shape": {"type": "sphere", "radius_m": radius_m, "center_m": [float(c) for c in centre_m]}}]}))


def _radar(views: int, settings: Settings) -> Radar:
    return Radar.from_spec(RadarSpec.model_validate({
        "name": f"ring-{views}", "waveform": {"kind": "ofdm", "carrier_hz": 79e9, "bandwidth_hz": 4e9,
                                              "subcarriers": settings.subcarriers},
        "array": {"kind": "boundary", "size_m": 0.06, "elements_per_edge": 8},
        "views": {"distance_m": 0.4, "azimuths_per_ring": [views], "elevations_rad": [0.0]},
        "noise": {"snr_db": settings.snr_db}}))


def _images(scene: Scene, radar: Radar, seed: int, *, grid: Grid) -> torch.Tensor:
    """(V, N) complex per-view MF images of the simulated data of ``scene``."""
    data = simulate(scene, radar, seed=seed)
    return matched_filter(data, grid, method="exact").per_view.reshape(len(radar.rotations), -1)


def run(settings: Settings) -> Result:
    grid = Grid((-_HALF,) * 3, (_HALF,) * 3, (settings.voxels,) * 3)
    losses, floors, contrasts = [], [], []
    for views in settings.view_counts:
        radar = _radar(views, settings)
        quiet = dataclasses.replace(radar, snr_db=None)
        toward_first = radar.positions_m[0] / np.linalg.norm(radar.positions_m[0])  # u_0

        images = partial(_images, grid=grid)
        # the prediction's facets on a grid offset by another seed than the data's, as a fit
        # samples its surface afresh: the converged quadrature makes them agree to 0.9996
        observed = images(_ball(settings.radius_m, (0.0, 0.0, 0.0)), radar, settings.seed).abs()
        row = []
        for delta_mm in settings.deltas_mm:
            delta = delta_mm * 1e-3
            member = _ball(settings.radius_m + delta, -delta * toward_first)
            row.append(float(amplitude_loss(images(member, quiet, settings.seed + 1), observed)))
        floor = row[settings.deltas_mm.index(0.0)]
        losses.append(row)
        floors.append(floor)
        contrasts.append(max(row) / floor)
    return Result(list(settings.deltas_mm), list(settings.view_counts), losses, floors, contrasts)


def plot(result: Result, path) -> None:
    fig, ax = plt.subplots(figsize=(6.5, 4), layout="constrained")
    for views, row, floor, contrast in zip(result.view_counts, result.loss, result.noise_floor, result.contrast):
        line, = ax.plot(result.deltas_mm, row, "o-", label=f"{views} view{'s' * (views > 1)}: "
                                                             f"largest loss {contrast:.1f}x the truth's")
        ax.axhline(floor, color=line.get_color(), ls=":", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("delta [mm]: radius r + delta, centre moved delta away from view 1")
    ax.set_ylabel("amplitude loss against the noisy truth")
    ax.set_title("the 'bigger ball, moved back' family (dotted: the truth's loss)")
    ax.legend(fontsize=8)
    save_figure(fig, path)
