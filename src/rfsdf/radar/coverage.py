"""Which parts of a scene's surface the radar can see at all: the observed-surface mask.

A smooth surface returns energy to a view coherently only near specular: where its normal
lies inside the view's bistatic cone, the set of bisectors of the directions to a Tx and an
Rx of the array. A surface sample counts as observed when at least one view lights it
without shadow and has its normal within that cone widened by ``tolerance_rad``. The
default tolerance, 10 degrees, is about the specular beamwidth lambda / (2 L) of a patch
of the size L of a cross-range resolution cell (3.8 mm / (2 x 12 mm) = 0.16 rad at 79 GHz
and 0.75 m on the default radar): a patch tilted by less still sends its glint into the
array. What no view observes cannot be recovered by any method from these data.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from scipy.spatial import ConvexHull

from .acquisition import Acquisition
from .scattering import lit_mask

__all__ = ["observed_mask", "DEFAULT_TOLERANCE_RAD"]

DEFAULT_TOLERANCE_RAD = math.radians(10.0)
_HULL_FROM = 64  # elements; a view with fewer measures its cone on all of them


def _hull_corners(elements: torch.Tensor) -> torch.Tensor:
    """The elements (E, 3) [m] that are corners of their convex hull (all of them when fewer
    than ``_HULL_FROM``, or on a line).

    A view's cone at a sample is the largest angle between the direction to an element and
    the direction to the centre. Where that angle is below 90 degrees, the elements within
    any angle form a convex cone, so the largest is found at a corner of the hull: a scan's
    5,445 elements (1,089 frames, 1 Tx and 4 Rx each) have four. (Above 90 degrees a sample
    faces away from the centre, and its facing test fails whatever the cone.)"""
    if len(elements) < _HULL_FROM:
        return elements
    points = elements.double().cpu().numpy()
    centred = points - points.mean(0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    rank = int((spread > 1e-9 * spread[0]).sum())
    if rank < 2:
        return elements
    corners = ConvexHull(points if rank == 3 else centred @ axes[:2].T).vertices
    return elements[torch.as_tensor(np.sort(corners))]


def observed_mask(points: torch.Tensor, normals: torch.Tensor, acquisition: Acquisition, occluder, *,
                  tolerance_rad: float = DEFAULT_TOLERANCE_RAD) -> torch.Tensor:
    """(N,) bool: samples (N, 3) [m] with unit normals (N, 3) that some view observes.

    occluder : the scene SDF for shadows. The cone of a view is bounded by the largest
    angle between the direction to any element and the direction to the array centre (a
    bisector of two such directions deviates no more than that). That angle is computed
    only where the tilt is within the cone's bound asin(r / d) (r: the farthest element
    from the centre, d: the sample's distance to it), on the corners of the elements' hull,
    and shadow rays are traced only for the samples inside a view's cone and not yet
    observed: the same mask as computing and tracing all of them (each ray is traced alone),
    at a fraction of the cost.
    """
    p, n = points.double(), normals.double()
    observed = torch.zeros(len(p), dtype=torch.bool)
    for v in range(acquisition.num_views):
        tx, rx = acquisition.view_elements(v)  # a frame's, or all of a scan's
        tx_centre, rx_centre = tx.mean(0), rx.mean(0)
        centre, elements = 0.5 * (tx_centre + rx_centre), _hull_corners(torch.cat([tx, rx]))
        towards = centre - p  # (N, 3)
        distance = towards.norm(dim=1)  # (N,)
        tilt = torch.arccos((towards * n).sum(1).div(distance).clamp(-1, 1))
        reach = float((elements - centre).norm(dim=1).max())
        bound = torch.where(distance > reach, torch.asin((reach / distance).clamp(max=1.0)), math.pi)
        near = (~observed & (tilt <= bound + tolerance_rad)).nonzero().squeeze(1)
        to_centre = towards[near] / distance[near, None]  # (M, 3)
        to_elements = torch.nn.functional.normalize(elements[None] - p[near, None], dim=2)  # (M, E, 3)
        cone = torch.arccos((to_elements * to_centre[:, None]).sum(2).clamp(-1, 1)).max(dim=1).values
        candidates = near[tilt[near] <= cone + tolerance_rad]
        if len(candidates):
            observed[candidates] = lit_mask(p[candidates], n[candidates], tx_centre, rx_centre, occluder=occluder)
    return observed
