"""A radar's gain from a separate capture of a known target (a metal sphere or plate).

A real radar's data carry an unknown gain (antennas, receiver chain, cables), so a fit with a
material head learns only the ratios of its surfaces' |Gamma| unless the gain is known. A
radar engineer measures it once, on a target whose return is known, and keeps it for the
captures that follow with the same radar and settings. rfsdf does the same: the capture y of
a reference scene (the target where it stood, with its material) is compared with the
simulator's noise-free data y_s of that scene through the capture's own acquisition, and

    g = |<y_s, y>| / <y_s, y_s>

is the gain from the simulator's (and the renderer's) amplitudes to the radar's. A capture
is the physics itself, so y_s is the simulator's converged sum: samples lambda/12 apart
(``REFERENCE_SAMPLES_PER_WAVELENGTH``; a 2 cm metal ball captured with gain 3.7 reads 3.65
against lambda/6 samples and 3.68 against lambda/12, while two lambda/3 samplings, the
simulator's default, read 3.16: their quadrature errors do not correlate). The
least-squares gain is complex; its phase (cable delay, the target's placement to a fraction
of a wavelength) is not the gain's, so only |g| is kept. ``explained`` = 1 - ||y - g_c y_s||^2
/ ||y||^2 (g_c the complex gain) says how well the reference scene explains the capture: a
target misplaced by more than a range resolution, or a capture of something else, explains
little, and the gain then means nothing.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import torch
from pydantic import Field

from ..config import StrictModel, validate
from ..errors import RfsdfError
from ..limits import input_file
from .acquisition import Acquisition, Measurements
from .simulate import simulate

__all__ = ["CaptureGain", "capture_gain", "acquisition_digest", "read_capture_gain", "EXPLAINED_AT_LEAST",
           "REFERENCE_SAMPLES_PER_WAVELENGTH"]

# below this share of the capture's energy explained by the reference scene, the gain is refused
EXPLAINED_AT_LEAST = 0.5
REFERENCE_SAMPLES_PER_WAVELENGTH = 12
_MOST_BYTES = 1 << 16  # a gain file is a few hundred bytes


def acquisition_digest(acquisition: Acquisition) -> str:
    """SHA-256 (hex, 16 digits) of the antenna positions, frequencies and boresights: the same
    radar and settings give the same digest."""
    h = hashlib.sha256()
    for tensor in (acquisition.tx_m, acquisition.rx_m, acquisition.frequencies_hz, acquisition.boresight):
        h.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    h.update(repr((acquisition.pattern_exponent, acquisition.spreading)).encode())
    return h.hexdigest()[:16]


@dataclass(frozen=True)
class CaptureGain:
    """``gain`` [data units per simulator unit], ``explained`` (share of the capture's energy
    the reference scene explains, 0..1), the ``acquisition`` digest it holds for, and the
    names of the capture and the reference scene."""

    gain: float
    explained: float
    acquisition: str
    capture: str
    scene: str

    def as_dict(self) -> dict:
        return {"gain": self.gain, "explained": self.explained, "acquisition": self.acquisition,
                "capture": self.capture, "scene": self.scene}

    def require_radar(self, acquisition: Acquisition, source: str) -> None:
        """RfsdfError unless ``acquisition`` is the one this gain was measured with."""
        if acquisition_digest(acquisition) != self.acquisition:
            raise RfsdfError(f"{source}: acquisition: the gain was measured with another radar or other settings "
                             f"(antennas, frequencies or views differ from the capture {self.capture!r}'s); "
                             "calibrate with a capture of this radar")


class _GainFile(StrictModel):
    gain: float = Field(gt=0)
    explained: float = Field(ge=0, le=1)
    acquisition: str = Field(pattern=r"^[0-9a-f]{16}$")
    capture: str
    scene: str


def read_capture_gain(path) -> CaptureGain:
    """A gain file ``rfsdf calibrate`` wrote; RfsdfError 'file: field: reason' on bad input."""
    path = input_file(path)
    if path.stat().st_size > _MOST_BYTES:
        raise RfsdfError(f"{path}: {path.stat().st_size:,} bytes: not a gain file from rfsdf calibrate (a few hundred)")
    try:
        table = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RfsdfError(f"{path}: not a gain file (JSON) from rfsdf calibrate: {exc}") from None
    if not isinstance(table, dict):
        raise RfsdfError(f"{path}: not a gain file (JSON) from rfsdf calibrate: expected an object")
    return CaptureGain(**validate(_GainFile, table, str(path)).model_dump())


@dataclass(frozen=True)
class _AcquisitionRadar:
    """A capture's acquisition as the noise-free radar :func:`simulate` takes."""

    acq: Acquisition
    name: str = "capture"
    snr_db: None = None

    def acquisition(self) -> Acquisition:
        return self.acq


def capture_gain(capture: Measurements, reference, *, capture_name: str = "capture", seed: int = 0,
                 max_samples: int = 1_000_000) -> CaptureGain:
    """The gain of the radar that took ``capture`` of the scene ``reference`` (a
    :class:`~rfsdf.scene.Scene` holding the known target where it stood). ValueError when the
    reference explains less than ``EXPLAINED_AT_LEAST`` of the capture's energy."""
    simulated = simulate(reference, _AcquisitionRadar(capture.acquisition), seed=seed, max_samples=max_samples,
                         samples_per_wavelength=REFERENCE_SAMPLES_PER_WAVELENGTH).data
    y, y_s = capture.data.to(torch.complex128).ravel(), simulated.to(torch.complex128).ravel()
    power = float(torch.vdot(y_s, y_s).real)
    if power == 0.0:
        raise ValueError(f"scene {reference.name!r}: the capture's views see none of it")
    complex_gain = torch.vdot(y_s, y) / power
    explained = 1.0 - float((y - complex_gain * y_s).norm() ** 2 / y.norm().clamp(min=1e-300) ** 2)
    if explained < EXPLAINED_AT_LEAST:
        raise ValueError(f"{capture_name}: scene {reference.name!r} explains {max(explained, 0.0):.0%} of the "
                         f"capture's energy (at least {EXPLAINED_AT_LEAST:.0%} needed): is the target where the "
                         "scene puts it, and is it the capture's only strong return?")
    return CaptureGain(float(complex_gain.abs()), round(explained, 6), acquisition_digest(capture.acquisition),
                       capture_name, reference.name)
