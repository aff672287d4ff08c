"""Distances between a reconstructed mesh and the truth: Chamfer-L1, F-score, normal
consistency, 95th-percentile Hausdorff (all from area-uniform surface samples and nearest
neighbours) and volumetric IoU (from inside/outside tests on uniform points in a box)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Callable

import numpy as np
import torch
import trimesh
from scipy.spatial import cKDTree

from .geometry import MeshSDF

__all__ = ["MeshMetrics", "compare_meshes", "volumetric_iou", "evaluate_mesh", "with_scene_iou"]


@dataclass(frozen=True)
class MeshMetrics:
    """chamfer_l1_mm: mean of the two mean nearest distances [mm]; fscore, precision, recall
    at ``threshold_mm``; normal_consistency: mean |n_a . n_b| of nearest pairs (1 = perfect);
    hausdorff95_mm: the larger of the two 95th-percentile nearest distances [mm]."""

    chamfer_l1_mm: float
    fscore: float
    precision: float
    recall: float
    threshold_mm: float
    normal_consistency: float
    hausdorff95_mm: float
    iou: float | None = None

    def as_dict(self) -> dict:
        return asdict(self)


def _samples(mesh: trimesh.Trimesh, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    points, faces = trimesh.sample.sample_surface(mesh, count, seed=seed)
    return np.asarray(points), np.asarray(mesh.face_normals[faces])


def compare_meshes(predicted: trimesh.Trimesh, reference: trimesh.Trimesh, *, threshold_m: float = 0.005,
                   samples: int = 50_000, seed: int = 0) -> MeshMetrics:
    """Surface metrics of ``predicted`` against ``reference`` (both in metres)."""
    if len(predicted.faces) == 0 or len(reference.faces) == 0:
        raise ValueError("cannot compare an empty mesh")
    pa, na = _samples(predicted, samples, seed)
    pb, nb = _samples(reference, samples, seed)  # same seed: identical meshes give exactly 0
    d_ab, i_ab = cKDTree(pb).query(pa)  # accuracy: predicted -> reference
    d_ba, i_ba = cKDTree(pa).query(pb)  # completeness: reference -> predicted
    precision, recall = float((d_ab < threshold_m).mean()), float((d_ba < threshold_m).mean())
    fscore = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    consistency = 0.5 * (np.abs((na * nb[i_ab]).sum(1)).mean() + np.abs((nb * na[i_ba]).sum(1)).mean())
    return MeshMetrics(
        chamfer_l1_mm=float(0.5 * (d_ab.mean() + d_ba.mean()) * 1e3), fscore=fscore, precision=precision,
        recall=recall, threshold_mm=threshold_m * 1e3, normal_consistency=float(consistency),
        hausdorff95_mm=float(max(np.percentile(d_ab, 95), np.percentile(d_ba, 95)) * 1e3),
    )


def volumetric_iou(predicted: trimesh.Trimesh, inside_reference: Callable[[torch.Tensor], torch.Tensor],
                   lower_m, upper_m, *, samples: int = 20_000, seed: int = 0) -> float:
    """|A and B| / |A or B| on uniform points in the box; A = inside ``predicted`` (a closed
    mesh; sign of its exact SDF, much faster than ray tests without embree), B = where
    ``inside_reference(points)`` is true (e.g. scene SDF < 0)."""
    rng = np.random.default_rng(seed)
    lower, upper = np.asarray(lower_m, float), np.asarray(upper_m, float)
    points = lower + (upper - lower) * rng.random((samples, 3))
    with torch.no_grad():
        a = (MeshSDF(predicted)(torch.as_tensor(points)) < 0).cpu().numpy()
        b = inside_reference(torch.as_tensor(points, dtype=torch.float32)).cpu().numpy().astype(bool)
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 1.0


def evaluate_mesh(mesh: trimesh.Trimesh, scene, *, threshold_m: float = 0.005, samples: int = 50_000,
                  seed: int = 0) -> MeshMetrics:
    """Metrics of ``mesh`` against a :class:`~rfsdf.scene.Scene`'s true surfaces; the IoU is
    filled in when the mesh is closed (an open mesh has no inside)."""
    metrics = compare_meshes(mesh, scene.ground_truth_mesh(), threshold_m=threshold_m, samples=samples, seed=seed)
    return with_scene_iou(metrics, mesh, scene, seed=seed)


def with_scene_iou(metrics: MeshMetrics, mesh: trimesh.Trimesh, scene, *, seed: int = 0) -> MeshMetrics:
    """``metrics`` of ``mesh`` with its volumetric IoU against ``scene`` filled in when the mesh
    is closed (for surface metrics already computed, e.g. by the baseline's sweep)."""
    if not mesh.is_watertight:
        return metrics
    iou = volumetric_iou(mesh, lambda p: scene.sdf(p) < 0, scene.lower_m, scene.upper_m, seed=seed)
    return replace(metrics, iou=iou)
