"""Schedules over training, registered by name in ``SCHEDULES``: each maps (step, total,
start, end) to the value at ``step`` (the learning rate, as a factor of its start)."""

from __future__ import annotations

from ..registry import Registry

__all__ = ["SCHEDULES", "exponential_decay", "constant"]

SCHEDULES: Registry = Registry("schedule")


@SCHEDULES.register("exponential")
def exponential_decay(step: int, total: int, start: float, end: float) -> float:
    """start * (end / start)^(step / total): start at step 0, end at the last step."""
    fraction = min(max(step / max(total, 1), 0.0), 1.0)
    return start * (end / start) ** fraction


@SCHEDULES.register("constant")
def constant(step: int, total: int, start: float, end: float) -> float:
    """start at every step (``end`` is ignored)."""
    return start
