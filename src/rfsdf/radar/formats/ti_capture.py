"""A TI capture as measurements: a DCA1000 ``.bin`` (or the files it split one record into),
its mmWave Studio ``*.mmwave.json`` (and optionally the DCA1000 CLI's ``cf.json``), a board
and a pose file -> :class:`Measurements`. The LVDS lanes come from the ``cf.json``, else the
``*.mmwave.json``, else the board.

Each frame becomes a view: its chirps of one loop are its Tx (TDM MIMO; the loops of a
frame are averaged, the scene being static), the enabled Rx its Rx, ADC sample n the
measurement at f0 + S (t_adc + n / f_s). The board's IF sign and fixed range delay are
undone so the data follow rfsdf's model, y = sum c exp(-j 2 pi f (d_tx + d_rx) / c).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ...errors import RfsdfError
from ..acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from ..boards import Board, board_positions
from .dca1000 import AdcLayout, read_bin, write_bin, write_cf_json
from .mmwave_studio import ChirpConfig, write_mmwave_json, write_setup_json
from .poses import read_poses

__all__ = ["CaptureGeometry", "delay_phase", "import_ti_capture", "model_data", "recorded_counts", "write_ti_capture"]

FULL_SCALE = 30_000  # int16 counts the writer gives the largest sample


@dataclass(frozen=True)
class CaptureGeometry:
    """How the board was held: ``boresight`` and ``rx_axis`` (3,) in the scene frame, the
    ``range_delay_m`` and ``conjugate`` to undo (None: the board's)."""

    board: Board
    boresight: tuple[float, float, float] = (0.0, 0.0, 1.0)
    rx_axis: tuple[float, float, float] = (0.0, -1.0, 0.0)
    range_delay_m: float | None = None
    conjugate: bool | None = None

    @property
    def delay_m(self) -> float:
        return self.board.range_delay_m if self.range_delay_m is None else self.range_delay_m

    @property
    def flip(self) -> bool:
        return self.board.conjugate if self.conjugate is None else self.conjugate

    def acquisition(self, chirp: ChirpConfig, tx0_m: np.ndarray) -> Acquisition:
        """The acquisition of frames at Tx0 positions ``tx0_m`` (M, 3) [m]."""
        tx, rx = board_positions(self.board, tx0_m, np.asarray(self.boresight), np.asarray(self.rx_axis),
                                 chirp.tx_mask, chirp.rx_mask)
        bore = np.tile(np.asarray(self.boresight, float) / np.linalg.norm(self.boresight), (len(tx0_m), 1))
        return Acquisition(torch.from_numpy(tx), torch.from_numpy(rx), torch.from_numpy(chirp.frequencies_hz()),
                           torch.from_numpy(bore), 0.0, True)


def delay_phase(frequencies_hz: torch.Tensor, delay_m: float) -> torch.Tensor:
    """exp(-j 2 pi f d / c) (K,): a fixed extra path ``delay_m`` as a phase."""
    return torch.polar(torch.ones_like(frequencies_hz), -2 * torch.pi * frequencies_hz * delay_m / SPEED_OF_LIGHT)


def _layout(chirp: ChirpConfig, lanes: int) -> AdcLayout:
    return AdcLayout(lanes, chirp.complex, chirp.rx, chirp.samples, chirp.chirps)


def import_ti_capture(bin_paths, chirp: ChirpConfig, geometry: CaptureGeometry, poses, *,
                      lanes: int | None = None) -> Measurements:
    """Measurements of the DCA1000 capture ``bin_paths`` (one file or the parts of one record)
    recorded with ``chirp`` over ``lanes`` (None: the chirp config's, else the board's), the
    board held as ``geometry`` at the pose file ``poses``."""
    bin_paths = [bin_paths] if isinstance(bin_paths, (str, Path)) else list(bin_paths)
    if not chirp.complex:
        raise RfsdfError(f"{bin_paths[0]}: real-sampled capture (rlAdcOutCfg_t.fmt.b2AdcOutFmt 0): rfsdf's model "
                         "needs complex I/Q samples")
    try:
        layout = _layout(chirp, lanes or chirp.lanes or geometry.board.lanes)
    except ValueError as exc:
        raise RfsdfError(f"{bin_paths[0]}: {exc}") from None
    cube = read_bin(bin_paths, layout)
    frames = len(cube)
    cube = cube.reshape(frames, chirp.loops, chirp.chirps_per_loop, chirp.rx, chirp.samples).mean(1)
    acquisition = geometry.acquisition(chirp, read_poses(poses, frames, chirp.frame_period_s))
    return Measurements(acquisition, model_data(cube, acquisition, geometry), None, {"source": ", ".join(map(str, bin_paths)),
                                                  "chip": geometry.board.name, "poses": str(poses)})


def model_data(cube: np.ndarray, acquisition: Acquisition, geometry: CaptureGeometry) -> torch.Tensor:
    """(V, T, R, K) complex128: the board's samples ``cube`` with its IF sign and fixed delay
    undone, as rfsdf's model y = sum c exp(-j 2 pi f (d_tx + d_rx) / c) has them."""
    data = torch.from_numpy(np.conj(cube) if geometry.flip else cube).to(torch.complex128)
    return data * delay_phase(acquisition.frequencies_hz, geometry.delay_m).conj()


def recorded_counts(measurements: Measurements, chirp: ChirpConfig, geometry: CaptureGeometry):
    """``measurements``' data (V, T, R, K) as the board records them, the fixed delay and IF sign
    applied, in int16 counts (the largest part ``FULL_SCALE``): (cube, scale from data to counts).
    The inverse of the importers' correction; ``chirp`` must have one loop and the data's frequencies."""
    frequencies = measurements.acquisition.frequencies_hz
    if chirp.loops != 1 or not np.allclose(chirp.frequencies_hz(), frequencies.numpy(), rtol=0, atol=1.0):
        raise ValueError("chirp must have one loop and the measurements' frequencies")
    data = measurements.data.to(torch.complex128) * delay_phase(frequencies, geometry.delay_m)
    cube = (data.conj() if geometry.flip else data).resolve_conj().numpy()
    scale = FULL_SCALE / max(np.abs(cube.real).max(), np.abs(cube.imag).max(), np.finfo(float).tiny)
    return cube * scale, scale


def write_ti_capture(folder, measurements: Measurements, chirp: ChirpConfig, geometry: CaptureGeometry, *,
                     lanes: int | None = None) -> float:
    """Write ``measurements`` as the board would have captured them (the fixed delay and IF sign
    applied, int16 counts) into ``folder``: ``adc_data.bin``, ``capture.mmwave.json``,
    ``capture.setup.json`` and ``cf.json``; returns the scale from data to counts. One loop a
    frame."""
    cube, scale = recorded_counts(measurements, chirp, geometry)
    folder = Path(folder)
    lanes = lanes or geometry.board.lanes
    write_bin(folder / "adc_data.bin", cube, _layout(chirp, lanes))
    write_mmwave_json(folder / "capture.mmwave.json", chirp)
    write_setup_json(folder / "capture.setup.json", folder / "capture.mmwave.json", [folder / "adc_data.bin"],
                     geometry.board.name)
    write_cf_json(folder / "cf.json", lanes)
    return scale
