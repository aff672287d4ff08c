"""Antenna array layouts in the radar frame: the array lies in the x-y plane, boresight +z.

Each generator returns (tx, rx) as (T, 3) and (R, 3) float64 arrays [m] centred on the origin.
"""

from __future__ import annotations

import numpy as np

__all__ = ["uniform_linear", "uniform_planar", "boundary", "ti_3tx4rx", "synthetic_aperture"]


def _line(count: int, spacing_m: float, axis: int = 0) -> np.ndarray:
    pts = np.zeros((count, 3))
    pts[:, axis] = (np.arange(count) - (count - 1) / 2) * spacing_m
    return pts


def _check(count: int, spacing_m: float):
    if count < 1 or not spacing_m > 0:
        raise ValueError(f"need >= 1 element and positive spacing, got {count} and {spacing_m} m")


def uniform_linear(tx_count: int, rx_count: int, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Co-located Tx and Rx lines along x with the same spacing."""
    _check(tx_count, spacing_m), _check(rx_count, spacing_m)
    return _line(tx_count, spacing_m), _line(rx_count, spacing_m)


def uniform_planar(nx: int, ny: int, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """An nx x ny grid used both to transmit and receive (monostatic-style full array)."""
    _check(nx * ny, spacing_m)
    x, y = _line(nx, spacing_m)[:, 0], _line(ny, spacing_m)[:, 0]
    grid = np.stack(np.meshgrid(x, y, indexing="ij"), -1).reshape(-1, 2)
    pts = np.column_stack([grid, np.zeros(len(grid))])
    return pts, pts.copy()


def boundary(size_m: float, elements_per_edge: int) -> tuple[np.ndarray, np.ndarray]:
    """Sparse multistatic square: Tx along the two x-edges, Rx along the two y-edges.

    The virtual array (midpoints of Tx-Rx pairs) is a filled size x size grid with half
    the element spacing: 4n physical elements give 4n^2 virtual ones.
    """
    _check(elements_per_edge, size_m)
    n, half = elements_per_edge, size_m / 2
    along = (np.arange(n) - (n - 1) / 2) * (size_m / max(n - 1, 1))
    tx = np.concatenate([np.column_stack([along, np.full(n, y), np.zeros(n)]) for y in (-half, half)])
    rx = np.concatenate([np.column_stack([np.full(n, x), along, np.zeros(n)]) for x in (-half, half)])
    return tx, rx


def ti_3tx4rx(wavelength_m: float) -> tuple[np.ndarray, np.ndarray]:
    """TI-style cascade-free MIMO: 4 Rx at lambda/2, 3 Tx at 2 lambda (one raised lambda/2 in y).

    Gives a 12-element virtual line (8 distinct in azimuth) plus elevation diversity.
    """
    rx = _line(4, wavelength_m / 2)
    tx = _line(3, 2 * wavelength_m)
    tx[1, 1] = wavelength_m / 2
    return tx, rx


def synthetic_aperture(tx: np.ndarray, rx: np.ndarray, offsets_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scan an array over ``offsets_m`` (S, 3) [m]: the union of the shifted arrays.

    Every shifted Tx is paired with every shifted Rx here, which suits a synthetic
    aperture whose positions are captured coherently; use views for separate captures.
    """
    offsets_m = np.asarray(offsets_m, float).reshape(-1, 3)
    return ((tx[None] + offsets_m[:, None]).reshape(-1, 3), (rx[None] + offsets_m[:, None]).reshape(-1, 3))
