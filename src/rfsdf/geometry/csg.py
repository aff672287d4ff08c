"""Constructive solid geometry on SDFs: union, intersection, complement, difference, smooth blends.

Exactness: complement is exact when its operand is; union and intersection are exact
on the zero level set (and outside/inside respectively) but only a bound in general;
smooth blends are bounds.
"""

from __future__ import annotations

import torch

from .base import SDF

__all__ = [
    "union", "intersection", "complement", "difference", "smooth_union", "smooth_intersection",
    "Union", "Intersection", "Complement", "SmoothUnion", "SmoothIntersection",
]


class _Combine(SDF):
    exact = False

    def __init__(self, *shapes: SDF):
        if len(shapes) < 2:
            raise ValueError(f"{type(self).__name__} needs at least two shapes, got {len(shapes)}")
        for s in shapes:
            if not isinstance(s, SDF):
                raise TypeError(f"CSG operands must be SDFs, got {type(s).__name__}")
        self.shapes = shapes

    def _stack(self, points):
        return torch.stack([s(points) for s in self.shapes], dim=0)


class Union(_Combine):
    """min of the operands' distances."""

    def _evaluate(self, points):
        return self._stack(points).min(dim=0).values


class Intersection(_Combine):
    """max of the operands' distances."""

    def _evaluate(self, points):
        return self._stack(points).max(dim=0).values


class Complement(SDF):
    """Inside and outside swapped: -f. Exact when ``shape`` is."""

    def __init__(self, shape: SDF):
        self.shape = shape
        self.exact = shape.exact

    def _evaluate(self, points):
        return -self.shape(points)


def _check_blend(blend_m: float) -> float:
    blend_m = float(blend_m)
    if not blend_m > 0:
        raise ValueError(f"blend radius must be positive [m], got {blend_m}")
    return blend_m


class SmoothUnion(_Combine):
    """Polynomial smooth minimum with blend radius ``blend_m`` [m] (a bound)."""

    def __init__(self, *shapes: SDF, blend_m: float):
        super().__init__(*shapes)
        self.blend_m = _check_blend(blend_m)

    def _evaluate(self, points):
        d = self.shapes[0](points)
        for s in self.shapes[1:]:
            d = _smooth_min(d, s(points), self.blend_m)
        return d


class SmoothIntersection(SmoothUnion):
    """Polynomial smooth maximum with blend radius ``blend_m`` [m] (a bound)."""

    def _evaluate(self, points):
        d = self.shapes[0](points)
        for s in self.shapes[1:]:
            d = -_smooth_min(-d, -s(points), self.blend_m)
        return d


def _smooth_min(a: torch.Tensor, b: torch.Tensor, k: float) -> torch.Tensor:
    h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0)
    return b + (a - b) * h - k * h * (1.0 - h)


def union(*shapes: SDF) -> SDF:
    """Union of two or more shapes (``a | b``)."""
    return Union(*shapes)


def intersection(*shapes: SDF) -> SDF:
    """Intersection of two or more shapes (``a & b``)."""
    return Intersection(*shapes)


def complement(shape: SDF) -> SDF:
    """Everything outside ``shape`` (``~a``)."""
    return Complement(shape)


def difference(shape: SDF, *cutters: SDF) -> SDF:
    """``shape`` with every cutter removed (``a - b``) = a & ~b."""
    return Intersection(shape, *(Complement(c) for c in cutters))


def smooth_union(*shapes: SDF, blend_m: float) -> SDF:
    """Union with a fillet of radius about ``blend_m`` [m] where the shapes meet."""
    return SmoothUnion(*shapes, blend_m=blend_m)


def smooth_intersection(*shapes: SDF, blend_m: float) -> SDF:
    """Intersection with rounded seams of about ``blend_m`` [m]."""
    return SmoothIntersection(*shapes, blend_m=blend_m)
