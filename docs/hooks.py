"""MkDocs hooks: the file-format reference, generated from the pydantic models that read the
files, and the provenance of every measured result (the commit that last wrote it).

A page line ``<!-- format: module.path:ModelName -->`` becomes one table per model (the model
and every model it nests): key, type, default, allowed values, and what it means (the
field's ``description``, else the comment written beside or above the field in the source).
So a field added to a model is in the reference at the next build, and the test suite checks
that every field is (``tests/test_docs.py``).

A page line ``<!-- provenance -->`` becomes a table of every file under ``PROVENANCE``: the
commit that last changed it, its date and its message, from ``git log``.
"""

from __future__ import annotations

import importlib
import inspect
import re
import subprocess
import types
import typing
from pathlib import Path

import pydantic

MARKER = re.compile(r"^<!-- format: ([\w.]+):(\w+) -->$", re.MULTILINE)
PROVENANCE_MARKER = "<!-- provenance -->"
PROVENANCE = ("benchmarks/results/*.json", "docs/figures/*.png", "docs/studies/*.png")
ROOT = Path(__file__).resolve().parents[1]
_CONSTRAINTS = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"), ("min_length", "length >="),
                ("max_length", "length <="))


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 (the hook's signature)
    markdown = MARKER.sub(lambda match: format_tables(match.group(1), match.group(2)), markdown)
    return markdown.replace(PROVENANCE_MARKER, provenance_table()) if PROVENANCE_MARKER in markdown else markdown


def provenance_table() -> str:
    """Markdown table: each result file, and the commit (hash, date, message) that last changed it."""
    rows = ["| file | commit | date | what the commit says |", "|---|---|---|---|"]
    for pattern in PROVENANCE:
        for path in sorted(ROOT.glob(pattern)):
            name = path.relative_to(ROOT).as_posix()
            log = subprocess.run(["git", "log", "-1", "--format=%h%x09%ad%x09%s", "--date=short", "--", name],
                                 cwd=ROOT, capture_output=True, text=True).stdout.strip()
            commit, date, subject = log.split("\t", 2) if log.count("\t") >= 2 else ("not committed", "", "")
            rows.append(f"| `{name}` | `{commit}` | {date} | {_cell(_shorten(subject, 160))} |")
    return "\n".join(rows)


def _shorten(text: str, length: int) -> str:
    return text if len(text) <= length else text[:length - 3].rsplit(" ", 1)[0] + " ..."


def format_tables(module: str, name: str) -> str:
    """Markdown tables for ``module.name`` and every pydantic model its fields nest, depth first."""
    root = getattr(importlib.import_module(module), name)
    seen: list[type[pydantic.BaseModel]] = []
    _collect(root, seen)
    return "\n\n".join(_table(model) for model in seen)


def _collect(model: type[pydantic.BaseModel], seen: list) -> None:
    if model in seen:
        return
    seen.append(model)
    for field in model.model_fields.values():
        for nested in _models_in(field.annotation):
            _collect(nested, seen)


def _models_in(annotation) -> list[type[pydantic.BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, pydantic.BaseModel):
        return [annotation]
    return [model for arg in getattr(annotation, "__args__", ()) for model in _models_in(arg)]


def _table(model: type[pydantic.BaseModel]) -> str:
    comments = _source_comments(model)
    doc = _first_line(model.__doc__)
    rows = [f"### `{model.__name__}`", "", *([doc, ""] if doc else []),
            "| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    for key, field in model.model_fields.items():
        default = "required" if field.is_required() else f"`{_short(field.get_default(call_default_factory=True))}`"
        meaning = field.description or comments.get(key, "")
        rows.append(f"| `{key}` | {_type_name(field.annotation)} | {default} | {_allowed(field)} | "
                    f"{_cell(meaning)} |")
    return "\n".join(rows)


def _source_comments(model) -> dict[str, str]:
    """Each field's comment in the class body: the ``#`` lines just above it and the one beside it."""
    try:
        lines = inspect.getsource(model).splitlines()
    except (OSError, TypeError):
        return {}
    comments, above = {}, []
    for line in lines[1:]:
        stripped = line.strip()
        if stripped.startswith("#"):
            above.append(stripped.lstrip("# "))
            continue
        match = re.match(r"(\w+)\s*:[^#]*?(?:#\s*(.*))?$", stripped)
        if match and not stripped.startswith(("def ", "@", "return")):
            comments[match.group(1)] = " ".join(above + ([match.group(2)] if match.group(2) else []))
        above = []
    return comments


def _type_name(annotation) -> str:
    return "`" + _describe(annotation).replace("|", "or") + "`"


def _describe(annotation) -> str:
    """A type as a person reads it: ``float > 0``, ``3 x float``, ``list of str``, ``'mf' or 'clean'``."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if annotation is type(None):
        return "none"
    if origin is typing.Annotated:
        return " ".join([_describe(args[0]), *_constraints(args[1:])])
    if origin is typing.Literal:
        return " or ".join(repr(arg) for arg in args)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(arg) for arg in args)
    if origin is tuple and args and Ellipsis not in args:
        names = [_describe(arg) for arg in args]
        return f"{len(names)} x {names[0]}" if len(set(names)) == 1 else "(" + ", ".join(names) + ")"
    if origin in (list, tuple):
        return "list of " + _describe(args[0]) if args else "list"
    if origin is dict:
        return f"table of {_describe(args[1])}" if args else "table"
    return getattr(annotation, "__name__", str(annotation))


def _allowed(field) -> str:
    return ", ".join(_constraints(field.metadata))


def _constraints(metadata) -> list[str]:
    return [f"{symbol} {getattr(item, attribute)}" for item in metadata for attribute, symbol in _CONSTRAINTS
            if getattr(item, attribute, None) is not None]


def _short(value) -> str:
    if isinstance(value, pydantic.BaseModel):
        return "{…}"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _first_line(doc: str | None) -> str:
    return (doc or "").strip().split("\n\n")[0].replace("\n", " ")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")
