"""HDF5 files for measurements and images, and import of real FMCW captures.

Schema (format_version 1), all arrays in SI units:

measurements file, attribute ``format = "rfsdf.measurements"``:
  tx_m (V, T, 3) f8, rx_m (V, R, 3) f8, frequencies_hz (K,) f8, boresight (V, 3) f8,
  data (V, T, R, K) c8, optionally scans (V,) i8 (the view each frame belongs to, when views
  are scans); attributes pattern_exponent, spreading, noise_std (NaN if unknown), and
  ``meta_*`` strings (scene, radar, ...).
image file, attribute ``format = "rfsdf.image"``:
  per_view (V, nx, ny, nz) c8, column_norms_sq (V, nx, ny, nz) f4, lower_m (3,), upper_m (3,).
"""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import torch

from ..atomic import atomic_path
from ..errors import RfsdfError
from ..geometry import Grid
from ..limits import input_file, require_memory
from .acquisition import Acquisition, Measurements
from .imaging import Image
from .waveform import fmcw_frequencies

__all__ = ["FORMAT_VERSION", "write_measurements", "read_measurements", "write_image", "read_image", "import_fmcw",
           "parse_bounds"]

FORMAT_VERSION = 1
_MEASUREMENTS, _IMAGE = "rfsdf.measurements", "rfsdf.image"


def _open_hdf5(path) -> h5py.File:
    path = input_file(path)
    try:
        return h5py.File(path, "r")
    except OSError:
        raise RfsdfError(f"{path}: not a readable HDF5 file (truncated or corrupt?)") from None


def _open(path, kind: str) -> h5py.File:
    fh = _open_hdf5(path)
    fmt, version = fh.attrs.get("format"), fh.attrs.get("format_version")
    if fmt != kind:
        fh.close()
        raise RfsdfError(f"{path}: format: expected {kind!r}, got {fmt!r}")
    if version != FORMAT_VERSION:
        fh.close()
        raise RfsdfError(f"{path}: format_version: this rfsdf reads version {FORMAT_VERSION}, the file is version {version}")
    return fh


def _read(fh: h5py.File, name: str, path) -> np.ndarray:
    if name not in fh or not isinstance(fh[name], h5py.Dataset):
        raise RfsdfError(f"{path}: {name}: dataset missing")
    dataset = fh[name]
    require_memory(dataset.size * dataset.dtype.itemsize, f"{path}: {name}: its declared shape {dataset.shape}")
    try:
        return dataset[()]
    except OSError:
        raise RfsdfError(f"{path}: {name}: cannot be read (truncated file?)") from None


def write_measurements(path, m: Measurements) -> Path:
    """Write ``m`` to ``path`` atomically."""
    acq = m.acquisition
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        fh.attrs.update(format=_MEASUREMENTS, format_version=FORMAT_VERSION, pattern_exponent=acq.pattern_exponent,
                        spreading=acq.spreading, noise_std=math.nan if m.noise_std is None else m.noise_std)
        for key, value in m.metadata.items():
            fh.attrs[f"meta_{key}"] = value
        for name in ("tx_m", "rx_m", "frequencies_hz", "boresight"):
            fh[name] = getattr(acq, name).numpy()
        if acq.scans is not None:
            fh["scans"] = acq.scans.numpy()
        fh.create_dataset("data", data=m.data.numpy(), compression="gzip", compression_opts=1)
    return Path(path)


def read_measurements(path) -> Measurements:
    """Read a measurements file; RfsdfError naming the file and field on any problem."""
    with _open(path, _MEASUREMENTS) as fh:
        arrays = {n: _read(fh, n, path) for n in ("tx_m", "rx_m", "frequencies_hz", "boresight", "data")}
        scans = _read(fh, "scans", path) if "scans" in fh else None
        attrs = dict(fh.attrs)
    if not np.isfinite(arrays["data"].view(np.float32)).all():
        raise RfsdfError(f"{path}: data: contains NaN or Inf")
    try:
        acq = Acquisition(*(torch.from_numpy(np.asarray(arrays[n], np.float64)) for n in ("tx_m", "rx_m", "frequencies_hz", "boresight")),
                          pattern_exponent=float(attrs.get("pattern_exponent", 0.0)), spreading=bool(attrs.get("spreading", True)),
                          scans=None if scans is None else torch.from_numpy(np.asarray(scans)))
        noise = float(attrs.get("noise_std", math.nan))
        meta = {k.removeprefix("meta_"): str(v) for k, v in attrs.items() if k.startswith("meta_")}
        return Measurements(acq, torch.from_numpy(arrays["data"]), None if math.isnan(noise) else noise, meta)
    except ValueError as exc:
        raise RfsdfError(f"{path}: {exc}") from None


def write_image(path, image: Image) -> Path:
    """Write a matched-filter image atomically."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        fh.attrs.update(format=_IMAGE, format_version=FORMAT_VERSION)
        fh["lower_m"], fh["upper_m"] = np.asarray(image.grid.lower_m), np.asarray(image.grid.upper_m)
        fh.create_dataset("per_view", data=image.per_view.numpy(), compression="gzip", compression_opts=1)
        fh.create_dataset("column_norms_sq", data=image.column_norms_sq.numpy(), compression="gzip", compression_opts=1)
    return Path(path)


def read_image(path) -> Image:
    """Read an image file written by :func:`write_image`."""
    with _open(path, _IMAGE) as fh:
        lower, upper = _read(fh, "lower_m", path), _read(fh, "upper_m", path)
        per_view, norms = _read(fh, "per_view", path), _read(fh, "column_norms_sq", path)
    if per_view.ndim != 4 or per_view.shape != norms.shape:
        raise RfsdfError(f"{path}: per_view: expected (V, nx, ny, nz) matching column_norms_sq, got {per_view.shape}")
    return Image(Grid(tuple(lower), tuple(upper), per_view.shape[1:]), torch.from_numpy(per_view), torch.from_numpy(norms))


def import_fmcw(path, *, conjugate: bool = False) -> Measurements:
    """Read a real FMCW capture (HDF5, layout in docs/reference/formats.md) as Measurements.

    Datasets: tx_m (M, 3), rx_m (M, 3) [m] per frame, adc (M, N) complex, optional
    boresight (M, 3); attributes start_frequency_hz, slope_hz_per_s, sample_rate_hz.
    ADC sample n of frame m is the measurement at f_start + slope n / f_s; each frame
    becomes a view with one Tx and one Rx. ``conjugate`` flips the IF phase convention
    (radars whose dechirped IF is exp(+j 2 pi f tau), e.g. TI mmWave, need it).
    """
    path = Path(path)
    with _open_hdf5(path) as fh:
        tx, rx, adc = (np.asarray(_read(fh, n, path)) for n in ("tx_m", "rx_m", "adc"))
        bore = np.asarray(_read(fh, "boresight", path)) if "boresight" in fh else None
        try:
            chirp = {k: float(fh.attrs[k]) for k in ("start_frequency_hz", "slope_hz_per_s", "sample_rate_hz")}
        except KeyError as exc:
            raise RfsdfError(f"{path}: attribute {exc.args[0]} missing") from None
    m = len(adc)
    if adc.ndim != 2 or tx.shape != (m, 3) or rx.shape != (m, 3):
        raise RfsdfError(f"{path}: adc must be (M, N) with tx_m, rx_m (M, 3); got {adc.shape}, {tx.shape}, {rx.shape}")
    if not np.iscomplexobj(adc):
        raise RfsdfError(f"{path}: adc: must be complex (I/Q) samples")
    try:
        freqs = fmcw_frequencies(chirp["start_frequency_hz"], chirp["slope_hz_per_s"], chirp["sample_rate_hz"], adc.shape[1])
        bore = bore if bore is not None else np.tile([0.0, 0.0, 1.0], (m, 1))
        acq = Acquisition(torch.from_numpy(tx.reshape(m, 1, 3)).double(), torch.from_numpy(rx.reshape(m, 1, 3)).double(),
                          torch.from_numpy(freqs), torch.from_numpy(bore).double(), 0.0, True)
        data = torch.from_numpy(np.conj(adc) if conjugate else adc).reshape(m, 1, 1, -1)
        return Measurements(acq, data, None, {"source": str(path)})
    except ValueError as exc:
        raise RfsdfError(f"{path}: {exc}") from None


def parse_bounds(text: str, source: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """'XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX' [m] -> (lower, upper); RfsdfError naming ``source``."""
    try:
        values = [float(v) for v in str(text).split(",")]
    except ValueError:
        raise RfsdfError(f"{source}: bounds must be six numbers XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [m], got {text!r}") from None
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise RfsdfError(f"{source}: bounds must be six finite numbers XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [m], got {text!r}")
    lower, upper = tuple(values[:3]), tuple(values[3:])
    if not all(lo < hi for lo, hi in zip(lower, upper)):
        raise RfsdfError(f"{source}: bounds need XMIN < XMAX, YMIN < YMAX and ZMIN < ZMAX, got {text!r}")
    return lower, upper
