"""Pictures of an SDF on axis-aligned planes: through the middle of a box, or through the
centre of each object of a scene (an object off the box's centre planes never shows there)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from .figures import plt, save_figure

__all__ = ["plot_sdf_slices", "plot_object_slices"]

_AXES = ("x", "y", "z")
_PLANES = (2, 1, 0)  # normal axes of the xy, xz and yz planes, in that order


def _slice_values(sdf, lower, upper, normal_axis: int, at: float, resolution: int):
    """SDF values (resolution, resolution) [m] on the plane {x[normal_axis] = at} inside the box."""
    u_axis, v_axis = [a for a in range(3) if a != normal_axis]
    u = np.linspace(lower[u_axis], upper[u_axis], resolution)
    v = np.linspace(lower[v_axis], upper[v_axis], resolution)
    uu, vv = np.meshgrid(u, v, indexing="xy")
    pts = np.zeros((uu.size, 3))
    pts[:, u_axis], pts[:, v_axis] = uu.ravel(), vv.ravel()
    pts[:, normal_axis] = at
    with torch.no_grad():
        values = sdf(torch.as_tensor(pts, dtype=torch.float32)).float().cpu().numpy()
    return values.reshape(uu.shape), (u[0], u[-1], v[0], v[-1]), (u_axis, v_axis)


def _draw_slice(ax, sdf, reference, lower, upper, normal_axis: int, at: float, resolution: int, title: str):
    """One panel: colour = SDF [mm] (blue inside, red outside), black = its zero set, dashed
    lime = the reference's zero set; returns the image for a colour bar."""
    values, extent, (ua, va) = _slice_values(sdf, lower, upper, normal_axis, at, resolution)
    limit = max(float(np.abs(values).max()) * 1e3, 1e-6)
    im = ax.imshow(values * 1e3, origin="lower", extent=extent, cmap="RdBu_r", vmin=-limit, vmax=limit)
    ax.contour(values, levels=[0.0], colors="k", linewidths=1.2, extent=extent, origin="lower")
    if reference is not None:
        ref, _, _ = _slice_values(reference, lower, upper, normal_axis, at, resolution)
        ax.contour(ref, levels=[0.0], colors="lime", linewidths=1.0, linestyles="--", extent=extent, origin="lower")
    ax.set_title(f"{title}{_AXES[normal_axis]} = {round(at * 1e3)} mm")  # round(): no "-0 mm"
    ax.set_xlabel(f"{_AXES[ua]} [m]")
    ax.set_ylabel(f"{_AXES[va]} [m]")
    return im


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
    for ax, normal_axis in zip(axes, _PLANES):
        middle = 0.5 * (lower[normal_axis] + upper[normal_axis])
        im = _draw_slice(ax, sdf, reference, lower, upper, normal_axis, middle, resolution, "")
        fig.colorbar(im, ax=ax, shrink=0.8, label="SDF [mm]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_object_slices(
    sdf: Callable[[torch.Tensor], torch.Tensor], reference: Callable[[torch.Tensor], torch.Tensor],
    names: Sequence[str], lower_m: np.ndarray, upper_m: np.ndarray, path, *, margin_m: float = 0.02,
    resolution: int = 120, title: str = "",
) -> Path:
    """Save a PNG with one row per object: ``sdf`` on the xy, xz and yz planes through the
    centre of the object's box, over that box grown by ``margin_m`` [m].

    names : (K,) object names; lower_m, upper_m : (K, 3) each object's box [m]. Colours and
    lines as in :func:`plot_sdf_slices`, the reference's zero set dashed.
    """
    lower_m, upper_m = np.atleast_2d(lower_m) - margin_m, np.atleast_2d(upper_m) + margin_m
    fig, axes = plt.subplots(len(names), 3, figsize=(13, 3.9 * len(names)), layout="constrained", squeeze=False)
    for row, (name, lower, upper) in enumerate(zip(names, lower_m, upper_m)):
        centre = 0.5 * (lower + upper)
        for ax, normal_axis in zip(axes[row], _PLANES):
            im = _draw_slice(ax, sdf, reference, lower, upper, normal_axis, centre[normal_axis], resolution, f"{name}: ")
            fig.colorbar(im, ax=ax, shrink=0.8, label="SDF [mm]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi=80)  # a row per object: a tall figure, kept under 1 MB
