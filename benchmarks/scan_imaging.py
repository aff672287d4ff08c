"""Coherent imaging of a planar scan: FFT convolution (rfsdf.radar.scan_imaging) against the
exact operator's adjoint (back-projection over every position, SensingOperator.adjoint) on
the same voxels and data, on each of --devices in one run: seconds of each, their ratio, the
relative error, and each device's time over the first's.

The set-up is GeRaF's at a reduced size: an IWR1443 (one Tx, four Rx 5 mm + (3 - k) lambda/2
from it) on a raster at lambda/4 steps, 0.2 m in front of three point targets, the first
--frequencies ADC samples of a 77 GHz chirp, the image on the raster's lattice over
--depths depths 0.17-0.23 m. The exact adjoint holds every position's distance to every
voxel: at 48 positions a side, 64 frequencies and 16 depths it ran out of 24 GiB; --no-exact
times the FFT alone (GeRaF's own scans: 142 x 512 positions, 512 samples, a 1 mm grid).

Usage: python benchmarks/scan_imaging.py [--positions 32] [--frequencies 32] [--depths 8]
       [--devices cpu,cuda] [--no-exact] [--out benchmarks/results/scan-imaging.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from rfsdf.device import resolve_device
from rfsdf.jsonio import to_json
from rfsdf.radar.acquisition import SPEED_OF_LIGHT, Acquisition
from rfsdf.radar.boards import board, board_positions
from rfsdf.radar.operator import SensingOperator
from rfsdf.radar.scan_imaging import PlanarScan, scan_image, scan_voxels


def _seconds(function, device: torch.device):
    """(result, wall seconds) of ``function()``, synchronised on ``device``."""
    clock = time.perf_counter()
    result = function()
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    return result, time.perf_counter() - clock


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--positions", type=int, default=32, help="raster positions per edge")
    parser.add_argument("--frequencies", type=int, default=32)
    parser.add_argument("--depths", type=int, default=8)
    parser.add_argument("--devices", default="cpu", help="comma-separated: cpu, cuda")
    parser.add_argument("--no-exact", action="store_true", help="time the FFT convolution alone")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-imaging.json"))
    args = parser.parse_args()
    devices = [resolve_device(name, "--devices") for name in args.devices.split(",")]
    n, step = args.positions, SPEED_OF_LIGHT / 79e9 / 4
    frequencies = 77.4e9 + 70e12 * np.arange(args.frequencies) / 10e6
    boresight, rx_axis = np.array([0, 0, 1.0]), np.array([0, -1.0, 0])
    tx, rx = board_positions(board("iwr1443"), np.zeros((1, 3)), boresight, rx_axis)
    origin = np.array([-(n - 1) * step / 2, -(n - 1) * step / 2, -0.2])
    scan = PlanarScan(origin, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), (step, step), (n, n),
                      np.repeat(tx[0], len(rx[0]), 0), rx[0], frequencies)
    positions = scan.positions_m().reshape(-1, 3)
    acquisition = Acquisition(torch.from_numpy(positions[:, None] + tx[0][None]),
                              torch.from_numpy(positions[:, None] + rx[0][None]), torch.from_numpy(frequencies),
                              torch.from_numpy(boresight).repeat(len(positions), 1), 0.0, True)
    operator = SensingOperator(acquisition)
    targets = torch.tensor([[0.0, 0.0, 0.0], [0.01, -0.008, 0.015], [-0.012, 0.006, -0.02]], dtype=torch.float64)
    data = operator.forward(targets, torch.tensor([1.0, 0.6j, -0.4], dtype=torch.complex128))
    depths = np.linspace(0.17, 0.23, args.depths)
    voxels = scan_voxels(scan, (0, 0), (n, n), depths)

    result = {"threads": torch.get_num_threads(), "positions": n * n, "pairs": len(rx[0]),
              "frequencies": len(frequencies), "voxels": int(voxels[..., 0].size)}
    for device in devices:
        image = lambda: scan_image(scan, data.reshape(n, n, len(rx[0]), -1), (0, 0), (n, n), depths,  # noqa: E731
                                   device=device)
        image()  # warms up (cuFFT plans, kernels)
        fft, fft_s = _seconds(image, device)
        row = {"fft_convolution_s": fft_s}
        if not args.no_exact:
            exact, exact_s = _seconds(lambda: operator.adjoint(data.to(device), torch.from_numpy(
                voxels.reshape(-1, 3)).to(device)).cpu(), device)
            row.update(exact_adjoint_s=exact_s, speedup=exact_s / fft_s,
                       relative_error=float((fft - exact.reshape(fft.shape)).norm() / exact.norm()))
        if device.type == "cuda":
            row["gpu"] = torch.cuda.get_device_name(device)
        result[str(device)] = row
        print(device, to_json(row), flush=True)
    first = str(devices[0])
    for device in devices[1:]:
        result[f"{device} over {first}"] = {key: result[first][key] / result[str(device)][key]
                                            for key in ("fft_convolution_s", "exact_adjoint_s") if key in result[first]}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
