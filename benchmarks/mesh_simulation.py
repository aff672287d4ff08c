"""Simulating a scene with a mesh object against the same scene made of primitives.

The `objects` scene is simulated as it is, and again with its CSG notched block replaced by
that block's own marching-cubes mesh (same place, same surface area, so the comparison is
of the SDF's cost alone), and, where the shared Spot mesh is beside the project, with a
6 cm Spot in its place. Most of a mesh scene's cost is the shadow rays, which sphere-trace
the scene SDF. Also timed: the mesh SDF on 2000 points near the block against trimesh's closest-point
and containment queries (the reference in the tests), on the same points.

Usage: python benchmarks/mesh_simulation.py [--out benchmarks/results/mesh_simulation.json]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from rfsdf.jsonio import to_json
from rfsdf.radar import load_radar, simulate
from rfsdf.scene import Scene, load_scene

SPOT = Path(__file__).resolve().parents[2] / "shared" / "data" / "spot.obj"
REPLACED = "notched_block"
REPEATS = 2


def with_mesh(scene: Scene, shape: dict) -> Scene:
    """``scene`` with the object ``REPLACED`` given the mesh ``shape`` (a shape table)."""
    spec = scene.spec.model_dump()
    for obj in spec["objects"]:
        if obj["name"] == REPLACED:
            obj["shape"] = shape
    return Scene(type(scene.spec).model_validate(spec))


def timed_simulation(scene: Scene, radar) -> dict:
    start = time.perf_counter()
    measurements = simulate(scene, radar, seed=0)
    return {"seconds": round(time.perf_counter() - start, 2),
            "surface_samples": int(measurements.metadata["surface_samples"])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/mesh_simulation.json"))
    args = parser.parse_args()
    torch.set_num_threads(2)
    scene, radar = load_scene("objects"), load_radar("near-77g")
    result = {"threads": torch.get_num_threads(), "radar": radar.name}
    with tempfile.TemporaryDirectory() as tmp:
        block = scene.object_meshes()[[o.name for o in scene.objects].index(REPLACED)]
        block.export(Path(tmp) / "block.ply")
        scenes = {"primitives": scene,
                  "block_as_mesh": with_mesh(scene, {"type": "mesh", "path": str(Path(tmp) / "block.ply")})}
        result["block_mesh_faces"] = len(block.faces)
        if SPOT.exists():
            centre = [float(v) for v in block.bounds.mean(axis=0)]
            scenes["spot"] = with_mesh(scene, {"type": "mesh", "path": str(SPOT), "size_m": 0.06, "center_m": centre})
        for _ in range(REPEATS):  # interleaved, the least time of each kept
            for name, s in scenes.items():
                run = timed_simulation(s, radar)
                if name not in result or run["seconds"] < result[name]["seconds"]:
                    result[name] = run
        print({name: result[name] for name in scenes}, flush=True)
    base = result["primitives"]["seconds"]
    for name in scenes:
        if name != "primitives":
            result[name]["ratio_to_primitives"] = round(result[name]["seconds"] / base, 2)

    mesh_sdf = scenes["block_as_mesh"].objects[[o.name for o in scene.objects].index(REPLACED)].sdf
    # near the block (trimesh's query takes gigabytes for points far from a mesh)
    points = np.random.default_rng(0).uniform(block.bounds[0] - 0.01, block.bounds[1] + 0.01, (2000, 3))
    start = time.perf_counter()
    mesh_sdf(torch.from_numpy(points))
    ours = time.perf_counter() - start
    start = time.perf_counter()
    block.nearest.on_surface(points)
    block.contains(points)
    reference = time.perf_counter() - start
    result["mesh_sdf_us_per_point"] = round(ours / len(points) * 1e6, 2)
    result["mesh_sdf_speedup_vs_trimesh"] = round(reference / ours, 1)
    print({k: result[k] for k in ("mesh_sdf_us_per_point", "mesh_sdf_speedup_vs_trimesh")})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
