"""MITO's robot captures (the dataset family of GeRaF and mmNorm): one scan of an IWR1443 on an arm.

A capture folder (in MITO's tree ``<object>/robot_collected/<angles>/exp<N>/<los|nlos>/
unprocessed/radars/77_ghz``) holds, as MITO's ``GenericLoader`` reads them:

- ``radar_data/adc_data<timestamp>*.bin``: DCA1000 records (4 lanes, complex I/Q), one a row
  of the scan, frames of one or more chirps, of which the first is used;
- ``continuous*.pkl``: the arm's log of its rows, ``all_radar_filenames`` (each record's
  timestamp, as in its name) and ``all_radar_created_ts`` (when its first frame was taken
  [s]; -1 where the row has no record);
- ``antenna*.npz``: the Tx's track, ``times_77`` (N,) [s] and ``tx_77_locs`` (N, 3 or more;
  the first three are the position [m] in the arm's base frame);

and ``experiment_info.json``, in the folder or up to four folders above it (MITO keeps it in
``exp<N>``): its ``rx offset`` ("x" or "y") is the axis along which the board's Rx lie, on
its negative side, 5 mm + (3 - k) lambda/2 from the Tx for Rx k (``boards.py``'s
``iwr1443``). Its ``aperture size`` names the chirp's entry in MITO's ``params.json``.

Frame j of a record was taken at created_ts + j * frame period, where the track is
interpolated linearly; frames outside the track, and frames within 3 lambda / 16 of an
earlier one of the same row (the arm standing still), are dropped, as MITO's own imaging
drops them. The chirp comes from an mmWave Studio ``*.mmwave.json`` or from MITO's
``params.json`` (``robot_collected`` -> ``77_ghz`` -> the aperture: ``min_f``, ``slope``
[Hz a sample], ``num_samples``, ``num_chirps``, ``periodicity`` and ``sweep_time`` [s]). The
scan is one view (``Acquisition.scans``): MITO images it coherently. The log is a pickle;
it is read with only containers, numbers and NumPy arrays allowed, never code.
"""

from __future__ import annotations

import dataclasses
import json
import pickle
import re
from pathlib import Path

import numpy as np
import torch

from ...atomic import atomic_path
from ...errors import RfsdfError
from ...jsonio import read_json
from ...limits import require_memory
from ..acquisition import SPEED_OF_LIGHT, Measurements
from ..boards import board
from .dca1000 import AdcLayout, read_bin, write_bin
from .mmwave_studio import ChirpConfig, mmwave_chirp
from .ti_capture import CaptureGeometry, model_data, recorded_counts

__all__ = ["MITO_SAMPLE_RATE_HZ", "is_mito", "mito_chirp", "read_mito", "write_mito", "write_mito_params"]

MITO_SAMPLE_RATE_HZ = 10e6  # the IWR1443's ADC rate in MITO's captures; params.json gives Hz a sample
_RX_AXES = {"x": (-1.0, 0.0, 0.0), "y": (0.0, -1.0, 0.0)}
_REPEAT_WAVELENGTHS = 3 / 16  # closer frames of one row are the arm standing still (MITO's threshold)
_INFO = "experiment_info.json"
_RECORD = re.compile(r"adc_data_?(\d+)")


def is_mito(path) -> bool:
    """Whether ``path`` is a MITO capture folder (``radar_data/adc_data*.bin`` and a track)."""
    folder = Path(path)
    return (folder / "radar_data").is_dir() and any((folder / "radar_data").glob("adc_data*.bin")) \
        and any(folder.glob("antenna*.npz"))


def _experiment_info(folder: Path) -> tuple[Path, dict]:
    for parent in [folder, *folder.parents][:5]:
        path = parent / _INFO
        if path.is_file():
            info = read_json(path)
            if not isinstance(info, dict):
                raise RfsdfError(f"{path}: not a JSON object")
            return path, info
    raise RfsdfError(f"{folder}: no {_INFO} in it or the four folders above it (MITO keeps it in exp<N>)")


def _info_field(folder: Path, key: str, allowed=None) -> str:
    path, info = _experiment_info(folder)
    value = info.get(key)
    if not isinstance(value, str) or (allowed is not None and value not in allowed):
        expected = f"one of {', '.join(map(repr, allowed))}" if allowed else "a name"
        raise RfsdfError(f"{path}: {key!r}: {value!r}; expected {expected}")
    return value


def mito_chirp(config, capture) -> ChirpConfig:
    """The chirp of a MITO ``capture`` folder from ``config``: an mmWave Studio ``*.mmwave.json``,
    or MITO's ``params.json`` (its entry for the capture's ``aperture size``)."""
    config = Path(config)
    document = read_json(config)
    if not (isinstance(document, dict) and "robot_collected" in document):
        return mmwave_chirp(config, document)
    aperture = _info_field(Path(capture), "aperture size")
    where = f"robot_collected.77_ghz.{aperture}"
    try:
        entry = document["robot_collected"]["77_ghz"][aperture]
        values = {key: float(entry[key]) for key in ("min_f", "slope", "num_samples", "num_chirps", "periodicity")}
        sweep = float(entry.get("sweep_time", 0.0))
    except (KeyError, TypeError) as exc:
        raise RfsdfError(f"{config}: {where}: {exc.args[0] if exc.args else ''} missing") from None
    except ValueError as exc:
        raise RfsdfError(f"{config}: {where}: {exc}") from None
    if not all(np.isfinite(v) and v > 0 for v in values.values()):
        raise RfsdfError(f"{config}: {where}: min_f, slope, num_samples, num_chirps and periodicity must be > 0")
    samples = int(values["num_samples"])
    return ChirpConfig(start_hz=values["min_f"], slope_hz_per_s=values["slope"] * MITO_SAMPLE_RATE_HZ,
                       sample_rate_hz=MITO_SAMPLE_RATE_HZ, samples=samples, adc_start_s=0.0, idle_s=0.0,
                       ramp_end_s=samples / MITO_SAMPLE_RATE_HZ, rx_mask=0xF, tx_mask=0x1, complex=True,
                       chirps_per_loop=int(values["num_chirps"]), loops=1, frames=0,
                       frame_period_s=values["periodicity"] + sweep, lanes=4)


class _LogUnpickler(pickle.Unpickler):
    """Containers, numbers, strings and NumPy arrays: a robot's log, never code."""

    _ALLOWED = {(module, name) for module in ("numpy.core.multiarray", "numpy._core.multiarray")
                for name in ("_reconstruct", "scalar")} | {("numpy", "ndarray"), ("numpy", "dtype")}

    def find_class(self, module, name):
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"{module}.{name} is not part of a robot log")


def _log(folder: Path) -> tuple[list[int], list[float]]:
    """Each row's record timestamp and the time of its first frame [s] (-1: no record)."""
    paths = sorted(folder.glob("continuous*.pkl"))
    if not paths:
        raise RfsdfError(f"{folder}: no continuous*.pkl (the arm's log of the rows and their records)")
    names, times = [], []
    for path in paths:
        try:
            with open(path, "rb") as fh:
                log = _LogUnpickler(fh).load()
            part_names = [int(name) for name in log["all_radar_filenames"]]
            part_times = [float(t) for t in log["all_radar_created_ts"]]
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError) as exc:
            raise RfsdfError(f"{path}: cannot read as the arm's log ({exc})") from None
        except (KeyError, TypeError, ValueError) as exc:
            raise RfsdfError(f"{path}: all_radar_filenames / all_radar_created_ts: missing or not numbers "
                             f"({exc})") from None
        if len(part_names) != len(part_times):
            raise RfsdfError(f"{path}: all_radar_filenames has {len(part_names)} rows, all_radar_created_ts "
                             f"{len(part_times)}")
        names += part_names
        times += part_times
    return names, times


def _track(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """The Tx's track: times (N,) [s], increasing, and positions (N, 3) [m]."""
    times, positions = [], []
    for path in sorted(folder.glob("antenna*.npz")):
        try:
            with np.load(path, allow_pickle=False) as arrays:
                t, p = np.asarray(arrays["times_77"], float), np.asarray(arrays["tx_77_locs"], float)
        except (OSError, ValueError, KeyError) as exc:
            raise RfsdfError(f"{path}: cannot read times_77 and tx_77_locs ({exc})") from None
        if t.ndim != 1 or p.ndim != 2 or p.shape[1] < 3:
            raise RfsdfError(f"{path}: times_77 must be (N,) and tx_77_locs (N, 3 or more); got {t.shape}, {p.shape}")
        n = min(len(t), len(p))  # the two logs may end a sample apart (MITO cuts them to the shorter)
        if not (np.isfinite(t[:n]).all() and np.isfinite(p[:n, :3]).all()):
            raise RfsdfError(f"{path}: times_77 or tx_77_locs: NaN or Inf")
        times.append(t[:n])
        positions.append(p[:n, :3])
    times, positions = np.concatenate(times), np.concatenate(positions)
    if len(times) < 2 or np.any(np.diff(times) <= 0):
        raise RfsdfError(f"{folder}: antenna*.npz: times_77 needs two or more samples in increasing order")
    return times, positions


def _records(folder: Path) -> dict[int, Path]:
    records = {}
    for path in sorted((folder / "radar_data").glob("adc_data*.bin")):
        match = _RECORD.match(path.name)
        if match:
            records[int(match.group(1))] = path
    return records


def _moved(positions: np.ndarray, distance_m: float) -> np.ndarray:
    """Indices of the positions (F, 3) [m] of one row kept in order: each at least ``distance_m``
    from every one kept before it."""
    kept = np.empty(len(positions), dtype=np.int64)
    count = 0
    for j, position in enumerate(positions):
        if count == 0 or np.min(np.linalg.norm(positions[kept[:count]] - position, axis=1)) >= distance_m:
            kept[count] = j
            count += 1
    return kept[:count]


def read_mito(folder, chirp: ChirpConfig, *, boresight=(0.0, 0.0, -1.0), range_delay_m: float | None = None,
              conjugate: bool | None = None) -> Measurements:
    """Measurements of the MITO capture ``folder`` recorded with ``chirp`` (:func:`mito_chirp`), the
    board facing ``boresight`` (MITO's arm looks down on the table: -z), one view; the
    IWR1443's fixed range delay and IF sign undone unless given. One error line naming the
    file and field for anything missing or inconsistent."""
    folder = Path(folder)
    if not is_mito(folder):
        raise RfsdfError(f"{folder}: not a MITO capture (radar_data/adc_data*.bin and antenna*.npz)")
    rx_axis = _RX_AXES[_info_field(folder, "rx offset", tuple(_RX_AXES))]
    chirp = dataclasses.replace(chirp, tx_mask=chirp.tx_mask & -chirp.tx_mask)  # each frame's first chirp: one Tx
    try:
        layout = AdcLayout(4, chirp.complex, chirp.rx, chirp.samples, chirp.chirps)
    except ValueError as exc:
        raise RfsdfError(f"{folder}: the chirp's {exc}") from None
    if not chirp.complex:
        raise RfsdfError(f"{folder}: the chirp config records real samples; rfsdf's model needs complex I/Q")
    records, (times, track) = _records(folder), _track(folder)
    names, created = _log(folder)
    sizes = [records[name].stat().st_size for name, t in zip(names, created) if t != -1 and name in records]
    require_memory(8 * sum(sizes), f"{folder}: the capture's records")
    repeat_m = _REPEAT_WAVELENGTHS * SPEED_OF_LIGHT / chirp.frequencies_hz()[0]
    positions, samples = [], []
    for name, start in zip(names, created):
        if start == -1:
            continue
        if name not in records:
            raise RfsdfError(f"{folder / 'radar_data'}: no adc_data{name}*.bin, which the arm's log lists")
        cube = read_bin(records[name], layout)[:, 0]  # (F, R, K): each frame's first chirp
        frame_times = start + np.arange(len(cube)) * chirp.frame_period_s
        inside = np.flatnonzero((frame_times >= times[0]) & (frame_times <= times[-1]))
        at = np.stack([np.interp(frame_times[inside], times, track[:, k]) for k in range(3)], 1)
        kept = _moved(at, repeat_m)
        positions.append(at[kept])
        samples.append(cube[inside[kept]])
    positions = np.concatenate(positions) if positions else np.empty((0, 3))
    if not len(positions):
        raise RfsdfError(f"{folder}: no frame lies within the track's times (antenna*.npz times_77 against "
                         "continuous*.pkl all_radar_created_ts)")
    geometry = CaptureGeometry(board("iwr1443"), tuple(boresight), rx_axis, range_delay_m, conjugate)
    acquisition = geometry.acquisition(chirp, positions)
    acquisition = dataclasses.replace(acquisition, scans=torch.zeros(len(positions), dtype=torch.int64))
    cube = np.concatenate(samples)[:, None]  # (F, 1, R, K)
    return Measurements(acquisition, model_data(cube, acquisition, geometry), None,
                        {"source": str(folder), "format": "mito"})


def write_mito(folder, measurements: Measurements, chirp: ChirpConfig, *, rx_offset: str, frames_per_row: int,
               boresight=(0.0, 0.0, -1.0), start_s: float = 1.7e9) -> Path:
    """Write ``measurements`` (frames of the IWR1443's Tx0 and four Rx, placed with ``rx_offset``
    ("x" or "y") and ``boresight``) as a MITO capture folder: records of ``frames_per_row``
    frames, a row every 10 s from ``start_s``, one chirp a frame, the track sampled at the
    frames; the inverse of :func:`read_mito` (``experiment_info.json`` inside ``folder``,
    aperture "normal")."""
    v = measurements.acquisition.shape[0]
    if rx_offset not in _RX_AXES or v % frames_per_row:
        raise ValueError(f"rx_offset must be 'x' or 'y' and {v} frames whole rows of {frames_per_row}")
    geometry = CaptureGeometry(board("iwr1443"), tuple(boresight), _RX_AXES[rx_offset])
    cube, _ = recorded_counts(measurements, chirp, geometry)
    folder = Path(folder)
    (folder / "radar_data").mkdir(parents=True, exist_ok=True)
    layout = AdcLayout(4, True, 4, chirp.samples, 1)
    names, created, times = [], [], []
    for row in range(v // frames_per_row):
        name, start = int(start_s) + 10 * row, start_s + 10 * row + 0.125
        write_bin(folder / "radar_data" / f"adc_data{name}.bin", cube[row * frames_per_row:(row + 1) * frames_per_row],
                  layout)
        names.append(str(name))
        created.append(start)
        times.append(start + np.arange(frames_per_row) * chirp.frame_period_s)
    with atomic_path(folder / "continuous.pkl") as tmp, open(tmp, "wb") as fh:
        pickle.dump({"all_radar_filenames": names, "all_radar_created_ts": created}, fh)
    with atomic_path(folder / "antenna.npz") as tmp, open(tmp, "wb") as fh:
        np.savez(fh, times_77=np.concatenate(times), tx_77_locs=measurements.acquisition.tx_m[:, 0].numpy())
    with atomic_path(folder / _INFO) as tmp:
        tmp.write_text(json.dumps({"aperture size": "normal", "rx offset": rx_offset}, indent=2))
    return folder


def write_mito_params(path, chirp: ChirpConfig, aperture: str = "normal") -> Path:
    """MITO's ``params.json`` holding ``chirp`` for ``aperture`` (what :func:`mito_chirp` reads)."""
    first, per_sample = float(chirp.frequencies_hz()[0]), chirp.slope_hz_per_s / chirp.sample_rate_hz
    entry = {"min_f": first, "max_f": first + per_sample * chirp.samples, "bandwidth": per_sample * chirp.samples,
             "slope": per_sample, "num_samples": chirp.samples, "num_rx_antenna": 4, "num_chirps": chirp.chirps,
             "periodicity": chirp.frame_period_s, "num_frames": chirp.frames, "sweep_time": 0}
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps({"robot_collected": {"77_ghz": {aperture: entry}}}, indent=2))
    return Path(path)
