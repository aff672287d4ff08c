"""The SDF interface: a callable ``f(points) -> (N,)`` with CSG operators and transforms.

Sign convention: f < 0 inside, f > 0 outside, outward normal = grad f.
"""

from __future__ import annotations

import torch

__all__ = ["SDF", "as_points", "as_vector"]


def as_points(points: torch.Tensor) -> torch.Tensor:
    """Check that ``points`` is an (N, 3) floating tensor and return it.

    Raises
    ------
    ValueError
        If the shape is not (N, 3) or the dtype is not floating point.
    """
    if not isinstance(points, torch.Tensor):
        raise TypeError(f"points must be a torch.Tensor, got {type(points).__name__}")
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {tuple(points.shape)}")
    if not points.is_floating_point():
        raise ValueError(f"points must be floating point, got {points.dtype}")
    return points


def as_vector(value, name: str, *, length: int = 3) -> torch.Tensor:
    """A float64 tensor of shape (length,) from a sequence; clear error otherwise."""
    vec = torch.as_tensor(value, dtype=torch.float64).flatten()
    if vec.numel() != length:
        raise ValueError(f"{name} must have {length} components, got {vec.numel()}")
    if not torch.isfinite(vec).all():
        raise ValueError(f"{name} must be finite, got {vec.tolist()}")
    return vec


class SDF:
    """Base class of every signed distance function.

    Subclasses implement :meth:`_evaluate` on an (N, 3) tensor and set ``exact``:
    True when ``|f|`` is the true Euclidean distance to the surface everywhere, False
    when ``f`` is only a bound (right sign and zero set, ``|f|`` at most the distance).
    Parameters are stored as float64 tensors and cast to the points' dtype/device.
    """

    exact: bool = True

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        """Evaluate at ``points`` : (N, 3) float tensor [m]; returns (N,) [m], differentiable."""
        return self._evaluate(as_points(points))

    def _evaluate(self, points: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    def bounding_sphere(self) -> tuple[torch.Tensor, float] | None:
        """Centre (3,) float64 [m] and radius [m] of a sphere holding the whole surface, given
        by shapes that are costly to evaluate (meshes) so that callers can skip them far
        away: f(p) >= |p - centre| - radius everywhere. None: not provided."""
        return None

    # CSG operators -----------------------------------------------------------------
    def __or__(self, other: SDF) -> SDF:
        from .csg import union

        return union(self, other)

    def __and__(self, other: SDF) -> SDF:
        from .csg import intersection

        return intersection(self, other)

    def __invert__(self) -> SDF:
        from .csg import complement

        return complement(self)

    def __sub__(self, other: SDF) -> SDF:
        from .csg import difference

        return difference(self, other)

    # Transforms --------------------------------------------------------------------
    def translate(self, offset_m) -> SDF:
        """This shape moved by ``offset_m`` : (3,) [m]."""
        from .transforms import Translate

        return Translate(self, offset_m)

    def rotate(self, axis, angle_rad: float) -> SDF:
        """This shape rotated about ``axis`` (through the origin) by ``angle_rad`` [rad]."""
        from .transforms import Rotate

        return Rotate(self, axis, angle_rad)

    def scale(self, factor: float) -> SDF:
        """This shape scaled uniformly about the origin; distances scale with it."""
        from .transforms import Scale

        return Scale(self, factor)


def _param(value, points: torch.Tensor) -> torch.Tensor:
    """A stored float64 parameter cast to the dtype/device of ``points``."""
    return value.to(dtype=points.dtype, device=points.device)
