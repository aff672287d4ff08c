"""Exact analytic SDFs of the usual primitives (Inigo Quilez's formulas, in torch).

Every parameter is in metres; every class validates its parameters on construction.
"""

from __future__ import annotations

import math

import torch

from .base import SDF, _param, as_vector

__all__ = ["Sphere", "Box", "HalfSpace", "Cylinder", "CappedCylinder", "Torus", "Capsule"]


def _positive(value, name: str):
    """``value`` when it is a positive finite number [m]: a float, or a 0-d tensor kept as it
    is (a fitted parameter stays differentiable, ``rfsdf.recon.primitive``)."""
    number = float(value.detach() if isinstance(value, torch.Tensor) else value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a positive finite number [m], got {number}")
    return value if isinstance(value, torch.Tensor) else number


def _unit(vector, name: str) -> torch.Tensor:
    vec = as_vector(vector, name)
    norm = torch.linalg.norm(vec)
    if norm < 1e-12:
        raise ValueError(f"{name} must be a non-zero vector")
    return vec / norm


class Sphere(SDF):
    """Sphere of ``radius`` [m] about ``center`` (3,) [m]: f = |p - c| - r.

    >>> import torch
    >>> Sphere(0.02)(torch.tensor([[0.05, 0.0, 0.0], [0.0, 0.0, 0.0]], dtype=torch.float64))
    tensor([ 0.0300, -0.0200], dtype=torch.float64)
    """

    def __init__(self, radius: float, center=(0.0, 0.0, 0.0)):
        self.radius = _positive(radius, "radius")
        self.center = as_vector(center, "center")

    def _evaluate(self, points):
        return torch.linalg.norm(points - _param(self.center, points), dim=1) - self.radius


class Box(SDF):
    """Axis-aligned box with ``half_extents`` (3,) [m] about ``center`` (3,) [m]."""

    def __init__(self, half_extents, center=(0.0, 0.0, 0.0)):
        self.half_extents = as_vector(half_extents, "half_extents")
        if not (self.half_extents > 0).all():
            raise ValueError(f"half_extents must be positive [m], got {self.half_extents.tolist()}")
        self.center = as_vector(center, "center")

    def _evaluate(self, points):
        q = (points - _param(self.center, points)).abs() - _param(self.half_extents, points)
        # |max(q, 0)|, with the norm's kink at 0 (every point inside) taken by the clamp, whose
        # derivative there is 0, not by the norm's, whose second derivative is NaN: the primitive
        # fit differentiates the normals of inside points in the box's parameters
        squared = (q.clamp(min=0) ** 2).sum(1)
        outside = squared.clamp(min=torch.finfo(squared.dtype).tiny).sqrt()
        inside = q.max(dim=1).values.clamp(max=0)
        return outside + inside


class HalfSpace(SDF):
    """Half-space n.p <= offset (n normalised): f = n.p - offset [m]."""

    def __init__(self, normal, offset: float = 0.0):
        self.normal = _unit(normal, "normal")
        self.offset = float(offset)

    def _evaluate(self, points):
        return points @ _param(self.normal, points) - self.offset


def _axial_coordinates(points, origin, axis):
    """(radial, along) [m], each (N,): distance from, and position along, the line through
    ``origin`` with unit direction ``axis``."""
    rel = points - _param(origin, points)
    along = rel @ _param(axis, points)
    radial = torch.linalg.norm(rel - along[:, None] * _param(axis, points), dim=1)
    return radial, along


class Cylinder(SDF):
    """Infinite cylinder of ``radius`` [m] about the line through ``point`` along ``axis``."""

    def __init__(self, radius: float, axis=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0)):
        self.radius = _positive(radius, "radius")
        self.axis = _unit(axis, "axis")
        self.point = as_vector(point, "point")

    def _radial(self, points):
        return _axial_coordinates(points, self.point, self.axis)

    def _evaluate(self, points):
        return self._radial(points)[0] - self.radius


class CappedCylinder(Cylinder):
    """Cylinder of ``radius`` and ``height`` [m] centred on ``center`` along ``axis``."""

    def __init__(self, radius: float, height: float, axis=(0.0, 0.0, 1.0), center=(0.0, 0.0, 0.0)):
        super().__init__(radius, axis, center)
        self.height = _positive(height, "height")

    def _evaluate(self, points):
        radial, along = self._radial(points)
        d = torch.stack([radial - self.radius, along.abs() - self.height / 2], dim=1)
        return torch.linalg.norm(d.clamp(min=0), dim=1) + d.max(dim=1).values.clamp(max=0)


class Torus(SDF):
    """Torus: tube of ``minor_radius`` about a circle of ``major_radius`` [m] normal to ``axis``."""

    def __init__(self, major_radius: float, minor_radius: float, axis=(0.0, 0.0, 1.0), center=(0.0, 0.0, 0.0)):
        self.major_radius = _positive(major_radius, "major_radius")
        self.minor_radius = _positive(minor_radius, "minor_radius")
        if self.minor_radius >= self.major_radius:
            raise ValueError("minor_radius must be smaller than major_radius")
        self.axis = _unit(axis, "axis")
        self.center = as_vector(center, "center")

    def _evaluate(self, points):
        radial, along = _axial_coordinates(points, self.center, self.axis)
        ring = torch.stack([radial - self.major_radius, along], dim=1)
        return torch.linalg.norm(ring, dim=1) - self.minor_radius


class Capsule(SDF):
    """Capsule: all points within ``radius`` [m] of the segment from ``start`` to ``end``."""

    def __init__(self, start, end, radius: float):
        self.start = as_vector(start, "start")
        self.end = as_vector(end, "end")
        if torch.linalg.norm(self.end - self.start) < 1e-12:
            raise ValueError("capsule start and end must differ (use Sphere for a point)")
        self.radius = _positive(radius, "radius")

    def _evaluate(self, points):
        a, b = _param(self.start, points), _param(self.end, points)
        ab = b - a
        t = (((points - a) @ ab) / (ab @ ab)).clamp(0.0, 1.0)
        return torch.linalg.norm(points - a - t[:, None] * ab, dim=1) - self.radius
