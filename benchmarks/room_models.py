"""The scene models side by side on a room: primitive, hybrid and neural (issue 31's table).

Runs ``rfsdf.model_demo.run_model_demo`` on a scene (default ``l-room`` by ``room-60g``) into
``--work/<scene>`` (the simulated data are kept there and reused) and writes the models'
scores to ``benchmarks/results/room-models-<scene>.json`` (``-joint`` appended to both with
``--hybrid-joint``). ``--model-scene`` starts the fit
from another scene's model (every length free, ``--start-offset`` off): one that lacks an
object of the data's scene, the case the hybrid's residual is for.

Usage: python benchmarks/room_models.py [--scene l-room] [--models primitive hybrid neural]
       [--model-scene S] [--start-offset 0.15] [--seed 0] [--max-samples 3000000]
       [--work /tmp/rfsdf-rooms] [--hybrid-joint]   (the hybrid's primitives and residual fitted together)
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from rfsdf.jsonio import to_json
from rfsdf.model_demo import MODELS, ModelDemoSettings, models_table, run_model_demo
from rfsdf.scene import load_scene
from rfsdf.scene_model import SceneModel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="l-room")
    parser.add_argument("--radar", default="room-60g")
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    parser.add_argument("--model-scene", default=None, help="start from this scene's model instead of --scene's")
    parser.add_argument("--start-offset", type=float, default=0.15)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-samples", type=int, default=ModelDemoSettings.max_surface_samples,
                        help="the simulator's facet budget")
    parser.add_argument("--work", type=Path, default=Path("/tmp/rfsdf-rooms"))
    parser.add_argument("--hybrid-joint", action="store_true",
                        help="fit the hybrid's primitives and residual together, then the residual alone")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    stem = Path(args.scene).stem
    settings = dataclasses.replace(ModelDemoSettings(), scene=args.scene, radar=args.radar,
                                   start_offset_m=args.start_offset, seed=args.seed,
                                   max_surface_samples=args.max_samples, hybrid_joint=args.hybrid_joint)
    start = None
    if args.model_scene is not None:
        start = SceneModel.from_scene(load_scene(args.model_scene), args.start_offset, args.seed)
    name = stem if args.model_scene is None else f"{stem}-from-{Path(args.model_scene).stem}"
    folder = args.work / (f"{name}-joint" if args.hybrid_joint else name)  # a demo folder holds one setting
    result = run_model_demo(folder, settings, args.models, start=start)
    print(models_table(result))
    out = args.out or Path(f"benchmarks/results/room-models-{folder.name}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json({**result, "model_scene": args.model_scene}))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
