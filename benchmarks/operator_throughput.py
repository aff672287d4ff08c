"""Sensing-operator throughput (voxel-measurement pairs per second), forward and adjoint,
against a naive NumPy dense-row reference on the same problem in the same run.

Usage: python benchmarks/operator_throughput.py [--points N] [--out benchmarks/results/operator.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from rfsdf.jsonio import to_json
from rfsdf.radar import SensingOperator, load_radar
from rfsdf.radar.dense import dense_row


def _rate(pairs: int, func, repeats: int = 3) -> float:
    func()
    start = time.perf_counter()
    for _ in range(repeats):
        func()
    return pairs * repeats / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--points", type=int, default=8192)
    parser.add_argument("--naive-rows", type=int, default=400, help="rows of A the naive reference computes")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/operator.json"))
    args = parser.parse_args()

    acq = load_radar("near-77g").acquisition().view(0)  # one view: 48 Tx x 48 Rx x 16 frequencies
    op = SensingOperator(acq)
    g = torch.Generator().manual_seed(0)
    points = (torch.rand(args.points, 3, generator=g) - 0.5) * 0.3
    c = torch.randn(args.points, dtype=torch.complex64, generator=g)
    y = torch.randn(*acq.shape, dtype=torch.complex64, generator=g)
    pairs = acq.num_measurements * args.points
    forward = _rate(pairs, lambda: op.forward(points, c))
    adjoint = _rate(pairs, lambda: op.adjoint(y, points))

    # Naive reference: build each row of A from the formula and take its dot product with c.
    pts = points.double().numpy()
    _, t_n, r_n, k_n = acq.shape
    rows = [(0, i % t_n, (i // t_n) % r_n, (i // (t_n * r_n)) % k_n) for i in range(args.naive_rows)]
    naive = _rate(len(rows) * args.points, lambda: [dense_row(acq, pts, *m) @ c.numpy() for m in rows], repeats=1)

    result = {
        "problem": {"measurements": acq.num_measurements, "points": args.points, "radar": "near-77g (one view)"},
        "threads": torch.get_num_threads(),
        "forward_pairs_per_s": forward, "adjoint_pairs_per_s": adjoint, "naive_pairs_per_s": naive,
        "forward_speedup_vs_naive": forward / naive, "adjoint_speedup_vs_naive": adjoint / naive,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
