"""Schedules over training: sigma of the surface kernel and the learning rate."""

from __future__ import annotations

__all__ = ["sigma_at", "exponential_decay"]


def exponential_decay(step: int, total: int, start: float, end: float) -> float:
    """start * (end / start)^(step / total): start at step 0, end at the last step."""
    fraction = min(max(step / max(total, 1), 0.0), 1.0)
    return start * (end / start) ** fraction


def sigma_at(step: int, total: int, start_m: float, end_m: float, schedule: str = "exponential") -> float:
    """Kernel width sigma [m] at ``step``: exponential coarse-to-fine decay, or constant ``end_m``."""
    if schedule == "constant":
        return end_m
    return exponential_decay(step, total, start_m, end_m)
