"""Pose files: where the radar's Tx0 was at each frame of a scan, as CSV with a header.

Either one row a frame, ``x_m,y_m,z_m`` (rows beyond the capture's frames are not used),
or timestamped rows ``time_s,x_m,y_m,z_m`` (a robot arm's log), interpolated linearly at
the frames' times ``frame * frame_period_s`` (counted from the first row's time).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ...atomic import atomic_path
from ...errors import RfsdfError

__all__ = ["read_poses", "write_poses"]

POSITION = ("x_m", "y_m", "z_m")


def read_poses(path, frames: int, frame_period_s: float | None = None) -> np.ndarray:
    """(frames, 3) [m] Tx0 positions from the pose file ``path``; one error line naming the file,
    and the row or column, where it cannot give them."""
    path = Path(path)
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise RfsdfError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    if not rows:
        raise RfsdfError(f"{path}: empty; expected a header {','.join(POSITION)} or time_s,{','.join(POSITION)}")
    header = [name.strip() for name in rows[0]]
    timed = "time_s" in header
    columns = (("time_s",) if timed else ()) + POSITION
    missing = [name for name in columns if name not in header]
    if missing:
        raise RfsdfError(f"{path}: header: no column {', '.join(missing)} (has {', '.join(header)})")
    index = [header.index(name) for name in columns]
    values = np.empty((len(rows) - 1, len(columns)))
    for line, row in enumerate(rows[1:], start=2):
        try:
            values[line - 2] = [float(row[i]) for i in index]
        except (IndexError, ValueError):
            raise RfsdfError(f"{path}: row {line}: expected numbers in {', '.join(columns)}, got {row}") from None
        if not np.isfinite(values[line - 2]).all():
            raise RfsdfError(f"{path}: row {line}: NaN or Inf in {', '.join(columns)}")
    if not timed:
        if len(values) < frames:
            raise RfsdfError(f"{path}: {len(values)} poses for {frames} frames: the pose file is shorter than the capture")
        return values[:frames]
    if frame_period_s is None or frame_period_s <= 0:
        raise RfsdfError(f"{path}: timestamped poses need the frame period (rlFrameCfg_t.framePeriodicity_msec)")
    times, positions = values[:, 0], values[:, 1:]
    if len(times) < 2 or np.any(np.diff(times) <= 0):
        raise RfsdfError(f"{path}: time_s: needs two or more rows with increasing times")
    frame_times = times[0] + np.arange(frames) * frame_period_s
    if frame_times[-1] > times[-1] + 1e-9:
        raise RfsdfError(f"{path}: time_s: the poses end at {times[-1] - times[0]:.6g} s, the {frames} frames at "
                         f"{frame_times[-1] - times[0]:.6g} s: the pose file is shorter than the capture")
    return np.stack([np.interp(frame_times, times, positions[:, k]) for k in range(3)], 1)


def write_poses(path, positions_m: np.ndarray, times_s: np.ndarray | None = None) -> Path:
    """Write positions (M, 3) [m] as a pose file, with ``times_s`` (M,) as its time_s column if given."""
    header = (("time_s",) if times_s is not None else ()) + POSITION
    rows = positions_m if times_s is None else np.column_stack([times_s, positions_m])
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows([repr(float(v)) for v in row] for row in rows)
    return Path(path)
