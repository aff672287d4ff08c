"""Baselines: what a radar engineer would threshold. Marching cubes on an image's power (the
raw MF image, or its CLEAN image) at a fraction of its peak, reported at the best fraction
of a sweep chosen against the truth, so the comparison with the neural reconstruction is
generous to them; and the local (CFAR-like) detection that the fit's warm start uses, at
its fixed settings."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from .geometry.grid import Grid
from .mesh import mesh_from_volume
from .metrics import MeshMetrics, compare_meshes
from .radar.detection import amplitude_of, detection_level, window_voxels

__all__ = ["DEFAULT_FRACTIONS", "threshold_mesh", "detection_mesh", "BaselineResult", "best_threshold_mesh"]

DEFAULT_FRACTIONS = (0.003, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5)


def threshold_mesh(power: np.ndarray, grid: Grid, fraction: float) -> trimesh.Trimesh:
    """Mesh of the set where ``power`` (nx, ny, nz) >= ``fraction`` of its maximum."""
    power = np.asarray(power, float)
    return mesh_from_volume(-power / power.max(), grid, level=-fraction)


def detection_mesh(power: np.ndarray, grid: Grid, *, threshold: float, local_threshold: float,
                   window_m: float, exclude: np.ndarray | None = None) -> trimesh.Trimesh:
    """Mesh of the boundary of :func:`~rfsdf.radar.detection.detection_mask` (the amplitude
    crossing its local level), by marching cubes on amplitude - level, less the voxels of
    ``exclude`` (bool, grid.shape; the warm start's exclusions)."""
    level = detection_level(power, threshold=threshold, local_threshold=local_threshold,
                            window_voxels=window_voxels(window_m, grid))
    values = level - amplitude_of(power)
    if exclude is not None:
        values = np.where(exclude, np.abs(values).max(), values)
    return mesh_from_volume(values, grid, level=0.0)


@dataclass(frozen=True)
class BaselineResult:
    """The best threshold mesh and what the sweep measured (Chamfer-L1 [mm] per fraction)."""

    fraction: float
    mesh: trimesh.Trimesh
    metrics: MeshMetrics
    sweep: dict[float, float]


def best_threshold_mesh(power: np.ndarray, grid: Grid, reference: trimesh.Trimesh, *,
                        fractions=DEFAULT_FRACTIONS, threshold_m: float = 0.005, samples: int = 50_000,
                        seed: int = 0) -> BaselineResult:
    """Sweep ``fractions`` of the peak MF power; keep the mesh with the lowest Chamfer-L1."""
    best: BaselineResult | None = None
    sweep: dict[float, float] = {}
    for fraction in fractions:
        try:
            mesh = threshold_mesh(power, grid, fraction)
        except ValueError:  # the level is outside the image's range: nothing to mesh
            continue
        metrics = compare_meshes(mesh, reference, threshold_m=threshold_m, samples=samples, seed=seed)
        sweep[fraction] = metrics.chamfer_l1_mm
        if best is None or metrics.chamfer_l1_mm < best.metrics.chamfer_l1_mm:
            best = BaselineResult(fraction, mesh, metrics, sweep)
    if best is None:
        raise ValueError("no threshold of the sweep gives a surface inside the box")
    return best  # its sweep is the dict filled in above, complete now
