"""TI's DCA1000 capture board: the raw ``.bin`` of ADC samples, and the DCA1000 CLI's ``cf.json``.

The ``.bin`` is headerless little-endian int16, frames after one another, chirps within a
frame. What one chirp holds depends on the radar's LVDS lanes (TI's ``readDCA1000``
scripts and the DCA1000 user's guide):

- 4 lanes (xWR12xx, xWR14xx), one lane per Rx: time sample after time sample, each
  ``[I0 I1 I2 I3 Q0 Q1 Q2 Q3]`` when complex, ``[x0 x1 x2 x3]`` when real;
- 2 lanes (xWR16xx, xWR18xx, xWR68xx): each Rx's samples in turn (Rx0's, then Rx1's, ...),
  complex values in pairs stored ``[I(n) I(n+1) Q(n) Q(n+1)]``, real ones one int16 each.

A capture is held as an array (frames, chirps, rx, samples), complex64 or float32.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...atomic import atomic_path
from ...errors import RfsdfError
from ...jsonio import read_json

__all__ = ["AdcLayout", "read_bin", "write_bin", "read_cf_json", "write_cf_json"]

LANES = (2, 4)
_INT16 = np.dtype("<i2")


@dataclass(frozen=True)
class AdcLayout:
    """How the samples of one capture lie in the file: ``lanes`` (2 or 4), ``complex`` (I/Q or
    real samples), ``rx`` channels, ``samples`` per chirp, ``chirps`` per frame."""

    lanes: int
    complex: bool
    rx: int
    samples: int
    chirps: int

    def __post_init__(self):
        if self.lanes not in LANES:
            raise ValueError(f"lanes: {self.lanes} LVDS lanes; the DCA1000 formats have {' or '.join(map(str, LANES))}")
        if min(self.rx, self.samples, self.chirps) < 1:
            raise ValueError(f"rx, samples and chirps must be >= 1, got {self.rx}, {self.samples}, {self.chirps}")
        if self.lanes == 4 and self.rx != 4:
            raise ValueError(f"rx: the 4-lane format carries one Rx a lane, 4 Rx, got {self.rx}")
        if self.lanes == 2 and self.complex and (self.samples % 2):
            raise ValueError(f"samples: the 2-lane complex format stores samples in pairs, got {self.samples}")

    @property
    def frame_values(self) -> int:
        """int16 values in one frame."""
        return self.chirps * self.rx * self.samples * (2 if self.complex else 1)

    def _decode(self, values: np.ndarray) -> np.ndarray:
        """int16 values (F, frame_values) -> (F, chirps, rx, samples)."""
        f = len(values)
        if self.lanes == 4:  # (F, chirp, sample, [I lanes, Q lanes] or [lanes])
            v = values.reshape(f, self.chirps, self.samples, -1, self.rx).astype(np.float32)
            cube = v[:, :, :, 0] + 1j * v[:, :, :, 1] if self.complex else v[:, :, :, 0]
            return np.ascontiguousarray(cube.transpose(0, 1, 3, 2))
        if not self.complex:
            return values.reshape(f, self.chirps, self.rx, self.samples).astype(np.float32)
        v = values.reshape(f, self.chirps, self.rx, self.samples // 2, 2, 2).astype(np.float32)  # [I Q] x [n n+1]
        return (v[..., 0, :] + 1j * v[..., 1, :]).reshape(f, self.chirps, self.rx, self.samples)

    def _encode(self, cube: np.ndarray) -> np.ndarray:
        """(F, chirps, rx, samples) -> int16 values (F, frame_values); the inverse of ``_decode``."""
        f = len(cube)
        parts = (cube.real, cube.imag) if self.complex else (cube.real,)
        if self.lanes == 4:
            v = np.stack([p.transpose(0, 1, 3, 2) for p in parts], 3)  # (F, chirp, sample, part, rx)
        elif not self.complex:
            v = cube.real
        else:
            v = np.stack([p.reshape(f, self.chirps, self.rx, self.samples // 2, 2) for p in parts], 4)
        return _to_int16(v).reshape(f, -1)


def _to_int16(values: np.ndarray) -> np.ndarray:
    rounded = np.rint(values)
    if rounded.min(initial=0) < -32768 or rounded.max(initial=0) > 32767:
        raise ValueError("samples exceed the int16 range: scale the capture before writing it")
    return rounded.astype(_INT16)


def read_bin(paths, layout: AdcLayout) -> np.ndarray:
    """The ADC samples of a DCA1000 ``.bin`` (frames, chirps, rx, samples), complex64 or float32.
    ``paths``: one file, or the files the DCA1000 split one record into, in order."""
    paths = [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]
    try:
        size = sum(path.stat().st_size for path in paths)
    except OSError as exc:
        raise RfsdfError(f"{exc.filename}: cannot read ({exc.strerror or exc})") from None
    frame_bytes = layout.frame_values * _INT16.itemsize
    if size == 0 or size % frame_bytes:
        raise RfsdfError(f"{', '.join(map(str, paths))}: size {size} bytes is not a whole number of frames of "
                         f"{frame_bytes} bytes ({layout.chirps} chirps x {layout.rx} Rx x {layout.samples} samples, "
                         f"{'complex' if layout.complex else 'real'}, {layout.lanes} lanes, from the config)")
    values = np.concatenate([np.fromfile(path, dtype=_INT16) for path in paths])
    return layout._decode(values.reshape(size // frame_bytes, layout.frame_values))


def write_bin(path, cube: np.ndarray, layout: AdcLayout) -> Path:
    """Write ``cube`` (frames, chirps, rx, samples) in ``layout`` (values rounded to int16)."""
    expected = (layout.chirps, layout.rx, layout.samples)
    if cube.ndim != 4 or cube.shape[1:] != expected:
        raise ValueError(f"cube must be (frames, {', '.join(map(str, expected))}), got {cube.shape}")
    if np.iscomplexobj(cube) != layout.complex:
        raise ValueError(f"a {'complex' if layout.complex else 'real'} layout needs a "
                         f"{'complex' if layout.complex else 'real'} cube")
    with atomic_path(path) as tmp:
        layout._encode(cube).tofile(tmp)
    return Path(path)


# The DCA1000 CLI's configuration: lvdsMode 1 is 4 lanes, 2 is 2 lanes; dataFormatMode 3 is 16-bit
_LVDS_MODES = {1: 4, 2: 2}
_SIXTEEN_BITS = 3


def read_cf_json(path) -> int:
    """The number of LVDS lanes in a DCA1000 CLI ``cf.json`` (which must capture 16-bit samples)."""
    path = Path(path)
    document = read_json(path)
    try:
        config = document["DCA1000Config"]
        mode, bits = config["lvdsMode"], config["dataFormatMode"]
    except (KeyError, TypeError) as exc:
        raise RfsdfError(f"{path}: DCA1000Config.{exc.args[0] if exc.args else ''}: missing") from None
    if mode not in _LVDS_MODES:
        raise RfsdfError(f"{path}: DCA1000Config.lvdsMode: {mode!r}, expected 1 (4 lanes) or 2 (2 lanes)")
    if bits != _SIXTEEN_BITS:
        raise RfsdfError(f"{path}: DCA1000Config.dataFormatMode: {bits!r}; only 16-bit captures (3) are read")
    return _LVDS_MODES[mode]


def write_cf_json(path, lanes: int) -> Path:
    """A minimal DCA1000 CLI ``cf.json`` for a raw 16-bit capture over ``lanes`` LVDS lanes."""
    mode = {v: k for k, v in _LVDS_MODES.items()}[lanes]
    config = {"DCA1000Config": {"dataLoggingMode": "raw", "dataTransferMode": "LVDSCapture",
                                "dataCaptureMode": "ethernetStream", "lvdsMode": mode,
                                "dataFormatMode": _SIXTEEN_BITS, "packetDelay_us": 25}}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(config, indent=2))
    return Path(path)
