"""Radar boards as capture presets: antenna layout, LVDS lanes, IF phase sign, fixed range delay.

Antenna offsets are in the board's own frame relative to Tx0 (the position a pose file
gives): ``u`` along the Rx line, pointing from Tx0 towards the Rx (what ``--rx-axis``
orients), and ``w = boresight x u``. A board's fixed range delay is the extra path [m]
its internal delay adds to every return (TI's 0.15 m, as GeRaF's back-projection
subtracts for the IWR1443; assumed for the other TI chips until a corner reflector says
otherwise: ``--range-delay``), and ``conjugate`` says that its dechirped IF is exp(+j 2 pi f tau), the
complex conjugate of rfsdf's model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RfsdfError
from .acquisition import SPEED_OF_LIGHT

__all__ = ["Board", "BOARDS", "board", "board_positions", "board_layout"]


@dataclass(frozen=True)
class Board:
    name: str
    lanes: int  # LVDS lanes to the DCA1000
    tx_uw_m: tuple[tuple[float, float], ...]  # (T, 2) [m], Tx k in (u, w) from Tx0
    rx_uw_m: tuple[tuple[float, float], ...]  # (R, 2) [m]
    conjugate: bool
    range_delay_m: float


def _iwr1443() -> Board:
    """TI IWR1443BOOST (as UT Dallas' getAntennaLocations, 79 GHz design wavelength): Rx k at
    5 mm + (3 - k) lambda/2 from Tx0 along u; Tx1 lambda back along u and lambda/2 across,
    Tx2 2 lambda back."""
    half = SPEED_OF_LIGHT / 79e9 / 2
    return Board("iwr1443", lanes=4, tx_uw_m=((0.0, 0.0), (-2 * half, -half), (-4 * half, 0.0)),
                 rx_uw_m=tuple((0.005 + (3 - k) * half, 0.0) for k in range(4)), conjugate=True, range_delay_m=0.15)


def _three_tx_board(name: str, design_hz: float) -> Board:
    """The xWR18xx/68xx booster-pack layout (TI's AWR1843BOOST and IWR6843ISK user's guides):
    four Rx lambda/2 apart; Tx0 and Tx2 2 lambda apart along the Rx line, so that their
    virtual arrays continue one another (8 x lambda/2 in azimuth); Tx1 between them, lambda
    from Tx0 and lambda/2 across (the elevated row). The Tx-to-Rx gap is not published; it is
    taken as the IWR1443BOOST's 5 mm (at 0.2 m a centimetre of it changes a path by 0.25 mm)."""
    half = SPEED_OF_LIGHT / design_hz / 2
    return Board(name, lanes=2, tx_uw_m=((0.0, 0.0), (-2 * half, half), (-4 * half, 0.0)),
                 rx_uw_m=tuple((0.005 + (3 - k) * half, 0.0) for k in range(4)), conjugate=True, range_delay_m=0.15)


BOARDS = {b.name: b for b in (_iwr1443(), _three_tx_board("awr1843", 77e9 + 2e9),
                               _three_tx_board("iwr6843", 60e9 + 2e9))}


def board(name: str, source: str = "--chip") -> Board:
    """The board called ``name``; unknown names are refused in one line."""
    try:
        return BOARDS[name.lower()]
    except KeyError:
        raise RfsdfError(f"{source}: unknown chip {name!r}; known: {', '.join(BOARDS)}") from None


def _enabled(mask: int, count: int, field: str, name: str) -> list[int]:
    """Indices of the bits of ``mask``, which must name some of the ``count`` antennas."""
    if mask < 1 or mask >> count:
        raise RfsdfError(f"{field}: {hex(mask)} enables antennas the {name} lacks (it has {count})")
    return [k for k in range(count) if mask >> k & 1]


def board_positions(board: Board, tx0_m: np.ndarray, boresight: np.ndarray, rx_axis: np.ndarray,
                    tx_mask: int = 1, rx_mask: int = 0xF) -> tuple[np.ndarray, np.ndarray]:
    """Tx (M, T, 3) and Rx (M, R, 3) [m] of the board at Tx0 positions ``tx0_m`` (M, 3), with
    the Tx and Rx that ``tx_mask`` and ``rx_mask`` enable (bit k: antenna k; Tx in chirp
    order). ``rx_axis`` (3,) is u; only its part across ``boresight`` (3,) counts."""
    b = np.asarray(boresight, float) / np.linalg.norm(boresight)
    u = np.asarray(rx_axis, float) - np.dot(rx_axis, b) * b
    if np.linalg.norm(u) < 1e-9:
        raise RfsdfError("--rx-axis: must not be parallel to --boresight")
    u /= np.linalg.norm(u)
    w = np.cross(b, u)
    tx = [board.tx_uw_m[k] for k in _enabled(tx_mask, len(board.tx_uw_m), "txChannelEn", board.name)]
    rx = [board.rx_uw_m[k] for k in _enabled(rx_mask, len(board.rx_uw_m), "rxChannelEn", board.name)]
    to_scene = lambda uw: np.asarray(uw)[:, :1] * u + np.asarray(uw)[:, 1:] * w  # noqa: E731
    tx0 = np.asarray(tx0_m, float)[:, None]
    return tx0 + to_scene(tx), tx0 + to_scene(rx)


def board_layout(name: str, tx_mask: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Tx (T, 3) and Rx (R, 3) [m] of board ``name`` in the radar frame (array in x-y,
    boresight +z): Tx0 at the origin, the Rx along +x (u), its Tx that ``tx_mask`` enables."""
    tx, rx = board_positions(board(name, "array.board"), np.zeros((1, 3)), np.array([0.0, 0.0, 1.0]),
                             np.array([1.0, 0.0, 0.0]), tx_mask)
    return tx[0], rx[0]
