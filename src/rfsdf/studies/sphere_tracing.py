"""Sphere tracing a sphere: iterations against the incidence angle and the distance.

A ray o + t d from distance D towards a sphere of radius R, offset by the impact parameter
b, meets it at incidence angle theta with sin theta = b / R. Each step moves by the SDF,
t_{k+1} = t_k + sqrt((D - t_k)^2 + b^2) - R in closed form, so the ray through the centre
(b = 0) lands on the surface in one step, and near grazing (b -> R) the steps shrink as the
ray runs along the surface: the iteration count grows without bound as theta -> 90 deg.
Rays with b > R miss and leave after a few steps once past the sphere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ..geometry import Sphere, sphere_trace
from ..viz.figures import plt, save_figure

NAME = "sphere-tracing"
SUMMARY = "iterations to converge against incidence angle and distance; the centre ray takes one step"


@dataclass(frozen=True)
class Settings:
    radius_m: float = 0.1
    distances_m: tuple[float, ...] = (0.3, 1.0, 3.0)
    angles: int = 60  # incidence angles from 0 to 89.9 deg
    eps_m: float = 1e-6
    max_steps: int = 2000
    worked_impact_m: float = 0.05  # the worked example's b (theta = 30 deg at R = 0.1 m), at the first distance


QUICK = Settings(distances_m=(0.3, 1.0), angles=12)


@dataclass(frozen=True)
class Result:
    angles_deg: list[float]
    steps: dict[str, list[int]]  # per distance [m] (as text): steps to converge at each angle
    every_ray_below_radius_hits: bool
    miss_impacts_over_radius: list[float]
    miss_steps: dict[str, list[int]]
    centre_ray_steps: dict[str, int]
    worked_closed_form_m: list[float]  # t_0 .. t_K by the recurrence
    worked_traced_m: list[float]  # the traced history
    worked_max_difference_m: float


def _trace(settings: Settings, distance: float, impacts: np.ndarray):
    origins = torch.tensor([[b, 0.0, -distance] for b in impacts], dtype=torch.float64)
    directions = torch.tensor([[0.0, 0.0, 1.0]] * len(impacts), dtype=torch.float64)
    return sphere_trace(Sphere(settings.radius_m), origins, directions, eps=settings.eps_m,
                        max_steps=settings.max_steps, t_max=3 * distance, record_history=True)


def run(settings: Settings) -> Result:
    radius = settings.radius_m
    angles = np.linspace(0.0, math.radians(89.9), settings.angles)
    misses = np.array([1.01, 1.1, 1.5])
    steps, miss_steps, centre, all_hit = {}, {}, {}, True
    for distance in settings.distances_m:
        hit = _trace(settings, distance, radius * np.sin(angles))
        all_hit &= bool(hit.hit.all())
        steps[f"{distance:g}"] = hit.steps.tolist()
        centre[f"{distance:g}"] = int(hit.steps[0])
        miss_steps[f"{distance:g}"] = _trace(settings, distance, radius * misses).steps.tolist()
    distance, b = settings.distances_m[0], settings.worked_impact_m
    traced = _trace(settings, distance, np.array([b]))
    history = traced.history[: int(traced.steps[0]) + 1, 0].tolist()
    closed = [0.0]
    for _ in range(len(history) - 1):
        closed.append(closed[-1] + math.sqrt((distance - closed[-1]) ** 2 + b**2) - radius)
    return Result([math.degrees(a) for a in angles], steps, all_hit, misses.tolist(), miss_steps, centre, closed, history,
                  float(np.max(np.abs(np.subtract(closed, history)))))


def plot(result: Result, path) -> None:
    fig, (ax, worked) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    for distance, steps in result.steps.items():
        ax.semilogy(result.angles_deg, steps, marker="o", ms=3, label=f"D = {distance} m")
    ax.set_xlabel("incidence angle [deg]")
    ax.set_ylabel("steps to |f| < eps [count]")
    ax.set_title("sphere tracing a sphere: grazing rays creep")
    ax.legend()
    k = np.arange(len(result.worked_traced_m))
    worked.plot(k, result.worked_closed_form_m, "k-", label="closed form t_k")
    worked.plot(k, result.worked_traced_m, "o", color="tab:orange", label="traced history")
    worked.set_xlabel("iteration k")
    worked.set_ylabel("t_k [m]")
    worked.set_title(f"worked example: max difference {result.worked_max_difference_m:.1e} m")
    worked.legend()
    save_figure(fig, path)
