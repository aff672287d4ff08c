"""Training curves of a reconstruction run: loss terms, and the annealed sigma."""

from __future__ import annotations

from pathlib import Path

from .figures import plt, save_figure

__all__ = ["plot_training_curves"]


def plot_training_curves(log: list[dict], path, *, title: str = "") -> Path:
    """Save the data and Eikonal losses (log scale) and sigma [mm] against the step.

    ``log`` : rows with keys step, data, eikonal, sigma_mm (a run's log.csv, as dicts).
    """
    steps = [float(row["step"]) for row in log]
    fig, (loss_ax, sigma_ax) = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
    for key in ("data", "eikonal"):
        loss_ax.semilogy(steps, [float(row[key]) for row in log], label=key)
    loss_ax.set_xlabel("step")
    loss_ax.set_ylabel("loss")
    loss_ax.legend()
    sigma_ax.plot(steps, [float(row["sigma_mm"]) for row in log], color="k")
    sigma_ax.set_xlabel("step")
    sigma_ax.set_ylabel("sigma [mm]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)
