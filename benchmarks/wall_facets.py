"""A large wall as facets against points: accuracy against the image source, and time.

A 2 x 2 m metal wall (10 cm thick) 1 m in front of a monostatic 57-64 GHz radar, at normal
incidence, whose closed-form return is the image source's |Gamma| / 2d at every frequency.
Simulated three ways in one run, on one machine:

- facets: the simulator's plan when lambda/3 points would exceed ``max_samples``
  (``rfsdf.radar.surface_plan``);
- points, as many over the face in view as there were facets (what a sample cap did before);
- points lambda/3 apart, uncapped (the converged point sum, 4 million samples).

For each: the samples, the wall time [s] and the largest relative error of |y| against the
image source over the frequencies. The tests (tests/test_rooms.py) assert the first two;
this adds the third and the times. Also timed: the facet integrals of 20,000 facets at 400
frequencies, compiled (what the simulator runs) against the torch form (the reference).

Usage: python benchmarks/wall_facets.py [--out benchmarks/results/wall_facets.json]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_rooms import _monostatic, _plate  # noqa: E402 - the tests' own wall and radar

from rfsdf.jsonio import to_json  # noqa: E402
from rfsdf.radar import simulate  # noqa: E402
from rfsdf.radar.acquisition import SPEED_OF_LIGHT  # noqa: E402
from rfsdf.radar.facets import facet_phase_integrals, triangle_phase_integral  # noqa: E402

DISTANCE_M = 1.0
FREQUENCIES_HZ = np.linspace(57e9, 64e9, 16)


def _run(label: str, scene, **kwargs) -> dict:
    clock = time.perf_counter()
    data = simulate(scene, _monostatic(FREQUENCIES_HZ), **kwargs)
    seconds = time.perf_counter() - clock
    error = float(np.abs(np.abs(data.data[0, 0, 0].numpy()) * 2 * DISTANCE_M - 1).max())
    row = {"samples": int(data.metadata["surface_sampling"].split()[0]), "seconds": round(seconds, 2),
           "max_relative_error": round(error, 4), "sampling": data.metadata["surface_sampling"]}
    print(f"{label:<22} {row['samples']:>9,} samples {seconds:7.1f} s   error {error:.4f}", flush=True)
    return row


def _integrals() -> dict:
    """Seconds of the facet integrals, compiled and in torch (float32, as the simulator ran
    them before), best of three, on the same facets."""
    import torch

    extra = torch.randn(20_000, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64) * 0.005
    k = torch.linspace(1190.0, 1340.0, 400, dtype=torch.float64)
    facet_phase_integrals(extra[:10], k[:2])  # compiled before timing

    def best(run) -> float:
        times = []
        for _ in range(3):
            clock = time.perf_counter()
            run()
            times.append(time.perf_counter() - clock)
        return min(times)

    compiled = best(lambda: facet_phase_integrals(extra, k))
    reference = best(lambda: triangle_phase_integral((k[:, None, None] * extra[None]).float()))
    row = {"facets": 20_000, "frequencies": 400, "compiled_s": round(compiled, 4), "torch_s": round(reference, 4),
           "speedup": round(reference / compiled, 1), "ns_per_facet_frequency": round(compiled / 8e6 * 1e9, 2)}
    print(f"facet integrals: compiled {compiled:.3f} s, torch {reference:.3f} s ({row['speedup']} x)", flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "wall_facets.json")
    args = parser.parse_args()
    scene = _plate((1.0, 1.0, 0.05), (0.0, 0.0, DISTANCE_M + 0.05))
    facets = _run("facets", scene, max_samples=300_000)
    rows = {"facets": facets,
            "points_as_many": _run("points, as many", scene, spacing_m=math.sqrt(4.0 / facets["samples"]),
                                   max_samples=10**8),
            "points_lambda_3": _run("points, lambda/3", scene, spacing_m=SPEED_OF_LIGHT / FREQUENCIES_HZ.mean() / 3,
                                    max_samples=10**8)}
    result = {"wall_m": [2.0, 2.0], "distance_m": DISTANCE_M, "frequencies_hz": [57e9, 64e9, 16], "runs": rows,
              "facet_integrals": _integrals(),
              "speedup_over_lambda_3_points": round(rows["points_lambda_3"]["seconds"] / facets["seconds"], 2)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
