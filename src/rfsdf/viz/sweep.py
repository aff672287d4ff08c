"""The summary figure of a sweep: each job's Chamfer-L1 by method."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import plt, save_figure

__all__ = ["plot_sweep_summary"]

_METHODS = (("neural", "GeRaF"), ("neural_warm_start", "warm start"), ("clean_detection", "CLEAN detection"),
            ("clean_threshold", "CLEAN threshold"), ("mf_threshold", "MF threshold"))


def plot_sweep_summary(rows: list[dict], path, *, title: str = "sweep: Chamfer-L1 by job and method") -> Path:
    """Grouped bars, one group per job (failed jobs marked), one bar per method [mm]."""
    jobs = [row["job"] for row in rows]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(jobs) + 2), 4.2), layout="constrained")
    width = 0.8 / len(_METHODS)
    x = np.arange(len(jobs))
    for m, (key, label) in enumerate(_METHODS):
        values = [row.get(f"{key}.full.chamfer_l1_mm") for row in rows]
        heights = [np.nan if v is None else v for v in values]
        ax.bar(x + (m - (len(_METHODS) - 1) / 2) * width, heights, width, label=label)
    for i, row in enumerate(rows):
        if row["status"] == "failed":
            ax.text(i, 0, "failed", ha="center", va="bottom", rotation=90, color="crimson")
    ax.set_xticks(x, jobs, rotation=30, ha="right")
    ax.set_ylabel("Chamfer-L1 [mm]")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title(title)
    return save_figure(fig, path)
