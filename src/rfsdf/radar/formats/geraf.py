"""GeRaF's processed captures: a folder of views, one turntable angle each.

Each view folder holds ``tpos.npy`` and ``rpos.npy`` (M, 3) [m], the Tx and the Rx of each
of its M rows (a scan position and one of the board's Rx); ``adcr.npy`` and ``adci.npy``
(M, K), the real and imaginary ADC samples of each row; and ``rotation.npy``, the
turntable's rotation R (a 3 x 3 matrix, or an angle [rad] about +z). The positions are the
radar's, fixed in the room while the object turns, so in the object's frame a position p
lies at R^T p: that is where the views are placed, with the boresight.

Rows that share their Tx (consecutive rows, the board's Rx at one position) form a frame,
and each frame becomes a view, as ``rfsdf import`` makes a DCA1000 capture's frames. The
frequencies come from the chirp config (sample n at f0 + S (t_adc + n / f_s)). GeRaF
back-projects with exp(+j 2 pi f tau), tau = (|tx - v| + |rx - v| + 0.15 m) / c: its samples
already follow rfsdf's model exp(-j 2 pi f tau) with TI's fixed 0.15 m added, which the
reader undoes (``range_delay_m``); ``conjugate`` flips the sign where a capture needs it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ...atomic import atomic_path
from ...errors import RfsdfError
from ...geometry.transforms import rotation_matrix
from ...limits import require_memory
from ..acquisition import Acquisition, Measurements
from .ti_capture import delay_phase

__all__ = ["GERAF_RANGE_DELAY_M", "is_geraf", "read_geraf", "write_geraf"]

GERAF_RANGE_DELAY_M = 0.15  # TI's fixed internal delay, as GeRaF's back-projection adds it
_ARRAYS = ("tpos", "rpos", "adcr", "adci", "rotation")


def _view_folders(folder: Path) -> list[Path]:
    if (folder / "tpos.npy").is_file():
        return [folder]
    return sorted(p for p in folder.iterdir() if (p / "tpos.npy").is_file()) if folder.is_dir() else []


def is_geraf(path) -> bool:
    """Whether ``path`` is a GeRaF view folder or a folder of them."""
    return bool(_view_folders(Path(path)))


def _rotation(value: np.ndarray, where: str) -> np.ndarray:
    """(3, 3) from a rotation matrix or an angle [rad] about +z."""
    if value.size == 1:
        return rotation_matrix((0.0, 0.0, 1.0), float(value)).numpy()
    if value.shape != (3, 3) or not np.allclose(value @ value.T, np.eye(3), atol=1e-6):
        raise RfsdfError(f"{where}: expected a 3 x 3 rotation matrix or an angle [rad], got shape {value.shape}")
    return value


def _rows(view: Path) -> int:
    """M, the rows of a view, from its tpos.npy's header (without reading the samples)."""
    try:
        return len(np.load(view / "tpos.npy", mmap_mode="r", allow_pickle=False))
    except (OSError, ValueError, TypeError) as exc:
        raise RfsdfError(f"{view / 'tpos.npy'}: cannot read as a numeric .npy ({exc})") from None


def _load(view: Path) -> dict[str, np.ndarray]:
    arrays = {}
    for name in _ARRAYS:
        path = view / f"{name}.npy"
        try:
            arrays[name] = np.asarray(np.load(path, allow_pickle=False), dtype=float)
        except (OSError, ValueError) as exc:
            raise RfsdfError(f"{path}: cannot read as a numeric .npy ({exc})") from None
        if not np.isfinite(arrays[name]).all():
            raise RfsdfError(f"{path}: contains NaN or Inf")
    return arrays


def _frames(view: Path, arrays: dict[str, np.ndarray], samples: int):
    """Tx (F, 1, 3), Rx (F, R, 3) and samples (F, 1, R, K) of one view's rows."""
    tx, rx = arrays["tpos"], arrays["rpos"]
    rows = len(tx)
    if tx.shape != (rows, 3) or rx.shape != (rows, 3) or rows == 0:
        raise RfsdfError(f"{view}: tpos.npy and rpos.npy must both be (M, 3), got {tx.shape} and {rx.shape}")
    if arrays["adcr"].shape != (rows, samples) or arrays["adci"].shape != (rows, samples):
        raise RfsdfError(f"{view}: adcr.npy and adci.npy must be (M, K) = ({rows}, {samples}) "
                         f"(K from the config), got {arrays['adcr'].shape} and {arrays['adci'].shape}")
    adc = arrays["adcr"] + 1j * arrays["adci"]
    starts = np.flatnonzero(np.r_[True, np.any(tx[1:] != tx[:-1], axis=1)])
    per_frame = np.diff(np.r_[starts, rows])
    if (per_frame != per_frame[0]).any():
        raise RfsdfError(f"{view}: tpos.npy: frames (rows sharing a Tx) hold {per_frame.min()} to "
                         f"{per_frame.max()} rows; expected the same number of Rx at every position")
    r = int(per_frame[0])
    frames = rows // r
    return tx[starts][:, None], rx.reshape(frames, r, 3), adc.reshape(frames, 1, r, samples)


def read_geraf(folder, frequencies_hz: np.ndarray, *, boresight=(0.0, 0.0, 1.0),
               range_delay_m: float = GERAF_RANGE_DELAY_M, conjugate: bool = False) -> Measurements:
    """Measurements of a GeRaF capture ``folder`` (a view folder, or a folder of them) sampled at
    ``frequencies_hz`` (K,), the radar facing ``boresight`` in the turntable's rest frame,
    each view folder's frames one view (``Acquisition.scans``), as GeRaF images them; one
    error line naming the file for a missing array, a wrong shape, a NaN."""
    folder = Path(folder)
    views = _view_folders(folder)
    if not views:
        raise RfsdfError(f"{folder}: no GeRaF view (a folder holding tpos.npy, rpos.npy, adcr.npy, adci.npy, "
                         "rotation.npy)")
    f = np.asarray(frequencies_hz, float)
    bore = np.asarray(boresight, float) / np.linalg.norm(boresight)
    rows = sum(_rows(view) for view in views)
    require_memory(4 * 16 * rows * len(f), f"{folder}: the capture ({len(views)} views, {rows} rows x {len(f)} samples)")
    parts = []
    for view in views:
        arrays = _load(view)
        tx, rx, adc = _frames(view, arrays, len(f))
        turn = _rotation(arrays["rotation"], str(view / "rotation.npy")).T
        parts.append((tx @ turn.T, rx @ turn.T, np.tile(turn @ bore, (len(tx), 1)), adc))
    tx, rx, bores, adc = (np.concatenate(p) for p in zip(*parts))
    scans = np.repeat(np.arange(len(parts)), [len(part[0]) for part in parts])
    acquisition = Acquisition(torch.from_numpy(tx), torch.from_numpy(rx), torch.from_numpy(f),
                              torch.from_numpy(bores), 0.0, True, torch.from_numpy(scans))
    data = torch.from_numpy(np.conj(adc) if conjugate else adc).to(torch.complex128)
    data = data * delay_phase(acquisition.frequencies_hz, range_delay_m).conj()
    return Measurements(acquisition, data, None, {"source": str(folder), "format": "geraf"})


def write_geraf(folder, measurements: Measurements, rotations: np.ndarray, *,
                range_delay_m: float = GERAF_RANGE_DELAY_M) -> list[Path]:
    """Write ``measurements`` (frames of one Tx each, in the object's frame) as GeRaF view folders
    ``view_000``, ... under ``folder``: one a scan (``Acquisition.scans``, in order), or the
    frames split evenly, over the turntable rotations ``rotations`` (A, 3, 3), the positions
    turned into the radar's frame (R p) and the fixed delay added; the inverse of
    :func:`read_geraf`."""
    acquisition = measurements.acquisition
    v, t, r, k = acquisition.shape
    rotations = np.asarray(rotations, float)
    if t != 1 or v % len(rotations):
        raise ValueError(f"need frames of one Tx, as many for each of the {len(rotations)} rotations; got {v} x {t} Tx")
    scans = acquisition.scans
    if scans is not None and not torch.equal(scans, torch.arange(len(rotations)).repeat_interleave(v // len(rotations))):
        raise ValueError(f"need the {len(rotations)} rotations' scans in order, as many frames each")
    delay = delay_phase(acquisition.frequencies_hz, range_delay_m)
    adc = (measurements.data.to(torch.complex128) * delay).numpy().reshape(len(rotations), -1, k)
    tx = np.repeat(acquisition.tx_m.numpy(), r, axis=1).reshape(len(rotations), -1, 3)
    rx = acquisition.rx_m.numpy().reshape(len(rotations), -1, 3)
    written = []
    for a, turn in enumerate(rotations):
        view = Path(folder) / f"view_{a:03d}"
        view.mkdir(parents=True, exist_ok=True)
        for name, value in zip(_ARRAYS, (tx[a] @ turn.T, rx[a] @ turn.T, adc[a].real, adc[a].imag, turn)):
            with atomic_path(view / f"{name}.npy") as tmp, open(tmp, "wb") as fh:
                np.save(fh, value)
        written.append(view)
    return written
