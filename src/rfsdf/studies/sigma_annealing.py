"""Coarse to fine: does comparing blurred images widen the fit's basin?

The fit compares predicted and observed MF amplitudes as root-mean-square over cubes of
`[sampling] cell_voxels` voxels per edge: a box blur of both power images, of width sigma.
A wide blur forgives a glint in the wrong voxel (in a voxel-by-voxel comparison a misplaced
glint is penalised twice, where it is and where it should be) and so might pull a surface
in from further away; a narrow one keeps the detail that sets the final accuracy. The
classic answer is to anneal: start wide, end narrow (`cell_voxels_start`). But the
amplitude of a coherent image of a smooth surface ripples with period lambda/2 as the
surface moves (its glint and its limb interfere), and a blur of the power does not remove
an interference that lies inside each voxel's value.

Measured: a small RadarField started as a ball too large by each start error around a
4 cm metal ball (a 4 cm array, 8 frequencies, 6 views; voxels 7.5 mm), fitted by the
trainer for the same steps with the cell edge constant at 1 voxel, constant at 4, and
annealed from 4 to 1: the radius of the zero set (mean of |p| - f(p) over the true sphere)
after every step, and its final error.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass

import numpy as np
import torch

from ..recon import Problem, Trainer
from ..viz.figures import plt, save_figure
from .ball_fit import GRID, RADIUS_M, ball_data, fit_config, small_radar, zero_set_radius

NAME = "sigma-annealing"
SUMMARY = "data compared over cubes of 1, 4, or 4 -> 1 voxels: radius error of a ball fitted from too large"

SCHEDULES = {"fine (1 voxel)": (1, None), "coarse (4 voxels)": (4, None), "annealed (4 -> 1)": (1, 4)}


@dataclass(frozen=True)
class Settings:
    start_errors_mm: tuple[float, ...] = (0.0, 2.0, 4.0, 6.0)
    steps: int = 60
    seed: int = 0


QUICK = Settings(start_errors_mm=(3.0,), steps=8)


@dataclass(frozen=True)
class Result:
    schedules: list[str]
    start_errors_mm: list[float]
    radius_error_mm: dict  # schedule -> [start error] -> radius - true radius [mm] after each step
    final_error_mm: dict  # schedule -> [start error] -> |radius - true radius| at the end [mm]
    wavelength_mm: float


def run(settings: Settings) -> Result:
    radar = small_radar()
    data = ball_data(radar, settings.seed)
    generator = torch.Generator().manual_seed(settings.seed)
    probes = RADIUS_M * torch.nn.functional.normalize(torch.randn(4096, 3, generator=generator), dim=1)
    curves: dict[str, list] = {name: [] for name in SCHEDULES}
    for name, (cell, cell_start) in SCHEDULES.items():
        for start in settings.start_errors_mm:
            config = fit_config(start * 1e-3, settings.steps, settings.seed, cell_voxels=cell,
                                cell_voxels_start=cell_start)
            with tempfile.TemporaryDirectory() as folder:
                trainer = Trainer(Problem(data, GRID), config, folder)
                curve = []

                def record(_step, trainer=trainer, curve=curve):
                    curve.append((zero_set_radius(trainer.field.sdf, probes) - RADIUS_M) * 1e3)

                trainer.fit(on_step=record)
            curves[name].append(curve)
    final = {name: [abs(c[-1]) for c in rows] for name, rows in curves.items()}
    return Result(list(SCHEDULES), list(settings.start_errors_mm), curves, final,
                  radar.acquisition().wavelength_m * 1e3)


def plot(result: Result, path) -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    styles = dict(zip(result.schedules, ("-", "--", ":")))
    for name, rows in result.radius_error_mm.items():
        for i, curve in enumerate(rows):  # one curve per start error
            left.plot(np.arange(1, len(curve) + 1), curve, styles[name], color=f"C{i}",
                      label=f"{name}" if i == 0 else None)
    for sign in (-1, 1):
        left.axhline(sign * result.wavelength_mm / 4, color="k", lw=0.6, ls=":")
    left.set_xlabel("step")
    left.set_ylabel("radius - true radius [mm] (dotted: +-lambda/4)")
    left.set_title("colour: start error; line: cell schedule")
    left.legend(fontsize=8)
    x = np.arange(len(result.start_errors_mm))
    for j, (name, errors) in enumerate(result.final_error_mm.items()):
        right.bar(x + (j - 1) * 0.27, errors, 0.27, label=name)
    right.set_xticks(x, [f"+{s:g} mm" for s in result.start_errors_mm])
    right.set_xlabel("start error")
    right.set_ylabel("final |radius error| [mm]")
    right.set_title("after the same steps")
    right.legend(fontsize=8)
    save_figure(fig, path)
