"""JSON that every parser reads: NaN and infinities become null (json.dumps writes bare NaN);
written atomically; read with one error line naming the file."""

from __future__ import annotations

import json
import math

from .atomic import atomic_path
from .errors import RfsdfError

__all__ = ["to_json", "write_json", "read_json"]


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


def read_json(path):
    """The JSON document in ``path``; a file that cannot be read or is not JSON is one
    :class:`RfsdfError` naming it."""
    try:
        return json.loads(path.read_text())
    except OSError as exc:
        raise RfsdfError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RfsdfError(f"{path}: not JSON ({exc})") from None
