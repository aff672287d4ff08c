"""Poses of the radar relative to the scene: rotation R (radar frame -> scene) and position t."""

from __future__ import annotations

import numpy as np

__all__ = ["look_at", "turntable_views"]


def look_at(position_m, target_m=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(3, 3) rotation whose columns are the radar's x, y, z (boresight) axes in the scene frame,
    with the boresight pointing from ``position_m`` to ``target_m``."""
    z = np.asarray(target_m, float) - np.asarray(position_m, float)
    with np.errstate(over="ignore"):
        length = np.linalg.norm(z)
    if not np.isfinite(length):
        raise ValueError("radar position and target are not a finite distance apart")
    if length < 1e-12:
        raise ValueError("radar position and target coincide")
    z /= length
    up = np.asarray(up, float)
    if abs(z @ up) > 0.999:  # looking straight up or down: any horizontal x axis will do
        up = np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def turntable_views(distance_m: float, azimuths_per_ring, elevations_rad, target_m=(0.0, 0.0, 0.0)):
    """Poses on rings around ``target_m``: ring e has ``azimuths_per_ring[e]`` evenly spaced
    azimuths (alternate rings offset by half a step) at elevation ``elevations_rad[e]``.

    Returns (rotations (V, 3, 3), positions (V, 3) [m]).
    """
    if not distance_m > 0:
        raise ValueError(f"distance_m must be positive, got {distance_m}")
    if len(azimuths_per_ring) != len(elevations_rad):
        raise ValueError("azimuths_per_ring and elevations_rad must have the same length")
    rotations, positions = [], []
    for ring, (count, elevation) in enumerate(zip(azimuths_per_ring, elevations_rad)):
        for a in range(int(count)):
            azimuth = 2 * np.pi * (a + 0.5 * (ring % 2)) / count
            direction = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
            position = np.asarray(target_m, float) + distance_m * direction
            rotations.append(look_at(position, target_m))
            positions.append(position)
    return np.stack(rotations), np.stack(positions)
