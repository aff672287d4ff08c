"""Pictures of an SDF on the three axis-aligned planes through the middle of a box."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch

from .figures import plt, save_figure

__all__ = ["plot_sdf_slices"]

_AXES = ("x", "y", "z")


def _slice_values(sdf, lower, upper, normal_axis: int, resolution: int):
    u_axis, v_axis = [a for a in range(3) if a != normal_axis]
    u = np.linspace(lower[u_axis], upper[u_axis], resolution)
    v = np.linspace(lower[v_axis], upper[v_axis], resolution)
    uu, vv = np.meshgrid(u, v, indexing="xy")
    pts = np.zeros((uu.size, 3))
    pts[:, u_axis], pts[:, v_axis] = uu.ravel(), vv.ravel()
    pts[:, normal_axis] = 0.5 * (lower[normal_axis] + upper[normal_axis])
    with torch.no_grad():
        values = sdf(torch.as_tensor(pts, dtype=torch.float32)).float().cpu().numpy()
    return values.reshape(uu.shape), (u[0], u[-1], v[0], v[-1]), (u_axis, v_axis)


def plot_sdf_slices(
    sdf: Callable[[torch.Tensor], torch.Tensor], lower_m, upper_m, path, *,
    reference: Callable[[torch.Tensor], torch.Tensor] | None = None, resolution: int = 160, title: str = "",
) -> Path:
    """Save a PNG of ``sdf`` on the xy, xz and yz mid-planes of the box [m].

    Colour is the signed distance [mm] (blue inside, red outside), the black line its
    zero level set; with ``reference`` (e.g. the ground truth) its zero set is drawn dashed.
    """
    lower, upper = np.asarray(lower_m, float), np.asarray(upper_m, float)
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4), layout="constrained")
    for ax, normal_axis in zip(axes, (2, 1, 0)):
        values, extent, (ua, va) = _slice_values(sdf, lower, upper, normal_axis, resolution)
        limit = max(float(np.abs(values).max()) * 1e3, 1e-6)
        im = ax.imshow(values * 1e3, origin="lower", extent=extent, cmap="RdBu_r", vmin=-limit, vmax=limit)
        ax.contour(values, levels=[0.0], colors="k", linewidths=1.2, extent=extent, origin="lower")
        if reference is not None:
            ref, _, _ = _slice_values(reference, lower, upper, normal_axis, resolution)
            ax.contour(ref, levels=[0.0], colors="lime", linewidths=1.0, linestyles="--", extent=extent, origin="lower")
        middle = 0.5 * (lower[normal_axis] + upper[normal_axis])
        ax.set_title(f"{_AXES[normal_axis]} = {middle * 1e3:.0f} mm")
        ax.set_xlabel(f"{_AXES[ua]} [m]")
        ax.set_ylabel(f"{_AXES[va]} [m]")
        fig.colorbar(im, ax=ax, shrink=0.8, label="SDF [mm]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)
