"""Where the Eikonal points are drawn: uniform in the box, near the surface, or both.

The data pin f only at the surface; the Eikonal term |grad f| = 1 is what makes f a
distance elsewhere, and it acts only where it is evaluated. Points uniform in the box keep
f a distance everywhere, but few of them fall where the surface is decided; points near
the zero set (the fit's own: it does not know the true one) shape the surface and its
normals but leave the rest of the box free, where spurious zero sets can appear. The fit
(`[sampling] eikonal_near`) mixes the two, half and half by default.

Measured: a RadarField (geometric initialisation to a sphere of a quarter of the box)
fitted to the true surface samples of a scene (data term mean |f(p)|, Eikonal weight 0.1,
Adam) with the Eikonal points drawn by :func:`rfsdf.recon.sampling.eikonal_points` at each
near share, the near points being voxel centres of the fit's own current zero set
(refreshed every 20 steps, as the trainer's surface anchors) with one voxel of jitter:
the Chamfer-L1 of the zero set's mesh against the truth, the mean | |grad f| - 1 | on
uniform points of the box and on points within 5 mm of the true surface, and the seconds
per step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from ..field import RadarField
from ..geometry import Grid, gradient
from ..mesh import evaluate_on_grid, extract_mesh
from ..metrics import compare_meshes
from ..recon.losses import eikonal_loss
from ..recon.sampling import eikonal_points
from ..scene import load_scene
from ..viz.figures import plt, save_figure

NAME = "eikonal-sampling"
SUMMARY = "uniform, near-surface and mixed Eikonal points: surface error, |grad f| - 1 in the box and near it, time"

_REFRESH = 20  # steps between new near points (the fit's own zero set)
_ANCHOR_VOXELS = 48  # grid of the near points


@dataclass(frozen=True)
class Settings:
    scene: str = "objects"
    near_shares: tuple[float, ...] = (0.0, 0.5, 1.0)
    steps: int = 600
    batch: int = 2048  # surface samples and Eikonal points per step, each
    eikonal_weight: float = 0.1
    mesh_resolution: int = 96
    seed: int = 0


QUICK = Settings(scene="sphere", near_shares=(0.0, 1.0), steps=60, batch=512, mesh_resolution=40)


@dataclass(frozen=True)
class Result:
    near_shares: list[float]
    chamfer_mm: list[float]
    eikonal_box: list[float]  # mean | |grad f| - 1 | on uniform points of the box
    eikonal_near: list[float]  # ... within 5 mm of the true surface
    seconds_per_step: list[float]


def _own_zero_set(field: RadarField, grid: Grid) -> torch.Tensor:
    """(M, 3) voxel centres within a voxel of the field's zero set (all centres if none)."""
    values = torch.from_numpy(evaluate_on_grid(field.sdf, grid)).flatten()
    near = values.abs() < float(np.max(grid.voxel_m))
    points = grid.points()
    return points[near] if bool(near.any()) else points


def _fit(scene, settings: Settings, near_share: float, surface: torch.Tensor) -> tuple[RadarField, float]:
    torch.manual_seed(settings.seed)
    extent = float(np.max(scene.upper_m - scene.lower_m))
    field = RadarField(scene.lower_m, scene.upper_m, levels=4, init_radius_m=extent / 4)
    optimizer = torch.optim.Adam(field.parameters(), lr=1e-3)
    generator = torch.Generator().manual_seed(settings.seed)
    grid = Grid(scene.lower_m, scene.upper_m, (_ANCHOR_VOXELS,) * 3)
    jitter = float(np.max(grid.voxel_m))
    start = time.perf_counter()
    for step in range(settings.steps):
        if step % _REFRESH == 0:
            anchors = _own_zero_set(field, grid)
        data = surface[torch.randint(len(surface), (settings.batch,), generator=generator)]
        points = eikonal_points(scene.lower_m, scene.upper_m, anchors, settings.batch, near_share, jitter, generator)
        loss = field.sdf(data).abs().mean() + settings.eikonal_weight * eikonal_loss(field.sdf, points)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return field, (time.perf_counter() - start) / settings.steps


def _eikonal_residual(field: RadarField, points: torch.Tensor) -> float:
    return float((gradient(field.sdf, points).norm(dim=1) - 1).abs().mean())


def run(settings: Settings) -> Result:
    scene = load_scene(settings.scene)
    reference = scene.ground_truth_mesh()
    surface = scene.sample_surface(0.002, seed=settings.seed, max_samples=50_000).points
    generator = torch.Generator().manual_seed(settings.seed + 1)
    lower = torch.as_tensor(scene.lower_m, dtype=torch.float32)
    box = lower + torch.as_tensor(scene.upper_m - scene.lower_m, dtype=torch.float32) * torch.rand(
        20_000, 3, generator=generator)
    shell = surface[torch.randint(len(surface), (20_000,), generator=generator)]
    shell = shell + 0.005 * (2 * torch.rand(20_000, 3, generator=generator) - 1) / np.sqrt(3)  # within 5 mm
    chamfer, in_box, near, seconds = [], [], [], []
    for share in settings.near_shares:
        field, per_step = _fit(scene, settings, share, surface)
        mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution)
        chamfer.append(compare_meshes(mesh, reference, samples=20_000, seed=settings.seed).chamfer_l1_mm)
        in_box.append(_eikonal_residual(field, box))
        near.append(_eikonal_residual(field, shell))
        seconds.append(per_step)
    return Result(list(settings.near_shares), chamfer, in_box, near, seconds)


def plot(result: Result, path) -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    labels = [{0.0: "uniform", 1.0: "near"}.get(s, f"mixed ({s:g} near)") for s in result.near_shares]
    x = np.arange(len(labels))
    left.bar(x, result.chamfer_mm, 0.5)
    for i, (value, seconds) in enumerate(zip(result.chamfer_mm, result.seconds_per_step)):
        left.annotate(f"{value:.2f} mm\n{seconds * 1e3:.0f} ms/step", (i, value), textcoords="offset points",
                      xytext=(0, 3), ha="center", fontsize=8)
    left.set_xticks(x, labels)
    left.set_ylabel("Chamfer-L1 of the zero set [mm]")
    left.set_title("surface error by Eikonal sampling")
    right.bar(x - 0.2, result.eikonal_box, 0.4, label="uniform in the box")
    right.bar(x + 0.2, result.eikonal_near, 0.4, label="within 5 mm of the surface")
    right.set_xticks(x, labels)
    right.set_ylabel("mean | |grad f| - 1 |")
    right.set_title("where f stays a distance")
    right.legend(fontsize=8)
    save_figure(fig, path)
