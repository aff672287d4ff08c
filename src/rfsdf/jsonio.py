"""JSON that every parser reads: NaN and infinities become null (json.dumps writes bare NaN);
written atomically."""

from __future__ import annotations

import json
import math

from .atomic import atomic_path

__all__ = ["to_json", "write_json"]


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


def write_json(path, value) -> None:
    """Write :func:`to_json` of ``value`` to ``path``, atomically (a crash leaves no half file)."""
    with atomic_path(path) as tmp:
        tmp.write_text(to_json(value))
