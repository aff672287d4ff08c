"""A slow, obviously-right reference: the sensing matrix built row by row in NumPy.

Used by the tests (against the matrix-free operator) and by the operator benchmark.
"""

from __future__ import annotations

import numpy as np

from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["dense_row", "dense_matrix"]


def dense_row(acq: Acquisition, points: np.ndarray, v: int, i: int, j: int, k: int) -> np.ndarray:
    """Row m = (v, i, j, k) of A over ``points`` (Q, 3): (Q,) complex128, straight from the formula."""
    s, r = acq.tx_m[v, i].numpy(), acq.rx_m[v, j].numpy()
    d_tx = np.linalg.norm(points - s, axis=1)
    d_rx = np.linalg.norm(points - r, axis=1)
    gain = np.ones(len(points))
    if acq.pattern_exponent > 0:
        b = acq.boresight[v].numpy()
        gain = (np.clip((points - s) @ b / d_tx, 0, None) * np.clip((points - r) @ b / d_rx, 0, None)) ** acq.pattern_exponent
    spread = 1.0 / (d_tx * d_rx) if acq.spreading else 1.0
    f = float(acq.frequencies_hz[k])
    return gain * spread * np.exp(-2j * np.pi * f * (d_tx + d_rx) / SPEED_OF_LIGHT)


def dense_matrix(acq: Acquisition, points: np.ndarray) -> np.ndarray:
    """The whole A, (V*T*R*K, Q) complex128, rows in (v, i, j, k) C order."""
    v_n, t_n, r_n, k_n = acq.shape
    return np.stack([dense_row(acq, points, v, i, j, k)
                     for v in range(v_n) for i in range(t_n) for j in range(r_n) for k in range(k_n)])
