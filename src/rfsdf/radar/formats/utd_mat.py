"""UT Dallas' 3-D MIMO-SAR captures (Yanik and Torlak's example data): MATLAB files.

A capture folder holds ``rawData.mat``, ``sensorParams.mat`` and ``sarParams.mat``, each one
variable of its name, as their processing (``highLevelProcessingFlow.m``) loads them:

- ``rawData``: complex (Num_RX Num_TX, Num_verticalScan, Num_horizontalScan,
  Samples_per_Chirp); channel ``t Num_RX + r`` is Tx t's chirp at Rx r (Rx fastest).
- ``sensorParams``: Start_Freq_GHz, Slope_MHzperus, Sampling_Rate_ksps, Adc_Start_Time_us,
  Samples_per_Chirp, Num_TX, RxToEnable (Rx numbers from 1), Frame_Repetition_Period_ms.
- ``sarParams``: Num_horizontalScan, Num_verticalScan, Vertical_stepSize_mm,
  Platform_Speed_mmps. The rail moves on during a row, so the horizontal step is the speed
  times the frame period.
- optionally ``calData.mat`` (``calData``, (C,) complex gains) and ``delayOffset.mat``
  (``delayOffset``, (C,) [s]), applied as their ``calibrateDataFunction.m`` does:
  x calData exp(-j 2 pi delayOffset S n / f_s) for ADC sample n.

Files MATLAB saved as v7.3 (HDF5, needed past 2 GB) are read with h5py, the others with SciPy.

The board is TI's IWR1443 in their frame (``getAntennaLocations.m``): x horizontal, y
vertical, z depth, facing +z, its Rx on a vertical line below Tx1 (``boards.py``'s
``iwr1443``, Rx axis -y). Frame (v, h) has Tx1 at (h dx, v dy, 0) [m] and becomes a view of
its Tx and Rx, as every importer makes a capture's frames. The IF sign and the fixed range
delay are undone as for a DCA1000 capture of the board; a delayOffset calibration already
holds the fixed delay, so with one none is undone unless asked.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import scipy.io
import torch

from ...atomic import atomic_path
from ...errors import RfsdfError
from ...limits import require_memory
from ..acquisition import Measurements
from ..boards import board
from .mmwave_studio import ChirpConfig
from .ti_capture import CaptureGeometry, delay_phase

__all__ = ["UTD_FILES", "is_utd", "read_utd", "write_utd"]

UTD_FILES = ("rawData", "sensorParams", "sarParams")
_CALIBRATION = ("calData", "delayOffset")
_SENSOR = ("Start_Freq_GHz", "Slope_MHzperus", "Sampling_Rate_ksps", "Adc_Start_Time_us", "Samples_per_Chirp",
           "Num_TX", "RxToEnable", "Frame_Repetition_Period_ms")
_SAR = ("Num_horizontalScan", "Num_verticalScan", "Vertical_stepSize_mm", "Platform_Speed_mmps")
_TX_MASKS = {1: 0b1, 3: 0b111}  # Num_TX -> the IWR1443's Tx in chirp order


def is_utd(path) -> bool:
    """Whether ``path`` is a folder holding UT Dallas' ``rawData.mat``."""
    return (Path(path) / "rawData.mat").is_file()


def _h5_value(node):
    """A v7.3 variable: a struct (group) as a dict, an array in MATLAB's axis order."""
    if isinstance(node, h5py.Group):
        return {key: _h5_value(node[key]) for key in node}
    value = node[()]
    if value.dtype.names and {"real", "imag"} <= set(value.dtype.names):
        value = value["real"] + 1j * value["imag"]
    return np.asarray(value).T.squeeze() if np.ndim(value) else value


def _struct_fields(value) -> dict:
    if isinstance(value, dict):
        return value
    return {name: getattr(value, name) for name in getattr(value, "_fieldnames", ())}


def _variable(folder: Path, name: str, *, optional: bool = False):
    """Variable ``name`` of ``folder / name.mat`` (a struct as a dict); None when optional and absent."""
    path = folder / f"{name}.mat"
    if not path.is_file():
        if optional:
            return None
        raise RfsdfError(f"{path}: missing (a UT Dallas capture holds {', '.join(f + '.mat' for f in UTD_FILES)})")
    try:
        if h5py.is_hdf5(path):
            with h5py.File(path, "r") as fh:
                value = _h5_value(fh[name])
        else:
            value = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False, variable_names=[name])[name]
    except KeyError:
        raise RfsdfError(f"{path}: holds no variable {name!r}") from None
    except (OSError, ValueError, TypeError, NotImplementedError, scipy.io.matlab.MatReadError) as exc:
        raise RfsdfError(f"{path}: cannot read as a MATLAB file ({exc})") from None
    return _struct_fields(value) if name in ("sensorParams", "sarParams") else value


def _numbers(fields: dict, names, path: Path) -> dict:
    """The named fields as finite float arrays (scalars squeezed), or one error line."""
    out = {}
    for name in names:
        if name not in fields:
            raise RfsdfError(f"{path}: no field {name}")
        try:
            value = np.asarray(fields[name], dtype=float).squeeze()
        except (TypeError, ValueError):
            raise RfsdfError(f"{path}: {name} is not numeric") from None
        if value.size == 0 or not np.isfinite(value).all():
            raise RfsdfError(f"{path}: {name} is empty, NaN or Inf")
        out[name] = value
    return out


def _count(value: np.ndarray, name: str, path: Path) -> int:
    if value.ndim or value < 1 or value != round(float(value)):
        raise RfsdfError(f"{path}: {name} must be a positive whole number, got {value}")
    return int(value)


def _setup(folder: Path) -> tuple[ChirpConfig, tuple[int, int], tuple[float, float]]:
    """The chirp, the raster's (vertical, horizontal) positions and its (dx, dy) steps [m]."""
    sensor_path, sar_path = folder / "sensorParams.mat", folder / "sarParams.mat"
    sensor = _numbers(_variable(folder, "sensorParams"), _SENSOR, sensor_path)
    sar = _numbers(_variable(folder, "sarParams"), _SAR, sar_path)
    num_tx = _count(sensor["Num_TX"], "Num_TX", sensor_path)
    if num_tx not in _TX_MASKS:
        raise RfsdfError(f"{sensor_path}: Num_TX {num_tx}: which of the IWR1443's Tx fired is recorded only for 1 "
                         "(Tx1) or 3 (all)")
    rx = np.atleast_1d(sensor["RxToEnable"])
    if not np.isin(rx, [1, 2, 3, 4]).all() or len(set(rx.tolist())) != len(rx) or list(rx) != sorted(rx):
        raise RfsdfError(f"{sensor_path}: RxToEnable must list Rx numbers 1 to 4 in order, got {rx.tolist()}")
    samples = _count(sensor["Samples_per_Chirp"], "Samples_per_Chirp", sensor_path)
    shape = (_count(sar["Num_verticalScan"], "Num_verticalScan", sar_path),
             _count(sar["Num_horizontalScan"], "Num_horizontalScan", sar_path))
    period_s = float(sensor["Frame_Repetition_Period_ms"]) * 1e-3
    steps = (float(sar["Platform_Speed_mmps"]) * 1e-3 * period_s, float(sar["Vertical_stepSize_mm"]) * 1e-3)
    if min(abs(steps[0]), abs(steps[1])) == 0:
        raise RfsdfError(f"{sar_path}: the raster's steps must not be zero (Platform_Speed_mmps x the frame period, "
                         "Vertical_stepSize_mm)")
    for name in ("Start_Freq_GHz", "Slope_MHzperus", "Sampling_Rate_ksps"):
        if sensor[name] <= 0:
            raise RfsdfError(f"{sensor_path}: {name} must be positive, got {sensor[name]}")
    chirp = ChirpConfig(start_hz=float(sensor["Start_Freq_GHz"]) * 1e9,
                        slope_hz_per_s=float(sensor["Slope_MHzperus"]) * 1e12,
                        sample_rate_hz=float(sensor["Sampling_Rate_ksps"]) * 1e3, samples=samples,
                        adc_start_s=float(sensor["Adc_Start_Time_us"]) * 1e-6, idle_s=0.0, ramp_end_s=0.0,
                        rx_mask=int(sum(1 << (int(k) - 1) for k in rx)), tx_mask=_TX_MASKS[num_tx], complex=True,
                        chirps_per_loop=num_tx, loops=1, frames=shape[0] * shape[1], frame_period_s=period_s)
    return chirp, shape, steps


def _raster(shape: tuple[int, int], steps: tuple[float, float]) -> np.ndarray:
    """(nv nh, 3) [m] Tx1 of frame (v, h) at (h dx, v dy, 0), vertical index slowest."""
    v, h = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    return np.column_stack([h.ravel() * steps[0], v.ravel() * steps[1], np.zeros(v.size)])


def _beat_phase(chirp: ChirpConfig, delay_s: np.ndarray) -> np.ndarray:
    """(C, K) exp(-j 2 pi delay S n / f_s): calibrateDataFunction's beat-frequency term."""
    beat_hz = np.arange(chirp.samples) * chirp.slope_hz_per_s / chirp.sample_rate_hz
    return np.exp(-2j * np.pi * np.asarray(delay_s, float).reshape(-1, 1) * beat_hz)


def _calibration(folder: Path, channels: int):
    """(calData (C,), delayOffset (C,) [s]) from the folder, each None when absent."""
    found = []
    for name in _CALIBRATION:
        value = _variable(folder, name, optional=True)
        if value is not None:
            value = np.asarray(value).ravel()
            if value.shape != (channels,) or not np.isfinite(value).all():
                raise RfsdfError(f"{folder / (name + '.mat')}: {name} must hold {channels} finite values (one a "
                                 f"channel), got shape {np.shape(value)}")
        found.append(value)
    return tuple(found)


def read_utd(folder, *, range_delay_m: float | None = None, conjugate: bool | None = None) -> Measurements:
    """Measurements of the UT Dallas capture in ``folder``: each raster position a view of its
    Tx and Rx, calibrated when the folder holds calData.mat / delayOffset.mat. ``range_delay_m``
    and ``conjugate``: the fixed delay and IF sign to undo (None: the IWR1443's, 0.15 m and
    conjugated; no delay with a delayOffset calibration). One error line naming the file and
    field for anything missing or malformed."""
    folder = Path(folder)
    chirp, shape, steps = _setup(folder)
    t, r, k = chirp.chirps_per_loop, chirp.rx, chirp.samples
    expected = (t * r, *shape, k)
    require_memory(16 * 3 * int(np.prod(expected)), f"{folder}: the capture ({shape[0]} x {shape[1]} positions, "
                   f"{t * r} channels x {k} samples)")
    raw = np.asarray(_variable(folder, "rawData"))
    path = folder / "rawData.mat"
    if raw.shape != expected:
        raise RfsdfError(f"{path}: rawData has shape {raw.shape}; sensorParams and sarParams give (Num_RX Num_TX, "
                         f"Num_verticalScan, Num_horizontalScan, Samples_per_Chirp) = {expected}")
    if not np.isfinite(raw).all():
        raise RfsdfError(f"{path}: rawData contains NaN or Inf")
    gains, delays = _calibration(folder, t * r)
    cube = raw.astype(np.complex128).reshape(t * r, -1, k)
    if gains is not None:
        cube = cube * gains[:, None, None]
    if delays is not None:
        cube = cube * _beat_phase(chirp, delays)[:, None]
    if range_delay_m is None and delays is not None:
        range_delay_m = 0.0
    geometry = CaptureGeometry(board("iwr1443"), range_delay_m=range_delay_m, conjugate=conjugate)
    acquisition = geometry.acquisition(chirp, _raster(shape, steps))
    data = torch.from_numpy(cube.reshape(t, r, -1, k).transpose(2, 0, 1, 3).copy())  # (V, T, R, K)
    data = (data.conj() if geometry.flip else data).resolve_conj()
    data = data * delay_phase(acquisition.frequencies_hz, geometry.delay_m).conj()
    return Measurements(acquisition, data, None, {"source": str(folder), "format": "utd-mat"})


def write_utd(folder, measurements: Measurements, chirp: ChirpConfig, shape: tuple[int, int],
              steps_m: tuple[float, float], *, calibration: tuple[np.ndarray, np.ndarray] | None = None,
              range_delay_m: float | None = None) -> Path:
    """Write ``measurements`` (views: the frames of :func:`read_utd`'s raster ``shape`` (nv, nh)
    with ``steps_m`` (dx, dy), in order) as the IWR1443 would have recorded them, with
    ``calibration`` (calData, delayOffset [s]) undone so that applying it recovers the data;
    the inverse of :func:`read_utd` (v5 MAT files)."""
    folder = Path(folder)
    v, t, r, k = measurements.acquisition.shape
    if v != shape[0] * shape[1] or (t, r, k) != (chirp.chirps_per_loop, chirp.rx, chirp.samples):
        raise ValueError(f"measurements {measurements.acquisition.shape} do not match a {shape} raster of {chirp.chirps_per_loop} "
                         f"Tx x {chirp.rx} Rx x {chirp.samples} samples")
    geometry = CaptureGeometry(board("iwr1443"), range_delay_m=range_delay_m)
    delay = geometry.delay_m if range_delay_m is not None or calibration is None else 0.0
    data = measurements.data.to(torch.complex128) * delay_phase(measurements.acquisition.frequencies_hz, delay)
    cube = (data.conj() if geometry.flip else data).resolve_conj().numpy()  # (V, T, R, K)
    cube = cube.transpose(1, 2, 0, 3).reshape(t * r, v, k)
    variables = {}
    if calibration is not None:
        gains, delays = (np.asarray(c).ravel() for c in calibration)
        cube = cube / gains[:, None, None] / _beat_phase(chirp, delays)[:, None]
        variables.update(calData=gains.reshape(-1, 1), delayOffset=delays.reshape(-1, 1))
    rx = [k + 1 for k in range(4) if chirp.rx_mask >> k & 1]
    period_ms = chirp.frame_period_s * 1e3
    variables.update(
        rawData=cube.reshape(t * r, *shape, k),
        sensorParams={"Start_Freq_GHz": chirp.start_hz / 1e9, "Slope_MHzperus": chirp.slope_hz_per_s / 1e12,
                      "Sampling_Rate_ksps": chirp.sample_rate_hz / 1e3, "Adc_Start_Time_us": chirp.adc_start_s * 1e6,
                      "Samples_per_Chirp": k, "Num_TX": t, "RxToEnable": np.array(rx, float),
                      "Frame_Repetition_Period_ms": period_ms},
        sarParams={"Num_horizontalScan": shape[1], "Num_verticalScan": shape[0],
                   "Vertical_stepSize_mm": steps_m[1] * 1e3, "Platform_Speed_mmps": steps_m[0] * 1e3 / (period_ms * 1e-3)})
    folder.mkdir(parents=True, exist_ok=True)
    for name, value in variables.items():
        with atomic_path(folder / f"{name}.mat") as tmp, open(tmp, "wb") as fh:
            scipy.io.savemat(fh, {name: value})
    return folder
