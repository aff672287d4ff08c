"""Regular voxel grids over an axis-aligned box (the layout of images and meshing)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

__all__ = ["Grid", "interpolated_sdf", "trilinear"]


@dataclass(frozen=True)
class Grid:
    """Voxel centres of a box split into ``shape`` cells.

    lower_m, upper_m : (3,) box corners [m]; shape : (nx, ny, nz). Voxel centres sit at
    lower + (i + 0.5) * voxel_m, so the grid covers the box exactly.
    """

    lower_m: tuple[float, float, float]
    upper_m: tuple[float, float, float]
    shape: tuple[int, int, int]

    def __post_init__(self):
        lo, hi = np.asarray(self.lower_m, float), np.asarray(self.upper_m, float)
        if lo.shape != (3,) or hi.shape != (3,) or not (hi > lo).all():
            raise ValueError(f"grid box needs lower < upper on every axis, got {self.lower_m}, {self.upper_m}")
        if len(self.shape) != 3 or min(self.shape) < 2:
            raise ValueError(f"grid shape needs 3 sizes >= 2, got {self.shape}")
        object.__setattr__(self, "lower_m", tuple(float(v) for v in lo))
        object.__setattr__(self, "upper_m", tuple(float(v) for v in hi))
        object.__setattr__(self, "shape", tuple(int(s) for s in self.shape))

    @classmethod
    def from_voxel(cls, lower_m, upper_m, voxel_m: float) -> Grid:
        """Grid over the box with cubic-ish voxels of about ``voxel_m`` [m]."""
        if not voxel_m > 0:
            raise ValueError(f"voxel size must be positive [m], got {voxel_m}")
        extent = np.asarray(upper_m, float) - np.asarray(lower_m, float)
        return cls(lower_m, upper_m, tuple(max(2, int(round(e / voxel_m))) for e in extent))

    @property
    def voxel_m(self) -> np.ndarray:
        """(3,) voxel edge lengths [m]."""
        return (np.asarray(self.upper_m) - np.asarray(self.lower_m)) / np.asarray(self.shape)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def axes(self) -> list[np.ndarray]:
        """Voxel-centre coordinates along x, y, z [m]."""
        return [lo + (np.arange(n) + 0.5) * v for lo, n, v in zip(self.lower_m, self.shape, self.voxel_m)]

    def points(self, *, dtype=torch.float32, device=None, start: int = 0, stop: int | None = None) -> torch.Tensor:
        """Voxel centres (M, 3) [m] in C order (x slowest), optionally the slice [start, stop)."""
        stop = self.size if stop is None else min(stop, self.size)
        flat = torch.arange(start, stop, device=device)
        ny, nz = self.shape[1], self.shape[2]
        idx = torch.stack([flat // (ny * nz), (flat // nz) % ny, flat % nz], dim=1)
        lower = torch.tensor(self.lower_m, dtype=torch.float64, device=device)
        voxel = torch.tensor(self.voxel_m, dtype=torch.float64, device=device)
        return (lower + (idx.double() + 0.5) * voxel).to(dtype)


def trilinear(values: torch.Tensor, grid: Grid):
    """Callable p (N, 3) [m] -> (N,) for voxel-centre ``values`` of shape grid.shape, or
    (N, C) for (C, *grid.shape), in the points' dtype: trilinear interpolation at p clamped
    into the box (values beyond the outer voxel centres are the outer ones'). One lookup
    serves all C channels."""
    lower = torch.tensor(grid.lower_m, dtype=values.dtype, device=values.device)
    upper = torch.tensor(grid.upper_m, dtype=values.dtype, device=values.device)
    channels = values.shape[:-3]
    volume = values.reshape(1, -1, *grid.shape)

    def lookup(points: torch.Tensor) -> torch.Tensor:
        inside = torch.minimum(torch.maximum(points.to(values.dtype), lower), upper)
        normalised = 2 * (inside - lower) / (upper - lower) - 1  # (x, y, z) in [-1, 1]
        # grid_sample indexes the last three dims as (z, y, x) = (W, H, D) order reversed.
        coords = normalised.flip(-1).reshape(1, -1, 1, 1, 3)
        value = torch.nn.functional.grid_sample(volume, coords, mode="bilinear", padding_mode="border",
                                                align_corners=False).reshape(volume.shape[1], -1)
        return (value.T if channels else value[0]).to(points.dtype)

    return lookup


def interpolated_sdf(values_m: torch.Tensor, grid: Grid):
    """Callable p (N, 3) [m] -> (N,) [m]: trilinear interpolation of voxel-centre SDF values
    (grid.shape) inside the box, plus the distance to the box outside it (a bound)."""
    lower = torch.tensor(grid.lower_m, dtype=values_m.dtype, device=values_m.device)
    upper = torch.tensor(grid.upper_m, dtype=values_m.dtype, device=values_m.device)
    inside_value = trilinear(values_m, grid)

    def sdf(points: torch.Tensor) -> torch.Tensor:
        p = points.to(values_m.dtype)
        outside = (p - torch.minimum(torch.maximum(p, lower), upper)).norm(dim=1)
        return (inside_value(p) + outside).to(points.dtype)

    return sdf
