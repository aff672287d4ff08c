"""How much of each object's surface the radar observes at all (the observed-surface mask of
`rfsdf.radar.coverage`: lit, and the normal within some view's bistatic cone + 10 degrees),
per scene and radar. No reconstruction can place surface no view observes, so an object
whose observed share is below one half cannot reach the 'found' recall of 0.5 from the data
alone; only the closed volume of the warm start stands in for the rest.

Usage: python benchmarks/coverage.py [--out benchmarks/results/coverage.json]
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path

from rfsdf.jsonio import to_json
from rfsdf.metrics import evaluate_scene
from rfsdf.radar import load_radar
from rfsdf.radar.coverage import observed_mask
from rfsdf.scene import load_scene

CASES = (("objects", "near-77g"), ("objects", "dense-77g"), ("tabletop", "near-77g"),
         ("benchmarks/scenes/workshop.toml", "near-77g"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/coverage.json"))
    args = parser.parse_args()
    result = {}
    for scene_name, radar_name in CASES:
        scene, acquisition = load_scene(scene_name), load_radar(radar_name).acquisition()
        truth = scene.ground_truth_mesh()
        metrics = evaluate_scene(truth, scene, samples=50_000, observed=partial(
            observed_mask, acquisition=acquisition, occluder=scene.sdf))
        key = f"{Path(scene_name).stem}/{radar_name}"
        result[key] = {"views": int(acquisition.shape[0]), "observed_fraction": metrics.observed_fraction,
                       "objects": {name: m.observed_fraction for name, m in metrics.objects.items()}}
        print(key, to_json(result[key], indent=None))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))


if __name__ == "__main__":
    main()
