"""Training curves of a reconstruction run: the loss terms, and the surface sample count."""

from __future__ import annotations

from pathlib import Path

from .figures import plt, save_figure

__all__ = ["plot_training_curves"]


def plot_training_curves(log, path, *, title: str = "") -> Path:
    """Save the data misfit and Eikonal loss (log scale) and the number of surface samples
    against the step. ``log`` : one mapping per step with keys step, data, eikonal, samples
    (a fit's StepRecords as dicts, or the rows of its log.csv)."""
    steps = [r["step"] for r in log]
    fig, (loss_ax, sample_ax) = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
    loss_ax.semilogy(steps, [r["data"] for r in log], label="data (relative misfit)")
    loss_ax.semilogy(steps, [r["eikonal"] for r in log], label="Eikonal")
    loss_ax.set_xlabel("step")
    loss_ax.set_ylabel("loss [1]")
    loss_ax.legend()
    sample_ax.plot(steps, [r["samples"] for r in log], color="k")
    sample_ax.set_xlabel("step")
    sample_ax.set_ylabel("surface samples [count]")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)
