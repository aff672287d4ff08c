"""Typed, validated configuration files (TOML + pydantic) with one-line errors."""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Annotated, TypeVar

import pydantic

from .errors import RfsdfError
from .limits import input_file

__all__ = ["Name", "StrictModel", "MAX_TOML_DEPTH", "read_toml", "merge_tables", "validate", "load_model",
           "preset_names", "resolve_preset"]

Model = TypeVar("Model", bound=pydantic.BaseModel)


_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


def _plain_name(text: str) -> str:
    if not _NAME.fullmatch(text) or ".." in text:
        raise ValueError(f"{text!r} is not a plain name (1-64 letters, digits, '_', '-', '.'; "
                         "it names output files, so no '/' or '..')")
    return text


Name = Annotated[str, pydantic.AfterValidator(_plain_name)]
"""A name that may become part of a file name: no path separators, no '..'."""


class StrictModel(pydantic.BaseModel):
    """Base of every config model: unknown keys are errors (they are usually typos), and no
    number may be NaN or infinite (no setting, size or position means anything there)."""

    model_config = pydantic.ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


MAX_TOML_DEPTH = 64
"""Deepest nesting of tables and arrays any rfsdf file may have (a scene's CSG tree is the
deepest real one, a few levels per operation): past it, recursive readers would overflow."""


def _nesting_depth(value) -> int:
    """Levels of tables and arrays in ``value`` (a scalar is 0), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        node, depth = stack.pop()
        children = node.values() if isinstance(node, dict) else node if isinstance(node, list) else None
        if children is not None:
            deepest = max(deepest, depth + 1)
            if depth + 1 > MAX_TOML_DEPTH:
                break
            stack.extend((child, depth + 1) for child in children)
    return deepest


def read_toml(path) -> dict:
    """Parse a TOML file; RfsdfError naming the file and line on failure, or when its tables
    and arrays nest deeper than ``MAX_TOML_DEPTH`` (which no rfsdf file needs)."""
    path = input_file(path)
    too_deep = f"{path}: invalid TOML: tables and arrays nest deeper than {MAX_TOML_DEPTH} levels"
    try:
        with path.open("rb") as fh:
            table = tomllib.load(fh)
    except UnicodeDecodeError:
        raise RfsdfError(f"{path}: not a text (UTF-8) TOML file") from None
    except tomllib.TOMLDecodeError as exc:
        raise RfsdfError(f"{path}: invalid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise RfsdfError(too_deep) from None
    if _nesting_depth(table) > MAX_TOML_DEPTH:
        raise RfsdfError(too_deep)
    return table


def merge_tables(base: dict, overrides: dict) -> dict:
    """Nested dict update (TOML tables): tables merge key by key, other values replace."""
    merged = dict(base)
    for key, value in overrides.items():
        nested = isinstance(value, dict) and isinstance(merged.get(key), dict)
        merged[key] = merge_tables(merged[key], value) if nested else value
    return merged


def _field_path(loc: tuple) -> str:
    parts = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        else:
            parts.append(("." if parts else "") + str(item))
    return "".join(parts)


def validate(model: type[Model], data: dict, source: str) -> Model:
    """Validate ``data`` against ``model``; the first problem becomes 'source: field: reason'."""
    try:
        return model.model_validate(data)
    except pydantic.ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        # Drop the tags pydantic adds for tagged unions (e.g. 'sphere') so paths read as the file does.
        loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and p.endswith("]")))
        message = err["msg"].removeprefix("Value error, ")
        raise RfsdfError(f"{source}: {_field_path(loc) or '(top level)'}: {message}") from None


def load_model(model: type[Model], path) -> Model:
    """Read and validate a TOML file in one step."""
    return validate(model, read_toml(path), str(path))


def preset_names(package: str) -> list[str]:
    """Names of the TOML presets shipped in ``package`` (e.g. 'rfsdf.presets.scenes')."""
    return sorted(p.name.removesuffix(".toml") for p in resources.files(package).iterdir() if p.name.endswith(".toml"))


def resolve_preset(name_or_path, package: str, kind: str) -> Path:
    """The file of a preset name in ``package``, or the given path; RfsdfError if neither exists."""
    text = str(name_or_path)
    if text in preset_names(package):
        return Path(str(resources.files(package) / f"{text}.toml"))
    if not Path(text).exists():
        raise RfsdfError(f"{text}: no such {kind} file or preset (presets: {', '.join(preset_names(package))})")
    return Path(text)
