"""Reconstruction quality and wall time of the default `rfsdf demo` (scene `objects`, radar
`near-77g`, 6 mm MF voxels): the GeRaF fit with one renderer, and the MF-threshold baseline
at its best threshold, both scored against the true surfaces.

Usage: python benchmarks/quality.py [--renderer physics|local] [--out benchmarks/results/quality-RENDERER.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from pathlib import Path

from rfsdf.demo import DemoSettings, metrics_table, run_demo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--renderer", choices=("physics", "local"), default="physics")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(f"benchmarks/results/quality-{args.renderer}.json")

    settings = dataclasses.replace(DemoSettings(), recon={"render": {"renderer": args.renderer}})
    with tempfile.TemporaryDirectory() as folder:
        result = run_demo(folder, settings, progress=False)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(metrics_table(result))
    print(json.dumps(result["timings_s"]))


if __name__ == "__main__":
    main()
