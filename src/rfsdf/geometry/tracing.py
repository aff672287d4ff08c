"""Sphere tracing: march each ray by the SDF value until it reaches the surface.

For an exact SDF (or a bound) the step t_{k+1} = t_k + f(o + t_k d) never crosses the
surface, so the first hit along the ray is found.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .base import as_points
from .differential import SDFCallable, normals as sdf_normals

__all__ = ["TraceResult", "sphere_trace"]


@dataclass(frozen=True)
class TraceResult:
    """Per-ray outcome of :func:`sphere_trace` (N rays).

    t : (N,) distance along the unit direction [m] (last iterate for misses)
    hit : (N,) bool, |f| < eps reached within ``t_max`` and ``max_steps``
    started_inside : (N,) bool, f(origin) < 0 (such rays are not marched and never hit)
    steps : (N,) int, steps taken until the ray stopped
    points : (N, 3) o + t d [m]
    normals : (N, 3) outward unit normals at hits, zero elsewhere
    history : (S, N) iterates t_k when requested, else None
    """

    t: torch.Tensor
    hit: torch.Tensor
    started_inside: torch.Tensor
    steps: torch.Tensor
    points: torch.Tensor
    normals: torch.Tensor
    history: torch.Tensor | None = None


def sphere_trace(
    sdf: SDFCallable,
    origins: torch.Tensor,
    directions: torch.Tensor,
    *,
    eps: float = 1e-5,
    max_steps: int = 128,
    t_max: float | torch.Tensor = 10.0,
    record_history: bool = False,
) -> TraceResult:
    """Trace rays o + t d, d normalised, against ``sdf``; vectorised over rays.

    Parameters
    ----------
    origins, directions : (N, 3) float tensors [m], scene frame.
    eps : hit tolerance on |f| [m]. max_steps : iteration cap.
    t_max : miss distance [m]: a number, or (N,) one per ray (a shadow ray ends at its target).

    Examples
    --------
    A ray from 1 m aimed at the centre of a 0.2 m sphere lands at t = 0.8 m in one step:

    >>> from rfsdf.geometry import Sphere
    >>> result = sphere_trace(Sphere(0.2), torch.tensor([[1.0, 0, 0]]), torch.tensor([[-1.0, 0, 0]]))
    >>> round(float(result.t[0]), 6), bool(result.hit[0]), int(result.steps[0])
    (0.8, True, 1)
    """
    origins, directions = as_points(origins), as_points(directions)
    if origins.shape != directions.shape:
        raise ValueError(f"origins {tuple(origins.shape)} and directions {tuple(directions.shape)} differ")
    d = torch.nn.functional.normalize(directions, dim=1)
    per_ray_limit = isinstance(t_max, torch.Tensor)
    with torch.no_grad():
        n = origins.shape[0]
        t = torch.zeros(n, dtype=origins.dtype, device=origins.device)
        f = sdf(origins)
        inside = f < 0
        active = ~inside & (f >= eps)
        hit = ~inside & (f < eps)
        steps = torch.zeros(n, dtype=torch.long, device=origins.device)
        history = [t.clone()] if record_history else None
        for _ in range(max_steps):
            if not active.any():
                break
            idx = active.nonzero().squeeze(1)
            t[idx] = t[idx] + f[idx]
            steps[idx] += 1
            f_idx = sdf(origins[idx] + t[idx, None] * d[idx])
            f[idx] = f_idx
            newly_hit = f_idx.abs() < eps
            escaped = t[idx] > (t_max[idx] if per_ray_limit else t_max)
            hit[idx[newly_hit & ~escaped]] = True
            active[idx[newly_hit | escaped]] = False
            if history is not None:
                history.append(t.clone())
        points = origins + t[:, None] * d
    normal = torch.zeros_like(points)
    if hit.any():
        normal[hit] = sdf_normals(sdf, points[hit])
    return TraceResult(
        t=t, hit=hit, started_inside=inside, steps=steps, points=points, normals=normal,
        history=torch.stack(history) if history is not None else None,
    )
