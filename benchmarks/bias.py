"""Where a demo's surfaces sit relative to the truth, object by object: the median signed
distance of each method's surface to the object it is nearest (+ bloated outward, - shrunk),
with precision and recall, for finished demo folders (e.g. the default radar's and the
dense one's). Reads the meshes and settings the demo wrote; reconstructs nothing.

Usage: python benchmarks/bias.py DEMO_DIR [DEMO_DIR ...] [--out benchmarks/results/bias.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import trimesh

from rfsdf.jsonio import to_json
from rfsdf.metrics import evaluate_scene
from rfsdf.scene import load_scene

METHODS = ("neural", "neural-warm-start", "clean-detection")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/bias.json"))
    args = parser.parse_args()
    result = {}
    for folder in args.folders:
        settings = json.loads((folder / "demo-settings.json").read_text())
        scene = load_scene(settings["scene"])
        key = f"{Path(settings['scene']).stem}/{Path(settings['radar']).stem}"
        result[key] = {}
        for method in METHODS:
            metrics = evaluate_scene(trimesh.load(folder / f"{method}.ply", force="mesh"), scene, samples=50_000)
            result[key][method] = {name: {"bias_mm": m.bias_mm, "precision": m.precision, "recall": m.recall}
                                   for name, m in metrics.objects.items()}
            print(key, method, to_json({n: round(v["bias_mm"] or 0, 1) for n, v in result[key][method].items()},
                                       indent=None), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
