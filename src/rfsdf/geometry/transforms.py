"""Rigid transforms and uniform scaling of SDFs (distance-preserving, so exactness is kept)."""

from __future__ import annotations

import math

import torch

from .base import SDF, _param, as_vector

__all__ = ["Translate", "Rotate", "Scale", "rotation_matrix", "rotation_from_vector"]


def rotation_matrix(axis, angle_rad: float) -> torch.Tensor:
    """(3, 3) float64 rotation about ``axis`` by ``angle_rad`` [rad] (Rodrigues, right-handed)."""
    a = as_vector(axis, "axis")
    norm = torch.linalg.norm(a)
    if norm < 1e-12:
        raise ValueError("rotation axis must be a non-zero vector")
    x, y, z = (a / norm).tolist()
    k = torch.tensor([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * (k @ k)


def rotation_from_vector(vector: torch.Tensor) -> torch.Tensor:
    """(3, 3) rotation by the rotation vector ``vector`` (3,) [rad] (axis times angle; Rodrigues),
    differentiable in it, in its dtype: a fitted frame's orientation (``rotation_matrix`` takes
    numbers, for a shape's fixed transform).

    >>> quarter = rotation_from_vector(torch.tensor([0.0, 0.0, math.pi / 2], dtype=torch.float64))
    >>> (quarter @ torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)).round(decimals=12).tolist()
    [0.0, 1.0, 0.0]
    """
    angle = torch.sqrt((vector**2).sum() + torch.finfo(vector.dtype).tiny)
    k = vector / angle
    zero = torch.zeros((), dtype=vector.dtype, device=vector.device)
    cross = torch.stack([torch.stack([zero, -k[2], k[1]]), torch.stack([k[2], zero, -k[0]]),
                         torch.stack([-k[1], k[0], zero])])
    eye = torch.eye(3, dtype=vector.dtype, device=vector.device)
    return eye + torch.sin(angle) * cross + (1 - torch.cos(angle)) * (cross @ cross)


class Translate(SDF):
    """``shape`` moved by ``offset_m`` (3,) [m]: f(p - t)."""

    def __init__(self, shape: SDF, offset_m):
        self.shape, self.offset = shape, as_vector(offset_m, "offset")
        self.exact = shape.exact

    def _evaluate(self, points):
        return self.shape(points - _param(self.offset, points))

    def bounding_sphere(self):
        inner = self.shape.bounding_sphere()
        return None if inner is None else (inner[0] + self.offset, inner[1])


class Rotate(SDF):
    """``shape`` rotated by R about the origin: f(R^T p)."""

    def __init__(self, shape: SDF, axis, angle_rad: float):
        self.shape, self.matrix = shape, rotation_matrix(axis, float(angle_rad))
        self.exact = shape.exact

    def _evaluate(self, points):
        # (R^T p) for row vectors is p @ R.
        return self.shape(points @ _param(self.matrix, points))

    def bounding_sphere(self):
        inner = self.shape.bounding_sphere()
        return None if inner is None else (self.matrix @ inner[0], inner[1])


class Scale(SDF):
    """``shape`` scaled by ``factor`` about the origin: s * f(p / s)."""

    def __init__(self, shape: SDF, factor: float):
        factor = float(factor)
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"scale factor must be positive, got {factor}")
        self.shape, self.factor = shape, factor
        self.exact = shape.exact

    def _evaluate(self, points):
        return self.factor * self.shape(points / self.factor)

    def bounding_sphere(self):
        inner = self.shape.bounding_sphere()
        return None if inner is None else (self.factor * inner[0], self.factor * inner[1])
