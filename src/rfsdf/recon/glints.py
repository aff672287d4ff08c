"""A range peak as a glint: where the sphere of its range about its view touches the surface.

A view's matched-filter image along one line of sight peaks at the range of the brightest
return within the array's main lobe about that line (about lambda / 2D, 0.9 degrees for the
demo's 12 cm array), and on a smooth surface that is the glint: the point that faces the
view. So a peak at range rho along the unit direction u from its view's centre c does not say
that the surface crosses the line at c + rho u; it says that the sphere of radius rho about c
touches the surface within a narrow cone about u, and meets no surface before. Read as points
on their lines, the demo's warm-start peaks stand 0.47 mm in front of the true surface
(median; a metal ball's 0.45 mm), every curved face pulled outward; read as this sphere's
nearest surface within 0.25 degrees of the line, 0.04 mm behind it (the ball 0.04 mm):
``benchmarks/peak_model.py``, docs/results/demo-quality.md.

:func:`glint_gap` is that contact for any signed distance f, differentiable through it: the
least f over the sphere's cap within the cone, sampled on rings of directions. It is 0 where
the cap touches the surface, positive by the gap where the surface stands behind it and
negative where the surface crosses the cap (stands in front). Rings cone / rings apart miss a
tangent contact by at most the sag of the two spheres across the samples' covering radius s
(about 0.75 rho cone / rings), s^2 / 2 (1 / R + 1 / rho): 0.005 mm for a 25 mm ball at 0.3 m,
cone 0.25 degrees, two rings. With no cone (or no range: a planar scan's parallel lines, which
have no apex) it is f at the peak itself, the line model.
"""

from __future__ import annotations

import math

import torch

__all__ = ["cap_directions", "glint_caps", "cap_minimum", "glint_gap"]


def cap_directions(cone_rad: float, rings: int) -> torch.Tensor:
    """(K, 2) float64 (polar angle [rad] from the axis, azimuth [rad]) of a cap's samples: the
    axis, then ring j = 1..``rings`` at j * cone / rings with 6 j directions, the first ring's
    from azimuth 0 and each even ring's turned by half its step; K = 1 + 3 rings (rings + 1)."""
    rows = [(0.0, 0.0)]
    for j in range(1, rings + 1 if cone_rad > 0 else 1):
        rows += [(j * cone_rad / rings, 2 * math.pi * (k + 0.5 * (1 - j % 2)) / (6 * j)) for k in range(6 * j)]
    return torch.tensor(rows, dtype=torch.float64)


def glint_caps(points: torch.Tensor, towards: torch.Tensor, ranges: torch.Tensor, cone_rad: float,
               rings: int = 2) -> torch.Tensor:
    """(N, K, 3) each peak's cap samples [m] (:func:`glint_gap`'s arguments), K of
    :func:`cap_directions`; the peak itself first."""
    directions = cap_directions(cone_rad, rings).to(points.device)
    polar, azimuth = directions[:, 0].to(points.dtype), directions[:, 1].to(points.dtype)
    axis = -towards
    x_axis, y_axis = torch.tensor([1.0, 0, 0]).to(axis), torch.tensor([0, 1.0, 0]).to(axis)
    helper = torch.where(axis[:, :1].abs() < 0.9, x_axis, y_axis)  # any vector not along the axis
    across = torch.nn.functional.normalize(torch.linalg.cross(axis, helper), dim=1)
    other = torch.linalg.cross(axis, across)
    # c + rho u' with c = p - rho axis and u' = cos(a) axis + sin(a) (cos(b) across + sin(b) other)
    lateral = torch.sin(polar)[None, :, None] * (torch.cos(azimuth)[None, :, None] * across[:, None]
                                                  + torch.sin(azimuth)[None, :, None] * other[:, None])
    step = (torch.cos(polar) - 1)[None, :, None] * axis[:, None] + lateral  # (N, K, 3)
    return points[:, None] + ranges[:, None, None] * step


def glint_gap(sdf, points: torch.Tensor, towards: torch.Tensor, ranges: torch.Tensor, cone_rad: float,
              rings: int = 2) -> torch.Tensor:
    """(N,) the least ``sdf`` [m] over each peak's cap: the sphere of radius ``ranges`` (N,) [m]
    about its view's centre (points (N, 3) [m] + ranges * towards, unit (N, 3) towards the view)
    within ``cone_rad`` [rad] of its line, sampled by :func:`cap_directions` (``rings``). In the
    points' dtype and device, differentiable through ``sdf``; a range of 0 gives f at the point.

    Examples
    --------
    A metal ball (radius 25 mm) 0.3 m from a view; a line of sight 1 degree off its centre, and a
    peak on it at the glint's range (|c| - R). Read on its line (no cone), the peak stands half a
    millimetre off the surface; a cone that reaches the glint's direction puts it on it:

    >>> from rfsdf.geometry import Sphere
    >>> a = math.radians(1.0)
    >>> centre = torch.tensor([[0.3, 0.0, 0.0]], dtype=torch.float64)
    >>> line = torch.tensor([[-math.cos(a), 0.0, math.sin(a)]], dtype=torch.float64)
    >>> rho = torch.tensor([0.275], dtype=torch.float64)
    >>> peak = centre + rho[:, None] * line
    >>> gap = lambda cone: float(glint_gap(Sphere(0.025), peak, -line, rho, math.radians(cone), rings=1))
    >>> round(gap(0.0) * 1e3, 3), abs(gap(1.0)) < 1e-9
    (0.498, True)
    """
    return cap_minimum(sdf, glint_caps(points, towards, ranges, cone_rad, rings))


def cap_minimum(sdf, caps: torch.Tensor) -> torch.Tensor:
    """(N,) the least ``sdf`` [m] over each row of ``caps`` (N, K, 3) [m] (:func:`glint_caps`)."""
    return sdf(caps.reshape(-1, 3)).reshape(caps.shape[:2]).min(1).values
