"""Occupancy network against neural SDF: the same network, points and budget, two targets.

An occupancy network learns o(x) = sigmoid(-alpha h(x)), inside where o > 1/2, from binary
labels (binary cross-entropy); a neural SDF learns f(x) = the signed distance itself
(clipped L1 plus the Eikonal term, the warm start's regression). Both surfaces are a zero
set (h = 0, f = 0), both normals a gradient. But the labels only say on which side of the
surface a point lies, not how far: between samples the occupancy's zero set is free to
wander, and nothing asks grad h to be smooth or of unit length; the distance pins f and its
gradient at every point. The sharpness alpha [1/m] sets how far from the surface labels
still pull (about 1/alpha).

Measured: a RadarField's geometry network (default depth and width, geometric initialisation
to a sphere half the box) trained both ways with Adam on the same batches (uniform in the
box, a quarter within 2 mm of the true surface), on the `sphere` and `objects` scenes: the
Chamfer-L1 of the zero set's mesh against the true surface, and the mean angle between the
gradient and the true normal at true surface points; and the occupancy's alpha swept on
the sphere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..field import RadarField
from ..geometry import gradient
from ..mesh import extract_mesh
from ..metrics import compare_meshes
from ..recon.warm_start import fit_to_image
from ..scene import load_scene
from ..viz.figures import plt, save_figure

NAME = "occupancy-vs-sdf"
SUMMARY = "occupancy (sigmoid + BCE) against SDF regression: surface error and normal angle, alpha swept"

_NEAR_M = 0.002  # the near-surface share of each batch lies within this of the surface


@dataclass(frozen=True)
class Settings:
    scenes: tuple[str, ...] = ("sphere", "objects")
    alpha_per_m: float = 1000.0  # occupancy sharpness of the scene comparison
    alphas_per_m: tuple[float, ...] = (100.0, 1000.0, 10000.0)  # swept on the first scene
    steps: int = 400
    batch: int = 4096
    mesh_resolution: int = 96
    seed: int = 0


QUICK = Settings(scenes=("sphere",), alphas_per_m=(1000.0,), steps=80, batch=1024, mesh_resolution=40)


@dataclass(frozen=True)
class Result:
    scenes: list[str]
    sdf_chamfer_mm: list[float]
    occupancy_chamfer_mm: list[float]
    sdf_normal_error_deg: list[float]
    occupancy_normal_error_deg: list[float]
    alphas_per_m: list[float]  # on scenes[0]
    alpha_chamfer_mm: list[float]
    alpha_normal_error_deg: list[float]


def _field(scene, seed: int) -> RadarField:
    torch.manual_seed(seed)
    extent = float(np.max(scene.upper_m - scene.lower_m))
    return RadarField(scene.lower_m, scene.upper_m, levels=4, init_radius_m=extent / 4)


def _batches(scene, settings: Settings, near: torch.Tensor):
    """The same ``settings.steps`` batches (N, 3) [m] for every network."""
    generator = torch.Generator().manual_seed(settings.seed)
    lower = torch.as_tensor(scene.lower_m, dtype=torch.float32)
    extent = torch.as_tensor(scene.upper_m - scene.lower_m, dtype=torch.float32)
    count = settings.batch // 4
    for _ in range(settings.steps):
        points = lower + extent * torch.rand(settings.batch, 3, generator=generator)
        pick = torch.randint(len(near), (count,), generator=generator)
        points[:count] = near[pick] + _NEAR_M * (2 * torch.rand(count, 3, generator=generator) - 1)
        yield points


def _fit_occupancy(scene, settings: Settings, alpha: float, near: torch.Tensor) -> RadarField:
    field = _field(scene, settings.seed)
    optimizer = torch.optim.Adam(field.parameters(), lr=1e-3)
    for points in _batches(scene, settings, near):
        with torch.no_grad():
            inside = (scene.sdf(points) < 0).float()
        loss = torch.nn.functional.binary_cross_entropy_with_logits(-alpha * field.sdf(points), inside)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return field


def _fit_sdf(scene, settings: Settings, near: torch.Tensor) -> RadarField:
    field = _field(scene, settings.seed)
    fit_to_image(field, scene.lower_m, scene.upper_m, scene.sdf, None, steps=settings.steps, lr=1e-3,
                 batch=settings.batch, eikonal_weight=0.1, generator=torch.Generator().manual_seed(settings.seed),
                 near_m=near, near_share=0.25, near_jitter_m=_NEAR_M)
    return field


def _scores(field: RadarField, scene, reference, surface, settings: Settings) -> tuple[float, float]:
    """(Chamfer-L1 [mm] of the zero set's mesh, mean angle [deg] of grad at true surface points)."""
    mesh = extract_mesh(field.sdf, scene.lower_m, scene.upper_m, settings.mesh_resolution)
    chamfer = compare_meshes(mesh, reference, samples=20_000, seed=settings.seed).chamfer_l1_mm
    normals = torch.nn.functional.normalize(gradient(field.sdf, surface.points), dim=1)
    cosine = (normals * surface.normals).sum(1).clamp(-1, 1)
    return chamfer, float(torch.rad2deg(torch.arccos(cosine)).mean())


def run(settings: Settings) -> Result:
    rows: dict[str, list] = {k: [] for k in ("sdf_chamfer", "occ_chamfer", "sdf_normal", "occ_normal")}
    alpha_chamfer, alpha_normal = [], []
    for index, name in enumerate(settings.scenes):
        scene = load_scene(name)
        reference = scene.ground_truth_mesh()
        surface = scene.sample_surface(0.002, seed=settings.seed, max_samples=20_000)
        near = surface.points
        chamfer, normal = _scores(_fit_sdf(scene, settings, near), scene, reference, surface, settings)
        rows["sdf_chamfer"].append(chamfer)
        rows["sdf_normal"].append(normal)
        alphas = settings.alphas_per_m if index == 0 else ()
        for alpha in sorted({settings.alpha_per_m, *alphas}):
            chamfer, normal = _scores(_fit_occupancy(scene, settings, alpha, near), scene, reference, surface, settings)
            if alpha == settings.alpha_per_m:
                rows["occ_chamfer"].append(chamfer)
                rows["occ_normal"].append(normal)
            if alpha in alphas:
                alpha_chamfer.append(chamfer)
                alpha_normal.append(normal)
    return Result(list(settings.scenes), rows["sdf_chamfer"], rows["occ_chamfer"], rows["sdf_normal"],
                  rows["occ_normal"], sorted(settings.alphas_per_m), alpha_chamfer, alpha_normal)


def plot(result: Result, path) -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    x = np.arange(len(result.scenes))
    left.bar(x - 0.2, result.sdf_normal_error_deg, 0.4, label="neural SDF")
    left.bar(x + 0.2, result.occupancy_normal_error_deg, 0.4, label="occupancy")
    for i in x:
        for dx, value in ((-0.2, result.sdf_chamfer_mm[i]), (0.2, result.occupancy_chamfer_mm[i])):
            left.annotate(f"CD {value:.2f} mm", (i + dx, 0), textcoords="offset points", xytext=(0, 4),
                          ha="center", fontsize=7, rotation=90, color="w")
    left.set_xticks(x, result.scenes)
    left.set_ylabel("mean normal angle error at the true surface [deg]")
    left.set_title("same network, points and steps (CD: Chamfer-L1)")
    left.legend(fontsize=8)
    right.semilogx(result.alphas_per_m, result.alpha_normal_error_deg, "o-", label="normal error [deg]")
    right.semilogx(result.alphas_per_m, result.alpha_chamfer_mm, "s-", label="Chamfer-L1 [mm]")
    right.axhline(result.sdf_normal_error_deg[0], color="C0", ls=":", label="SDF normal error [deg]")
    right.axhline(result.sdf_chamfer_mm[0], color="C1", ls=":", label="SDF Chamfer-L1 [mm]")
    right.set_xlabel("occupancy sharpness alpha [1/m]")
    right.set_title(f"occupancy on {result.scenes[0]!r} against alpha")
    right.legend(fontsize=8)
    save_figure(fig, path)
