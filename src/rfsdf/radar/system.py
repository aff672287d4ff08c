"""A radar system: arrays, frequencies, views, antenna pattern, spreading, noise; TOML files.

A radar file (or preset ``near-77g``, ``room-60g``, ``sar-77g``; see ``examples/radars``)
has a ``[waveform]`` (ofdm or fmcw), an ``[array]`` (boundary, uniform_linear, uniform_planar,
ti_3tx4rx, a TI board; optionally scanned over a raster as a synthetic aperture), ``[views]``
(turntable rings) and ``[antenna]`` / ``[noise]`` options.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import torch
from pydantic import Field, PositiveFloat, model_validator

from ..config import Name, StrictModel, preset_names, read_toml, resolve_preset, validate
from ..errors import RfsdfError
from ..limits import require_memory
from . import arrays, waveform
from .acquisition import SPEED_OF_LIGHT, Acquisition, swept_bandwidth_hz
from .boards import BOARDS, board_layout
from .views import turntable_views

__all__ = ["Radar", "RadarSpec", "load_radar", "radar_presets"]

MAX_FREQUENCIES = 1 << 16  # per sweep
MAX_ELEMENTS = 4096  # per edge, line, row or ring: beyond any real array, and it bounds the layout's memory
ScanSteps = Annotated[int, Field(ge=1, le=1024)]
_BYTES_PER_SAMPLE = 8  # complex64


class WaveformSpec(StrictModel):
    kind: Literal["ofdm", "fmcw"]  # ofdm: carrier_hz, bandwidth_hz, subcarriers; fmcw: the other four
    carrier_hz: PositiveFloat | None = None
    bandwidth_hz: PositiveFloat | None = None
    subcarriers: int | None = Field(None, ge=1, le=MAX_FREQUENCIES)  # K frequencies, B / K apart
    start_hz: PositiveFloat | None = None
    slope_hz_per_s: PositiveFloat | None = None
    sample_rate_hz: PositiveFloat | None = None
    samples: int | None = Field(None, ge=1, le=MAX_FREQUENCIES)  # ADC samples: start_hz + slope n / rate

    @model_validator(mode="after")
    def _complete(self):
        need = ("carrier_hz", "bandwidth_hz", "subcarriers") if self.kind == "ofdm" else \
            ("start_hz", "slope_hz_per_s", "sample_rate_hz", "samples")
        missing = [n for n in need if getattr(self, n) is None]
        if missing:
            raise ValueError(f"{self.kind} waveform needs {', '.join(missing)}")
        return self

    def frequencies(self) -> np.ndarray:
        if self.kind == "ofdm":
            return waveform.ofdm_frequencies(self.carrier_hz, self.bandwidth_hz, self.subcarriers)
        return waveform.fmcw_frequencies(self.start_hz, self.slope_hz_per_s, self.sample_rate_hz, self.samples)


class ArraySpec(StrictModel):
    kind: Literal["boundary", "uniform_linear", "uniform_planar", "ti_3tx4rx", "board"]
    size_m: PositiveFloat | None = None  # boundary
    elements_per_edge: int | None = Field(None, ge=1, le=MAX_ELEMENTS)  # boundary
    tx_count: int | None = Field(None, ge=1, le=MAX_ELEMENTS)  # uniform_linear
    rx_count: int | None = Field(None, ge=1, le=MAX_ELEMENTS)  # uniform_linear
    nx: int | None = Field(None, ge=1, le=MAX_ELEMENTS)  # uniform_planar
    ny: int | None = Field(None, ge=1, le=MAX_ELEMENTS)  # uniform_planar
    spacing_m: PositiveFloat | None = None  # uniform_linear, uniform_planar
    board: str | None = None  # board: a TI board of rfsdf.radar.boards (iwr1443, awr1843, iwr6843)
    tx_mask: int = Field(1, ge=1)  # board: its Tx enabled (bit k: Tx k), as mmWave Studio's txChannelEn
    scan_steps: tuple[ScanSteps, ScanSteps] = (1, 1)  # synthetic aperture grid (x, y)
    scan_step_m: PositiveFloat | None = None  # the synthetic aperture's step
    # "mimo": the union of the moved arrays, every Tx paired with every Rx (one coherent
    # snapshot); "frames": each position a frame of its own Tx and Rx (a board on an arm or a
    # rail), the frames of one pose a scan, imaged as one view
    scan_capture: Literal["mimo", "frames"] = "mimo"

    @model_validator(mode="after")
    def _complete(self):
        need = {"boundary": ("size_m", "elements_per_edge"), "uniform_linear": ("tx_count", "rx_count", "spacing_m"),
                "uniform_planar": ("nx", "ny", "spacing_m"), "ti_3tx4rx": (), "board": ("board",)}[self.kind]
        if self.scan_steps != (1, 1):
            need = (*need, "scan_step_m")
        missing = [n for n in need if getattr(self, n) is None]
        if missing:
            raise ValueError(f"{self.kind} array needs {', '.join(missing)}")
        if self.kind == "board":
            if self.board not in BOARDS:
                raise ValueError(f"unknown board {self.board!r}; known: {', '.join(BOARDS)}")
            if self.tx_mask >> len(BOARDS[self.board].tx_uw_m):
                raise ValueError(f"tx_mask {hex(self.tx_mask)} enables Tx the {self.board} lacks")
        return self

    @property
    def positions_per_view(self) -> int:
        """Raster positions a view is scanned over (1: not scanned)."""
        return self.scan_steps[0] * self.scan_steps[1]

    def element_counts(self) -> tuple[int, int]:
        """(T, R) of a frame without laying the array out (to size it first)."""
        tx, rx = {"boundary": lambda: (2 * self.elements_per_edge,) * 2,
                  "uniform_linear": lambda: (self.tx_count, self.rx_count),
                  "uniform_planar": lambda: (self.nx * self.ny,) * 2, "ti_3tx4rx": lambda: (3, 4),
                  "board": lambda: (self.tx_mask.bit_count(), len(BOARDS[self.board].rx_uw_m))}[self.kind]()
        scans = self.positions_per_view if self.scan_capture == "mimo" else 1
        return tx * scans, rx * scans

    def scan_offsets(self) -> np.ndarray:
        """(S, 3) [m] the raster's positions in the radar frame (x fastest along the array's x)."""
        sx, sy = self.scan_steps
        gx, gy = np.meshgrid((np.arange(sx) - (sx - 1) / 2) * (self.scan_step_m or 0.0),
                             (np.arange(sy) - (sy - 1) / 2) * (self.scan_step_m or 0.0), indexing="ij")
        return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])

    def elements(self, wavelength_m: float) -> tuple[np.ndarray, np.ndarray]:
        if self.kind == "boundary":
            tx, rx = arrays.boundary(self.size_m, self.elements_per_edge)
        elif self.kind == "uniform_linear":
            tx, rx = arrays.uniform_linear(self.tx_count, self.rx_count, self.spacing_m)
        elif self.kind == "uniform_planar":
            tx, rx = arrays.uniform_planar(self.nx, self.ny, self.spacing_m)
        elif self.kind == "ti_3tx4rx":
            tx, rx = arrays.ti_3tx4rx(wavelength_m)
        else:
            tx, rx = board_layout(self.board, self.tx_mask)
        if self.scan_steps != (1, 1) and self.scan_capture == "mimo":
            tx, rx = arrays.synthetic_aperture(tx, rx, self.scan_offsets())
        return tx, rx


class ViewsSpec(StrictModel):
    kind: Literal["turntable"] = "turntable"
    distance_m: PositiveFloat  # from target_m to each view's array centre
    # ring e: azimuths_per_ring[e] views evenly spaced at elevations_rad[e] (alternate rings
    # offset by half a step)
    azimuths_per_ring: list[Annotated[int, Field(ge=1, le=MAX_ELEMENTS)]] = Field(min_length=1)
    elevations_rad: list[float] = Field(min_length=1)
    target_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the point every view looks at

    @model_validator(mode="after")
    def _rings(self):
        if len(self.azimuths_per_ring) != len(self.elevations_rad):
            raise ValueError("azimuths_per_ring and elevations_rad must have the same length")
        return self


class AntennaSpec(StrictModel):
    pattern_exponent: float = Field(default=0.0, ge=0.0)  # cos^n of the angle off boresight; 0: isotropic
    spreading: bool = True  # 1/d amplitude on each path


class NoiseSpec(StrictModel):
    snr_db: float | None = 30.0  # mean signal power over the noise's; none: noise-free


class RadarSpec(StrictModel):
    name: Name
    waveform: WaveformSpec
    array: ArraySpec
    views: ViewsSpec
    antenna: AntennaSpec = AntennaSpec()
    noise: NoiseSpec = NoiseSpec()


@dataclass(frozen=True)
class Radar:
    """A radar system, ready to place: element positions in its own frame and its poses.

    tx_m (T, 3), rx_m (R, 3) [m] in the radar frame (array in x-y, boresight +z);
    rotations (V, 3, 3) radar -> scene; positions_m (V, 3) [m] of each frame; frequencies_hz
    (K,) [Hz]; scans (V,) the view each frame belongs to, or None (each frame a view).
    """

    name: str
    tx_m: np.ndarray
    rx_m: np.ndarray
    frequencies_hz: np.ndarray
    rotations: np.ndarray
    positions_m: np.ndarray
    pattern_exponent: float = 0.0
    spreading: bool = True
    snr_db: float | None = 30.0
    scans: np.ndarray | None = None

    @classmethod
    def from_spec(cls, spec: RadarSpec) -> Radar:
        freqs, v, array = spec.waveform.frequencies(), spec.views, spec.array
        views, (txs, rxs) = sum(v.azimuths_per_ring), array.element_counts()
        frames = views * (array.positions_per_view if array.scan_capture == "frames" else 1)
        require_memory(_BYTES_PER_SAMPLE * frames * txs * rxs * len(freqs),
                       f"the measurements ({frames} frames x {txs} Tx x {rxs} Rx x {len(freqs)} frequencies)")
        # Arrays are laid out at the shortest wavelength so spacings hold across the band.
        tx, rx = array.elements(SPEED_OF_LIGHT / float(np.max(freqs)))
        rotations, positions = turntable_views(v.distance_m, v.azimuths_per_ring, v.elevations_rad, v.target_m)
        scans = None
        if array.scan_capture == "frames" and array.scan_steps != (1, 1):
            # each pose scans its raster: frame (view, position) at the pose moved by the offset
            offsets = array.scan_offsets()
            positions = (positions[:, None] + np.einsum("vab,sb->vsa", rotations, offsets)).reshape(-1, 3)
            rotations = np.repeat(rotations, len(offsets), axis=0)
            scans = np.repeat(np.arange(views), len(offsets))
        return cls(spec.name, tx, rx, freqs, rotations, positions, spec.antenna.pattern_exponent,
                   spec.antenna.spreading, spec.noise.snr_db, scans)

    def acquisition(self) -> Acquisition:
        """Elements placed by every pose, in the scene frame."""
        rot = torch.as_tensor(self.rotations)
        pos = torch.as_tensor(self.positions_m)
        place = lambda e: torch.einsum("vab,eb->vea", rot, torch.as_tensor(e)) + pos[:, None]  # noqa: E731
        return Acquisition(place(self.tx_m), place(self.rx_m), torch.as_tensor(self.frequencies_hz),
                           rot[:, :, 2], self.pattern_exponent, self.spreading,
                           None if self.scans is None else torch.as_tensor(self.scans))

    @property
    def num_views(self) -> int:
        """Views imaged coherently: the scans, or the frames."""
        return len(self.rotations) if self.scans is None else int(self.scans.max()) + 1

    @property
    def aperture_m(self) -> float:
        """Largest extent of a view's virtual (Tx-Rx midpoint) array [m]: a scan's frames'
        positions in the radar frame, widened by the board's own virtual array."""
        virtual = 0.5 * (self.tx_m[:, None] + self.rx_m[None]).reshape(-1, 3)
        extent = np.ptp(virtual[:, :2], axis=0)
        if self.scans is not None:
            frames = self.scans == 0
            local = np.einsum("ba,vb->va", self.rotations[0], self.positions_m[frames] - self.positions_m[frames][0])
            extent = extent + np.ptp(local[:, :2], axis=0)
        return float(extent.max())

    def summary(self) -> str:
        f = self.frequencies_hz
        return (f"radar {self.name!r}: {len(self.tx_m)} Tx x {len(self.rx_m)} Rx, {len(f)} frequencies "
                f"{f.min() / 1e9:.2f}-{f.max() / 1e9:.2f} GHz, {self.num_views} views, "
                f"virtual aperture {self.aperture_m * 100:.1f} cm, range resolution "
                f"{waveform.range_resolution_m(swept_bandwidth_hz(f)) * 100:.2f} cm"
                + ("" if self.scans is None else f", each view a scan of {len(self.rotations) // self.num_views} frames"))


def radar_presets() -> list[str]:
    """Names of the built-in radars."""
    return preset_names("rfsdf.presets.radars")


def load_radar(name_or_path) -> Radar:
    """A radar from a preset name or a TOML file; RfsdfError 'file: field: reason' on bad input."""
    path = resolve_preset(name_or_path, "rfsdf.presets.radars", "radar")
    spec = validate(RadarSpec, read_toml(path), str(path))
    try:
        return Radar.from_spec(spec)
    except ValueError as exc:
        raise RfsdfError(f"{path}: {exc}") from None
