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

import torch

from .acquisition import Acquisition
from .scattering import lit_mask

__all__ = ["observed_mask", "DEFAULT_TOLERANCE_RAD"]

DEFAULT_TOLERANCE_RAD = math.radians(10.0)


def observed_mask(points: torch.Tensor, normals: torch.Tensor, acquisition: Acquisition, occluder, *,
                  tolerance_rad: float = DEFAULT_TOLERANCE_RAD) -> torch.Tensor:
    """(N,) bool: samples (N, 3) [m] with unit normals (N, 3) that some view observes.

    occluder : the scene SDF for shadows. The cone of a view is bounded by the largest
    angle between the direction to any element and the direction to the array centre (a
    bisector of two such directions deviates no more than that).
    """
    p, n = points.double(), normals.double()
    observed = torch.zeros(len(p), dtype=torch.bool)
    for v in range(acquisition.shape[0]):
        tx_centre, rx_centre = acquisition.tx_m[v].mean(0), acquisition.rx_m[v].mean(0)
        lit = lit_mask(p, n, tx_centre, rx_centre, occluder=occluder)
        to_centre = torch.nn.functional.normalize(0.5 * (tx_centre + rx_centre) - p, dim=1)  # (N, 3)
        elements = torch.cat([acquisition.tx_m[v], acquisition.rx_m[v]])  # (E, 3)
        to_elements = torch.nn.functional.normalize(elements[None] - p[:, None], dim=2)  # (N, E, 3)
        cone = torch.arccos((to_elements * to_centre[:, None]).sum(2).clamp(-1, 1)).max(dim=1).values
        tilt = torch.arccos((n * to_centre).sum(1).clamp(-1, 1))
        observed |= lit & (tilt <= cone + tolerance_rad)
    return observed
