"""A mesh file's header checked against its size before a mesh library reads it: a PLY that
declares a billion vertices in a few bytes would otherwise allocate for all of them."""

from __future__ import annotations

from pathlib import Path

__all__ = ["check_mesh_file"]

_MAX_HEADER_BYTES = 65536
_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
          "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
_ASCII_BYTES = 2  # the least an ASCII number takes: one digit and a separator


def _ply_minimum_bytes(header: list[str], path: Path) -> tuple[int, str]:
    """(the least body size the header's elements need [bytes], a description of the largest)."""
    binary = any(line.startswith("format binary") for line in header)
    elements: list[list] = []  # [name, count, bytes per item]
    for line in header:
        words = line.split()
        if not words:
            continue
        if words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise ValueError(f"{path}: malformed PLY header line {line!r}")
            elements.append([words[1], int(words[2]), 0])
        elif words[0] == "property" and elements:
            if words[1] == "list":  # the count, and no items at the least
                size = _SIZES.get(words[2], 1) if binary else _ASCII_BYTES
            else:
                size = _SIZES.get(words[1], 1) if binary else _ASCII_BYTES
            elements[-1][2] += size
    need = sum(count * size for _, count, size in elements)
    largest = max(elements, key=lambda e: e[1] * e[2], default=["nothing", 0, 0])
    return need, f"{largest[1]:,} {largest[0]}s"


def check_mesh_file(path: Path) -> None:
    """ValueError naming ``path`` when a PLY's header is unreadable or declares more data than
    the file holds; other formats (OBJ, STL, ...) declare no counts and pass."""
    if path.suffix.lower() != ".ply":
        return
    with path.open("rb") as fh:
        head = fh.read(_MAX_HEADER_BYTES)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file (no 'ply' ... 'end_header' in its first {_MAX_HEADER_BYTES} bytes)")
    header = head[:end].decode("ascii", errors="replace").splitlines()
    need, largest = _ply_minimum_bytes(header, path)
    body = path.stat().st_size - end - len(b"end_header\n")
    if need > body:
        raise ValueError(f"{path}: declares {largest}, more than its {body:,} bytes after the header can hold")
