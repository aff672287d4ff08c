"""Which way a surface faces, from which views see it: normals from per-view image power.

A surface element returns most to a view whose bisector (the unit vector halfway between
the directions to its Tx and Rx phase centres) lies along the element's normal: that is the
specular direction, and the lobe falls off away from it. So at a voxel where several views
see something, the power-weighted mean of their bisectors,

    m(x) = sum_v P_v(x) b_v(x) / sum_v P_v(x),

points along the surface normal there, and its length |m| <= 1 says how much the views
agree. Thresholded images throw this away: their boundaries have the shape of the blur
(the PSF), not of the surface; on the default demo the warm start's normals on the seen
faces were 42 degrees off (median), this estimate's 8 (docs/results/demo-quality.md, "Normals from the views").
"""

from __future__ import annotations

import numpy as np

__all__ = ["specular_normals"]


def specular_normals(per_view_power: np.ndarray, tx_centres_m: np.ndarray, rx_centres_m: np.ndarray,
                     grid) -> np.ndarray:
    """(3, nx, ny, nz) float32 power-weighted mean bisector m(x) at the voxel centres of ``grid``
    (unit length where every view that sees x agrees, 0 where none does).

    per_view_power : (V, nx, ny, nz) per-view image power; tx_centres_m, rx_centres_m : (V, 3)
    [m] the views' phase centres.
    """
    power = np.maximum(np.asarray(per_view_power, float), 0).reshape(len(per_view_power), -1)  # (V, N)
    points = grid.points().double().numpy()  # (N, 3)
    total = np.zeros_like(points)
    for weight, tx, rx in zip(power, np.asarray(tx_centres_m, float), np.asarray(rx_centres_m, float)):
        bisector = _unit(_unit(tx - points) + _unit(rx - points))
        total += weight[:, None] * bisector
    mean = total / np.maximum(power.sum(0), np.finfo(float).tiny)[:, None]
    return mean.T.reshape(3, *grid.shape).astype(np.float32)


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.maximum(np.linalg.norm(vectors, axis=1, keepdims=True), np.finfo(float).tiny)
