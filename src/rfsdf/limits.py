"""Inputs checked before use: sizes before allocating, files before reading; one clear error
instead of a MemoryError, a hang or a long wait.

Commands estimate the memory of their largest arrays from their inputs (measurement
counts, voxels, mesh resolution, the shapes a file declares) and call ``require_memory``
before making them.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import RfsdfError

__all__ = ["available_memory_bytes", "require_memory", "input_file"]

GIB = 2**30


def available_memory_bytes() -> int:
    """Memory the process may still take [bytes]: MemAvailable on Linux, else physical memory."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def require_memory(nbytes: float, what: str) -> None:
    """RfsdfError naming ``what`` (e.g. 'radar: the measurements (12 views x ...)') when
    ``nbytes`` exceeds the memory available."""
    available = available_memory_bytes()
    if not nbytes <= available:
        raise RfsdfError(f"{what} need about {nbytes / GIB:.3g} GiB, more than the "
                         f"{available / GIB:.3g} GiB of memory available")


def input_file(path) -> Path:
    """``path`` as a Path when it is a regular file; else one RfsdfError, at once (a FIFO would
    block and ``/dev/zero`` never end)."""
    path = Path(path)
    if not path.exists():
        raise RfsdfError(f"{path}: file not found")
    if path.is_dir():
        raise RfsdfError(f"{path}: is a folder, not a file")
    if not stat.S_ISREG(path.stat().st_mode):
        raise RfsdfError(f"{path}: not a regular file (a FIFO, socket or device)")
    return path
