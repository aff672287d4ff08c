"""`[init] primitives` with every peak's line of sight as free space, against only the lines
the warm start leaves clear (`recon.object_primitives.free_space`'s ``occluder``, the
pipeline's). On each scene's warm start as `rfsdf demo` builds it (seed 0; the peaks read as
glints within ``--cone``): per variant the free-space samples, each fragment's primitive (the
true object it lies on, the kind, its peaks' median |f|, the share of the samples near it it
carves, whether it replaces the fragment) and the target (`primitive_target`) scored as the
demo scores a mesh (observed and whole Chamfer, per object); and the warm start's own scores.

Usage: python benchmarks/clear_lines.py [--scenes objects,tabletop,...] [--cone 0.25]
       [--out benchmarks/results/clear-lines.json]
       (about 4-5 min a scene on 2 cores; a scene that is not a preset is benchmarks/scenes/NAME.toml)
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from demo_data import demo_data, demo_warm_start
from primitive_start import object_of, scorer

from rfsdf.demo import DemoSettings
from rfsdf.jsonio import to_json
from rfsdf.recon.object_primitives import explain_all, fragments, free_space, primitive_target

PRESETS = ("objects", "tabletop")
SCENES = "objects,tabletop,counter,garage,workshop,shelf,pantry,cellar,bench"


def _scene(name: str, cone_deg: float) -> dict:
    """The warm start's and both variants' scores on scene ``name``, the peaks read as glints
    within ``cone_deg``."""
    settings = dataclasses.replace(DemoSettings(),
                                   scene=name if name in PRESETS else f"benchmarks/scenes/{name}.toml")
    data = demo_data(settings)
    scene = data.scene
    trainer, _ = demo_warm_start(data)
    warm = trainer.field.requires_grad_(False)
    points, _, _, towards = trainer.peaks
    labels, grid, pieces = fragments(warm.sdf, scene.lower_m, scene.upper_m, points, trainer.peak_caps(cone_deg))
    scored = scorer(data, settings)
    result = {"warm start": scored(warm.sdf)}
    for variant, occluder in (("every line", None), ("clear lines", warm.sdf)):
        free = free_space(points, towards, scene.lower_m, scene.upper_m, occluder=occluder)
        _, fits = explain_all(pieces, warm.sdf, labels, grid, free)
        rows = [{"object": object_of(fit, scene), "fragments": len(fit.fragment.labels), "kind": fit.primitive.kind,
                 "peaks_median_mm": fit.peaks_median_m * 1e3, "carved": fit.carved, "replaces": fit.explains}
                for fit in fits]
        result[variant] = {"free_samples": len(free), "fragments": rows,
                           **scored(primitive_target(warm.sdf, labels, grid, fits))}
        print(name, variant, f"{result[variant]['observed_chamfer_l1_mm']:.2f} mm observed", flush=True)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scenes", default=SCENES)
    parser.add_argument("--cone", type=float, default=0.25, help="the peaks read as glints within this cone [deg]")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/clear-lines.json"))
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    results = {"cone_deg": args.cone, "scenes": {}}
    for name in args.scenes.split(","):
        results["scenes"][name] = _scene(name, args.cone)
        args.out.write_text(to_json(results))


if __name__ == "__main__":
    main()
