"""JSON that every parser reads: NaN and infinities become null (json.dumps writes bare NaN)."""

from __future__ import annotations

import json
import math

__all__ = ["to_json"]


def _finite(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def to_json(value, *, indent: int | None = 2) -> str:
    """Strict JSON text of ``value`` (dicts, lists, numbers, strings), non-finite floats as null."""
    return json.dumps(_finite(value), indent=indent, allow_nan=False)
