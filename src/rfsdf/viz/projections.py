"""Maximum-intensity projections of a 3-D power image along x, y and z."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import plt, save_figure

__all__ = ["plot_mip"]


def plot_mip(power: np.ndarray, lower_m, upper_m, path, *, title: str = "", dynamic_range_db: float = 30.0,
             quantity: str = "MF power") -> Path:
    """Save MIPs of ``power`` (nx, ny, nz) [linear] in dB relative to its maximum; the colour
    bar reads ``quantity`` [dB]."""
    power = np.asarray(power, float)
    db = 10 * np.log10(np.maximum(power / power.max(), 10 ** (-dynamic_range_db / 10)))
    lo, hi = np.asarray(lower_m), np.asarray(upper_m)
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4), layout="constrained")
    for ax, (axis, (u, v)) in zip(axes, [(2, (0, 1)), (1, (0, 2)), (0, (1, 2))]):
        mip = db.max(axis=axis)
        im = ax.imshow(mip.T, origin="lower", extent=(lo[u], hi[u], lo[v], hi[v]), cmap="inferno",
                       vmin=-dynamic_range_db, vmax=0)
        ax.set_title(f"MIP along {'xyz'[axis]}")
        ax.set_xlabel(f"{'xyz'[u]} [m]")
        ax.set_ylabel(f"{'xyz'[v]} [m]")
        fig.colorbar(im, ax=ax, shrink=0.8, label=f"{quantity} [dB re max]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)
