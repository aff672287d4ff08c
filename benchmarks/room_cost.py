"""How a room fit's cost grows with the room's size and its number of free parameters.

The room is ``pillar-room`` (``benchmarks/scenes/pillar-room.toml``) with every length scaled
by ``--scales`` about the views' centre, seen by ``room-60g`` (1.5 puts the far walls at
4.2 m, within its unambiguous range c / 2 delta f = 4.3 m). Per scale:

- **simulation**: the facets in view that ``simulate`` would sum (``surface_samples``: edges
  within sqrt(lambda R / 32) at their range R, so a facet's area grows as R and a room s
  times larger, s^2 the area at s times the range, needs about s times the facets), the
  time to make them, and the time of the scattering and A c per facet, measured on
  ``--facet-subset`` of them: the simulation's cost is their product;
- **fit**: seconds per step of the range-profile fit (``fit_profiles``: ray votes of
  room-60g's 8 x 48^2 rays, forward and backward) with every length free, on data of the
  right shape (random: a step's cost does not depend on the values).

And at scale 1, seconds per step with fewer free parameters (the pillar's centre only, the
pillar's lengths, every length): the gradient of every free parameter comes from one
backward pass, so the count should barely matter.

Usage: python benchmarks/room_cost.py [--scales 0.5 1 1.5] [--steps 5] [--facet-subset 20000]
       [--out benchmarks/results/room-cost.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import torch

from rfsdf.jsonio import to_json
from rfsdf.radar import Measurements, load_radar
from rfsdf.radar.facets import facet_weight
from rfsdf.radar.operator import SensingOperator
from rfsdf.radar.simulate import SAMPLES_PER_WAVELENGTH, view_reflectivities
from rfsdf.radar.surface_plan import surface_samples
from rfsdf.recon.primitive import PrimitiveField
from rfsdf.recon.range_profile import ProfileSettings, fit_profiles
from rfsdf.scene import Scene, load_scene
from rfsdf.scene_model import POSITION_FIELDS, SIZE_FIELDS, SceneModel
from rfsdf.scene_spec import SceneSpec

SCENE = "benchmarks/scenes/pillar-room.toml"
RADAR = load_radar("room-60g")
ACQUISITION = RADAR.acquisition()


def scaled(scene: Scene, factor: float, about) -> Scene:
    """``scene`` with every length scaled by ``factor`` about the point ``about`` (3,) [m]:
    points move away from it, sizes and translations (offsets, not points) grow."""
    about = np.asarray(about, dtype=float)
    table = scene.spec.model_dump(mode="json", exclude_none=True)
    point = lambda value: (about + factor * (np.asarray(value) - about)).tolist()  # noqa: E731
    length = lambda value: (factor * np.asarray(value)).tolist()  # noqa: E731

    def walk(node):
        if isinstance(node, dict):
            for key, value in node.items():
                if key in SIZE_FIELDS + ("translate_m",) and value is not None:
                    node[key] = length(value)
                elif key in POSITION_FIELDS and value is not None:
                    node[key] = point(value)
                else:
                    walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(table["objects"])
    table["bounds"] = {key: point(value) for key, value in table["bounds"].items()}
    table["name"] = f"{scene.name}-x{factor:g}"
    return Scene(SceneSpec.model_validate(table), scene.base_dir)


def only_free(model: SceneModel, keep) -> SceneModel:
    """``model`` with only the free parameters whose dotted name ``keep(name)`` accepts."""
    return dataclasses.replace(model, free=[p for p in model.free if keep(p.name)])


def _seconds(work) -> float:
    clock = time.perf_counter()
    work()
    return time.perf_counter() - clock


def seconds_per_step(measurements: Measurements, model: SceneModel, steps: int) -> float:
    """A profile fit's seconds per step, less what a fit spends once (the data's profiles)."""
    def fit(count: int) -> None:
        field = PrimitiveField(model)
        fit_profiles(measurements, field, [{"params": list(field.values), "lr": 0.01}], steps=count,
                     settings=ProfileSettings())
    return (_seconds(lambda: fit(steps + 1)) - _seconds(lambda: fit(1))) / steps


def seconds_per_facet(scene: Scene, facets, count: int) -> float:
    """The scattering and A c's seconds per facet: the time for 2 ``count`` random facets
    less that for ``count`` (what a run spends once: shadows' set-up, chunking), over ``count``."""
    acq_operator = SensingOperator(ACQUISITION)

    def simulate(n: int) -> None:
        subset = facets.select(torch.randperm(len(facets.points))[:n])
        c = view_reflectivities(scene, subset, ACQUISITION)
        acq_operator.forward_weighted(subset.points, c, facet_weight(ACQUISITION, subset.points, subset.corners_m))
    return (_seconds(lambda: simulate(2 * count)) - _seconds(lambda: simulate(count))) / count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scales", type=float, nargs="+", default=[0.5, 1.0, 1.5])
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--facet-subset", type=int, default=20_000)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/room-cost.json"))
    args = parser.parse_args()
    torch.manual_seed(0)
    acq = ACQUISITION
    centre = (0.5 * (acq.tx_m.mean(1) + acq.rx_m.mean(1))).double().mean(0).numpy()
    data = torch.randn(*acq.shape, dtype=torch.complex64)
    measurements = Measurements(acq, data)
    base = load_scene(SCENE)
    rows = []
    for factor in args.scales:
        scene = scaled(base, factor, centre)
        spacing = acq.wavelength_m / SAMPLES_PER_WAVELENGTH
        area = float(sum(m.area for m in scene.object_meshes()))
        clock = time.perf_counter()  # a budget just under the points' count: facets, as for any room
        facets, _ = surface_samples(scene, acq, spacing, int(area / spacing**2) - 1)
        make_s = time.perf_counter() - clock
        per_facet_s = seconds_per_facet(scene, facets, args.facet_subset)
        model = SceneModel.from_scene(scene, 0.05 * factor, 0)
        rows.append({"scale": factor, "surface_m2": round(area, 2), "points_lambda_3": round(area / spacing**2), "facets_in_view": len(facets.points),
                     "facets_s": round(make_s, 2), "scatter_and_ac_us_per_facet": round(per_facet_s * 1e6, 2),
                     "simulation_s_estimate": round(make_s + per_facet_s * len(facets.points), 1),
                     "free_parameters": sum(len(p.start) for p in model.free),
                     "fit_s_per_step": round(seconds_per_step(measurements, model, args.steps), 3)})
        print(rows[-1], flush=True)
        del facets
    model = SceneModel.from_scene(base, 0.05, 0)
    free_rows = []
    for label, keep in (("the pillar's centre", lambda name: name == "pillar.center_m"),
                        ("the pillar's lengths", lambda name: name.startswith("pillar.")),
                        ("every length", lambda name: True)):
        narrowed = only_free(model, keep)
        free_rows.append({"free": label, "free_parameters": sum(len(p.start) for p in narrowed.free),
                          "fit_s_per_step": round(seconds_per_step(measurements, narrowed, args.steps), 3)})
        print(free_rows[-1], flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"scene": SCENE, "radar": RADAR.name, "threads": torch.get_num_threads(),
                                 "steps": args.steps, "scales": rows, "free_parameters": free_rows}))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
