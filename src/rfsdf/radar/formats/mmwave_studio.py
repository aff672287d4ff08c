"""TI mmWave Studio's ``*.mmwave.json`` (the chirp, channels and frame of a capture) and
``*.setup.json`` (which config, which captured files, which device).

Read from ``mmWaveDevices[0].rfConfig`` (some versions write one device as an object rather
than a list): ``rlProfiles[0].rlProfileCfg_t`` (start frequency [GHz], slope [MHz/us],
ADC samples, sample rate [ksps], idle, ADC start and ramp end times [us]), ``rlChanCfg_t``
(Rx and Tx enable masks), ``rlAdcOutCfg_t.fmt`` (16 bits; real or complex samples) and
``rlFrameCfg_t`` (chirps of a loop, loops, frames, periodicity [ms]); the LVDS lanes, where
recorded, from ``rawDataCaptureConfig.rlDevLaneEnable_t.laneEn`` (one bit a lane). The first ADC sample
lies at the start frequency plus slope x ADC start time.

A ``*.setup.json`` names the ``*.mmwave.json`` it used (``configUsed``), the files it
captured (``capturedFiles.fileBasePath`` and ``files[].processedFileName`` or
``rawFileName``) and the device (``mmWaveDevice``); its ``DCA1000Config`` must log raw. Its paths are the capturing PC's (often Windows): a file is found there
or, failing that, by its name beside the setup file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...atomic import atomic_path
from ...errors import RfsdfError
from ...jsonio import read_json
from ..waveform import fmcw_frequencies

__all__ = ["ChirpConfig", "read_mmwave_json", "write_mmwave_json", "CaptureSetup", "read_setup_json",
           "write_setup_json"]

_SIXTEEN_BITS = 2  # rlAdcOutCfg_t.fmt.b2AdcBits
_REAL = 0  # rlAdcOutCfg_t.fmt.b2AdcOutFmt: 0 real, 1 complex (1x), 2 complex (2x)


@dataclass(frozen=True)
class ChirpConfig:
    """One chirp profile and the frames of a capture, in SI units."""

    start_hz: float
    slope_hz_per_s: float
    sample_rate_hz: float
    samples: int
    adc_start_s: float
    idle_s: float
    ramp_end_s: float
    rx_mask: int  # bit k: Rx k enabled
    tx_mask: int
    complex: bool
    chirps_per_loop: int  # chirps of one loop (one per Tx in TDM MIMO)
    loops: int
    frames: int
    frame_period_s: float
    lanes: int | None = None  # LVDS lanes to the DCA1000 (rawDataCaptureConfig), if recorded

    @property
    def rx(self) -> int:
        return bin(self.rx_mask).count("1")

    @property
    def chirps(self) -> int:
        """Chirps in one frame."""
        return self.chirps_per_loop * self.loops

    def frequencies_hz(self) -> np.ndarray:
        """(samples,) [Hz]: the instantaneous frequency of each ADC sample, f0 + S (t_adc + n / f_s)."""
        return fmcw_frequencies(self.start_hz + self.slope_hz_per_s * self.adc_start_s, self.slope_hz_per_s,
                                self.sample_rate_hz, self.samples)


# (JSON field, ChirpConfig field, scale to SI)
_PROFILE = (("startFreqConst_GHz", "start_hz", 1e9), ("freqSlopeConst_MHz_usec", "slope_hz_per_s", 1e12),
            ("digOutSampleRate", "sample_rate_hz", 1e3), ("numAdcSamples", "samples", 1),
            ("adcStartTimeConst_usec", "adc_start_s", 1e-6), ("idleTimeConst_usec", "idle_s", 1e-6),
            ("rampEndTime_usec", "ramp_end_s", 1e-6))


def _where(keys) -> str:
    """``("a", 0, "b")`` -> ``"a[0].b"``."""
    return "".join(f"[{key}]" if isinstance(key, int) else f".{key}" for key in keys).lstrip(".")


def read_mmwave_json(path) -> ChirpConfig:
    """The :class:`ChirpConfig` of an mmWave Studio ``*.mmwave.json``; one error line naming the
    file and the field for anything missing or out of range."""
    path = Path(path)
    return mmwave_chirp(path, read_json(path))


def mmwave_chirp(path: Path, document) -> ChirpConfig:
    """:func:`read_mmwave_json` of the ``document`` already read from ``path``."""
    def field(*keys, required=True):
        value = document
        for depth, key in enumerate(keys):
            if isinstance(key, int) and isinstance(value, dict):  # one device written as an object
                continue
            try:
                value = value[key]
            except (KeyError, IndexError, TypeError):
                if not required:
                    return None
                raise RfsdfError(f"{path}: {_where(keys[:depth + 1])}: missing") from None
        return value

    def number(keys, kind=float, positive=True, value=None):
        value = field(*keys) if value is None else value
        try:
            number = kind(int(value, 16) if isinstance(value, str) and value.lower().startswith("0x") else value)
        except (TypeError, ValueError):
            raise RfsdfError(f"{path}: {_where(keys)}: {value!r} is not a number") from None
        if not np.isfinite(number) or number < 0 or (positive and number == 0):
            raise RfsdfError(f"{path}: {_where(keys)}: {value!r} must be {'> 0' if positive else '>= 0'}")
        return number

    rf = ("mmWaveDevices", 0, "rfConfig")
    profile = (*rf, "rlProfiles", 0, "rlProfileCfg_t")
    values = {name: number((*profile, key), int if name == "samples" else float,
                           positive=name not in ("adc_start_s", "idle_s")) * scale
              for key, name, scale in _PROFILE}
    bits = field(*rf, "rlAdcOutCfg_t", "fmt", "b2AdcBits")
    if bits != _SIXTEEN_BITS:
        raise RfsdfError(f"{path}: {_where((*rf, 'rlAdcOutCfg_t', 'fmt', 'b2AdcBits'))}: {bits!r}; "
                         "only 16-bit samples (2) are read")
    frame = (*rf, "rlFrameCfg_t")
    first, last = (number((*frame, key), int, positive=False) for key in ("chirpStartIdx", "chirpEndIdx"))
    if last < first:
        raise RfsdfError(f"{path}: {_where((*frame, 'chirpEndIdx'))}: {last} is before chirpStartIdx {first}")
    lane_keys = (*rf[:2], "rawDataCaptureConfig", "rlDevLaneEnable_t", "laneEn")
    lane_mask = field(*lane_keys, required=False)
    lanes = None if lane_mask is None else bin(number(lane_keys, int, value=lane_mask)).count("1")
    return ChirpConfig(**values, lanes=lanes, rx_mask=number((*rf, "rlChanCfg_t", "rxChannelEn"), int),
                       tx_mask=number((*rf, "rlChanCfg_t", "txChannelEn"), int),
                       complex=field(*rf, "rlAdcOutCfg_t", "fmt", "b2AdcOutFmt") != _REAL,
                       chirps_per_loop=last - first + 1, loops=number((*frame, "numLoops"), int),
                       frames=number((*frame, "numFrames"), int, positive=False),
                       frame_period_s=number((*frame, "framePeriodicity_msec")) * 1e-3)


def write_mmwave_json(path, config: ChirpConfig) -> Path:
    """An ``*.mmwave.json`` holding ``config`` in mmWave Studio's fields (the ones read back)."""
    profile = {key: getattr(config, name) / scale for key, name, scale in _PROFILE}
    profile["numAdcSamples"] = config.samples
    device = {"mmWaveDeviceId": 0}
    if config.lanes is not None:
        device["rawDataCaptureConfig"] = {"rlDevLaneEnable_t": {"laneEn": hex((1 << config.lanes) - 1)}}
    document = {"configGenerator": {"createdBy": "rfsdf"}, "mmWaveDevices": [{**device, "rfConfig": {
        "rlChanCfg_t": {"rxChannelEn": hex(config.rx_mask), "txChannelEn": hex(config.tx_mask)},
        "rlAdcOutCfg_t": {"fmt": {"b2AdcBits": _SIXTEEN_BITS, "b2AdcOutFmt": 1 if config.complex else _REAL}},
        "rlProfiles": [{"rlProfileCfg_t": {"profileId": 0, **profile}}],
        "rlFrameCfg_t": {"chirpStartIdx": 0, "chirpEndIdx": config.chirps_per_loop - 1, "numLoops": config.loops,
                         "numFrames": config.frames, "framePeriodicity_msec": config.frame_period_s * 1e3}}}]}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(document, indent=2))
    return Path(path)


@dataclass(frozen=True)
class CaptureSetup:
    """What a ``*.setup.json`` points at: the ``config`` (``*.mmwave.json``), the ``captures``
    (the .bin files of one record, in order) and the ``device`` (e.g. ``awr1843``; empty if
    not recorded)."""

    config: Path
    captures: tuple[Path, ...]
    device: str


def _locate(setup: Path, recorded: str) -> Path | None:
    """The file the capturing PC recorded as ``recorded``: there, or by its name beside ``setup``;
    None where it is in neither."""
    name = recorded.replace("\\", "/").rsplit("/", 1)[-1]
    for candidate in (Path(recorded), setup.parent / name):
        if name and candidate.is_file():
            return candidate
    return None


def read_setup_json(path) -> CaptureSetup:
    """The :class:`CaptureSetup` of an mmWave Studio ``*.setup.json`` (one error line naming the
    file and field for anything missing, or a file it names that cannot be found)."""
    path = Path(path)
    document = read_json(path)
    if not isinstance(document, dict):
        raise RfsdfError(f"{path}: not a setup.json (a JSON object)")
    config_used = document.get("configUsed")
    config = _locate(path, config_used) if isinstance(config_used, str) else None
    if config is None:
        raise RfsdfError(f"{path}: configUsed: {config_used!r} is neither there nor beside the setup file")
    captured = document.get("capturedFiles")
    files = captured.get("files") if isinstance(captured, dict) else None
    if not isinstance(files, list) or not files or not all(isinstance(f, dict) for f in files):
        raise RfsdfError(f"{path}: capturedFiles.files: missing or empty")
    base = str(captured.get("fileBasePath") or "").rstrip("/\\")
    separator = "\\" if "\\" in base else "/"
    captures = []
    for k, entry in enumerate(files):
        names = [entry[key] for key in ("processedFileName", "rawFileName") if isinstance(entry.get(key), str)]
        found = [f for f in (_locate(path, f"{base}{separator}{name}" if base else name) for name in names) if f]
        if not found:
            raise RfsdfError(f"{path}: capturedFiles.files[{k}]: none of {names} is in {base!r} "
                             "or beside the setup file")
        captures.append(found[0])
    logging = (document.get("DCA1000Config") or {}).get("dataLoggingMode", "raw")
    if logging != "raw":
        raise RfsdfError(f"{path}: DCA1000Config.dataLoggingMode: {logging!r}; only raw captures are read "
                         "(multi mode adds packet headers)")
    return CaptureSetup(config, tuple(captures), str(document.get("mmWaveDevice") or "").lower())


def write_setup_json(path, config: Path, captures: list[Path], device: str) -> Path:
    """A ``*.setup.json`` naming ``config`` and ``captures`` (by name, beside it) and ``device``,
    in mmWave Studio's fields."""
    document = {"createdBy": "rfsdf", "configUsed": Path(config).name, "captureHardware": "DCA1000",
                "DCA1000Config": {"dataLoggingMode": "raw", "dataTransferMode": "LVDSCapture",
                                  "dataCaptureMode": "ethernetStream", "packetSequenceEnable": 1,
                                  "packetDelay_us": 25},
                "mmWaveDevice": device,
                "capturedFiles": {"fileBasePath": "", "numFilesCollected": len(captures),
                                  "files": [{"processedFileName": Path(c).name} for c in captures]}}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(document, indent=2))
    return Path(path)
