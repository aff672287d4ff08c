"""Coherent imaging of a planar scan: FFT convolution (rfsdf.radar.scan_imaging) against the
exact operator's adjoint (back-projection over every position, SensingOperator.adjoint) on
the same voxels and data, in one run: seconds of each, their ratio and the relative error.

The set-up is GeRaF's at a reduced size: an IWR1443 (one Tx, four Rx 5 mm + (3 - k) lambda/2
from it) on a raster at lambda/4 steps, 0.2 m in front of three point targets, the first
--frequencies ADC samples of a 77 GHz chirp, the image on the raster's lattice over
--depths depths 0.17-0.23 m. The exact adjoint holds every position's distance to every
voxel: at 48 positions a side, 64 frequencies and 16 depths it ran out of 24 GiB.

Usage: python benchmarks/scan_imaging.py [--positions 32] [--frequencies 32] [--depths 8]
       [--device cpu|cuda] [--out benchmarks/results/scan-imaging.json]
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--positions", type=int, default=32, help="raster positions per edge")
    parser.add_argument("--frequencies", type=int, default=32)
    parser.add_argument("--depths", type=int, default=8)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/scan-imaging.json"))
    args = parser.parse_args()
    device = resolve_device(args.device, "--device")
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

    clock = time.perf_counter()
    fft = scan_image(scan, data.reshape(n, n, len(rx[0]), -1), (0, 0), (n, n), depths, device=device)
    fft_s = time.perf_counter() - clock
    clock = time.perf_counter()
    exact = operator.adjoint(data.to(device), torch.from_numpy(voxels.reshape(-1, 3)).to(device)).cpu()
    exact_s = time.perf_counter() - clock
    exact = exact.reshape(fft.shape)
    result = {"device": str(device), "threads": torch.get_num_threads(), "positions": n * n,
              "pairs": len(rx[0]), "frequencies": len(frequencies), "voxels": int(voxels[..., 0].size),
              "exact_adjoint_s": exact_s, "fft_convolution_s": fft_s, "speedup": exact_s / fft_s,
              "relative_error": float((fft - exact).norm() / exact.norm())}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
