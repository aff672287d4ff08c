"""Real captures in: rfsdf import (rfsdf's HDF5, TI DCA1000, GeRaF, MITO, UT Dallas) and import-fmcw."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import click

from .app import main, one_line_errors, refuse_overwriting_inputs

FORMATS = ("auto", "hdf5", "dca1000", "geraf", "mito", "utd-mat")
_SUFFIXES = {".h5": "hdf5", ".hdf5": "hdf5", ".bin": "dca1000", ".json": "dca1000"}  # .json: a setup.json


def _vector(text: str, option: str) -> tuple[float, float, float]:
    """'X,Y,Z' -> a finite, non-zero 3-vector, or one error line naming ``option``."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
        raise ValueError(f"{option}: expected three finite numbers X,Y,Z, not all zero; got {text!r}")
    return values


def _capture_format(capture: Path, name: str) -> str:
    if name != "auto":
        return name
    if capture.is_dir():
        from ..radar.formats.geraf import is_geraf
        from ..radar.formats.mito import is_mito
        from ..radar.formats.utd_mat import is_utd

        if is_geraf(capture):
            return "geraf"
        if is_mito(capture):
            return "mito"
        if is_utd(capture):
            return "utd-mat"
        raise ValueError(f"{capture}: a folder, but not GeRaF's (view folders holding tpos.npy), MITO's "
                         "(radar_data/adc_data*.bin) or UT Dallas' (rawData.mat); pass --format")
    try:
        return _SUFFIXES[capture.suffix.lower()]
    except KeyError:
        raise ValueError(f"{capture}: cannot tell the format from the name; pass --format "
                         f"({', '.join(FORMATS[1:])})") from None


def _ti_inputs(capture: Path | None, configs: tuple[Path, ...]):
    """The .bin files, chirp, lanes (None: not given) and recorded device of a TI capture.
    ``capture`` is a .bin, mmWave Studio's *.setup.json naming its .bin files and config, or
    None (only the chirp is wanted); each --config an *.mmwave.json, a *.setup.json or a
    DCA1000 CLI cf.json. An explicit *.mmwave.json wins over a setup's ``configUsed``."""
    from ..errors import RfsdfError
    from ..radar.formats.dca1000 import read_cf_json
    from ..radar.formats.mmwave_studio import read_mmwave_json, read_setup_json

    setup_capture = capture is not None and capture.suffix.lower() == ".json"
    bins, chirp, lanes, setup = None if setup_capture or capture is None else (capture,), None, None, None
    for path in ((capture,) if setup_capture else ()) + configs:
        try:
            keys = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RfsdfError(f"{path}: cannot read as JSON ({getattr(exc, 'strerror', None) or exc})") from None
        if isinstance(keys, dict) and "mmWaveDevices" in keys:
            chirp = read_mmwave_json(path)
        elif isinstance(keys, dict) and ("configUsed" in keys or "capturedFiles" in keys):
            setup = read_setup_json(path)
            bins = bins or setup.captures
        elif isinstance(keys, dict) and "DCA1000Config" in keys:
            lanes = read_cf_json(path)
        else:
            raise RfsdfError(f"{path}: neither an mmWave Studio *.mmwave.json (mmWaveDevices) or *.setup.json "
                             "(configUsed) nor a DCA1000 cf.json (DCA1000Config)")
    if chirp is None and setup is not None:
        chirp = read_mmwave_json(setup.config)
    if chirp is None:
        raise RfsdfError("--config: a TI capture needs its mmWave Studio *.mmwave.json (or *.setup.json)")
    return bins, chirp, lanes, setup.device if setup is not None else ""


def _frequencies(configs: tuple[Path, ...]):
    """(K,) [Hz] the samples' frequencies from --config: an rfsdf radar TOML's waveform, else the
    chirp of mmWave Studio's *.mmwave.json or *.setup.json."""
    tomls = [path for path in configs if path.suffix.lower() == ".toml"]
    if tomls:
        from ..radar import load_radar

        return load_radar(tomls[-1]).frequencies_hz
    return _ti_inputs(None, configs)[1].frequencies_hz()


@main.command("import")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Measurements file (.h5).")
@click.option("--format", "format_name", type=click.Choice(FORMATS), default="auto", show_default=True,
              help="auto: by the name (.h5 hdf5; .bin, or mmWave Studio's .setup.json, dca1000; a folder "
                   "of GeRaF views geraf; a folder holding radar_data/adc_data*.bin mito; a folder holding "
                   "rawData.mat utd-mat).")
@click.option("--config", "configs", type=click.Path(path_type=Path), multiple=True,
              help="dca1000, geraf: mmWave Studio's *.mmwave.json (or *.setup.json), and optionally the "
                   "DCA1000 CLI's cf.json (lanes); geraf: or an rfsdf radar TOML (its waveform's frequencies); "
                   "mito: MITO's params.json or an *.mmwave.json.")
@click.option("--chip", default=None, help="dca1000: the board (antenna layout, lanes, IF sign, range delay): "
              "iwr1443, awr1843, iwr6843; default: the setup.json's mmWaveDevice.")
@click.option("--poses", type=click.Path(path_type=Path), default=None,
              help="dca1000: CSV of Tx0 positions, x_m,y_m,z_m a frame or time_s,x_m,y_m,z_m interpolated at the frames.")
@click.option("--boresight", default=None,
              help="dca1000, geraf, mito: the board's boresight X,Y,Z (geraf: in the turntable's rest frame); "
                   "default 0,0,1, mito 0,0,-1 (the arm looks down).")
@click.option("--rx-axis", default="0,-1,0", show_default=True,
              help="dca1000: the direction X,Y,Z from the board's Tx0 to its Rx.")
@click.option("--range-delay", "range_delay_m", type=float, default=None,
              help="dca1000, geraf, mito, utd-mat: the fixed range delay [m] to undo (default: the chip's, 0.15 "
                   "for TI; geraf 0.15; utd-mat 0.15, or 0 with a delayOffset.mat).")
@click.option("--conjugate/--no-conjugate", default=None,
              help="Conjugate the IF (default: the chip's sign for dca1000, mito and utd-mat, none for hdf5 and "
                   "geraf).")
@click.option("--one-view", is_flag=True,
              help="The capture's frames are one view (a scan at one turntable angle), imaged and fitted coherently "
                   "(default: each frame a view; GeRaF: each view folder one view; MITO: its scan one view).")
@one_line_errors
def import_cmd(capture: Path, out: Path, format_name: str, configs: tuple[Path, ...], chip: str | None,
               poses: Path | None, boresight: str | None, rx_axis: str, range_delay_m: float | None,
               conjugate: bool | None, one_view: bool):
    """Convert a real capture into a measurements file: rfsdf's HDF5 layout; a TI DCA1000
    .bin (or mmWave Studio's setup.json) with its mmWave Studio config, board and pose file;
    GeRaF's view folders with the chirp's config; a MITO capture folder with its params.json;
    or a UT Dallas MIMO-SAR folder of .mat files (each frame a view unless --one-view, each
    GeRaF folder and each MITO scan one; layouts in docs/reference/formats.md)."""
    from ..radar import import_fmcw, write_measurements

    refuse_overwriting_inputs(out, capture, *configs, poses)
    kind = _capture_format(capture, format_name)
    if range_delay_m is not None and not math.isfinite(range_delay_m):
        raise ValueError(f"--range-delay: {range_delay_m} is not a finite length")
    facing = _vector(boresight or ("0,0,-1" if kind == "mito" else "0,0,1"), "--boresight")
    if kind == "hdf5":
        measurements = import_fmcw(capture, conjugate=bool(conjugate))
    elif kind == "utd-mat":
        from ..radar.formats.utd_mat import read_utd

        measurements = read_utd(capture, range_delay_m=range_delay_m, conjugate=conjugate)
    elif kind == "geraf":
        from ..radar.formats.geraf import GERAF_RANGE_DELAY_M, read_geraf

        measurements = read_geraf(capture, _frequencies(configs), boresight=facing,
                                  range_delay_m=GERAF_RANGE_DELAY_M if range_delay_m is None else range_delay_m,
                                  conjugate=bool(conjugate))
    elif kind == "mito":
        from ..radar.formats.mito import mito_chirp, read_mito

        if len(configs) != 1:
            raise ValueError(f"{capture}: a MITO capture needs one --config, MITO's params.json or an *.mmwave.json")
        measurements = read_mito(capture, mito_chirp(configs[0], capture), boresight=facing,
                                 range_delay_m=range_delay_m, conjugate=conjugate)
    else:
        from ..radar.boards import BOARDS, board
        from ..radar.formats.ti_capture import CaptureGeometry, import_ti_capture

        if poses is None:
            raise ValueError(f"{capture}: a DCA1000 capture needs --poses")
        bins, chirp, lanes, device = _ti_inputs(capture, configs)
        if chip is None and device not in BOARDS:
            raise ValueError(f"{capture}: a DCA1000 capture needs --chip (its setup names "
                             f"{device or 'no device'}; known: {', '.join(BOARDS)})")
        geometry = CaptureGeometry(board(chip or device), facing,
                                   _vector(rx_axis, "--rx-axis"), range_delay_m, conjugate)
        measurements = import_ti_capture(bins, chirp, geometry, poses, lanes=lanes)
    if one_view:
        import torch

        frames = measurements.acquisition.shape[0]
        measurements = dataclasses.replace(measurements, acquisition=dataclasses.replace(
            measurements.acquisition, scans=torch.zeros(frames, dtype=torch.int64)))
    write_measurements(out, measurements)
    acq = measurements.acquisition
    v, t, r, k = acq.shape
    f = acq.frequencies_hz
    views = f"{v} views" if acq.scans is None else f"{acq.num_views} view(s) of {v} frames"
    click.echo(f"{views} of {t} Tx x {r} Rx, {k} samples over {float(f[0]) / 1e9:.3f}-{float(f[-1]) / 1e9:.3f} GHz")
    click.echo(f"wrote {out}")


@main.command("import-fmcw")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True)
@click.option("--conjugate", is_flag=True, help="Flip the IF phase sign (e.g. TI mmWave captures).")
@one_line_errors
def import_fmcw_cmd(capture: Path, out: Path, conjugate: bool):
    """Convert a real FMCW capture (rfsdf's HDF5 layout: docs/reference/formats.md) into a
    measurements file; the same as ``rfsdf import --format hdf5``."""
    from ..radar import import_fmcw, write_measurements

    refuse_overwriting_inputs(out, capture)
    write_measurements(out, import_fmcw(capture, conjugate=conjugate))
    click.echo(f"wrote {out}")
