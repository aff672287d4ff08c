"""Each hot stage of `rfsdf demo` timed on the CPU and, where torch sees one, on a CUDA GPU.

On the default demo (scene `objects`, radar `near-77g`, 6 mm grid): the simulation
(scattering with shadows + A c over the surface samples), the exact matched filter of every
view, CLEAN of one view, a fit step (fit settings as the demo's, warm start skipped; the
seconds per step the trainer measures), and the SDF network evaluated on a 128^3 grid for
marching cubes; and a room's hot stage: A c over 100,000 facets (float64, as the facet
simulation sums them) for l-room's radar `room-60g` (8 views, 12 channels, 400 frequencies);
and a fit step on scanned apertures: scene `handheld` on preset `sar-77g` (four scans of 1089
frames, simulated once on the GPU where there is one), `[render] element_step = 3`, started
from a sphere (the warm start skipped: its facets, not the warm start's, set the cost).
Each stage runs once to warm up (CUDA kernels, numba) and is then timed;
`speedup` is CPU seconds / GPU seconds in the same run. Without a GPU the JSON says so and
holds the CPU figures only.

Usage: python benchmarks/devices.py [--stages fit_step_s,...] [--out benchmarks/results/devices.json]
"""

from __future__ import annotations

import argparse
import functools
import tempfile
import time
from pathlib import Path

import torch

from rfsdf.demo import DemoSettings
from rfsdf.device import resolve_device
from rfsdf.geometry import Grid
from rfsdf.jsonio import to_json
from rfsdf.mesh import evaluate_on_grid
from rfsdf.radar import SensingOperator, load_radar, matched_filter, simulate
from rfsdf.radar.clean import clean_view
from rfsdf.radar.scan_imaging import lattice_grid
from rfsdf.recon import Problem, ReconConfig, Trainer
from rfsdf.scene import load_scene

FIT_STEPS = 4


def _seconds(function, device: torch.device) -> float:
    """Wall time of a second call of ``function`` (the first warms up), synchronised."""
    function()
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    start = time.perf_counter()
    function()
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    return round(time.perf_counter() - start, 3)


STAGES = ("simulate_s", "matched_filter_s", "clean_one_view_s", "fit_step_s", "sdf_on_128_grid_s", "room_facets_ac_s",
          "scan_fit_step_s")
SCAN_FIT_STEPS = 2


@functools.cache
def _scan_problem() -> Problem:
    """Scene ``handheld`` on preset ``sar-77g`` (four scans), simulated once, on a GPU where
    there is one, on the lattice grid the scans share."""
    scene = load_scene("handheld")
    measurements = simulate(scene, load_radar("sar-77g"), seed=0, device=resolve_device("auto"))
    return Problem(measurements, lattice_grid(measurements.acquisition, scene.lower_m, scene.upper_m))


def stage_seconds(device: torch.device, stages=STAGES) -> dict[str, float]:
    """Seconds per stage on ``device`` (the demo's scene, radar and grid), of ``stages``."""
    settings = DemoSettings()
    scene, radar = load_scene(settings.scene), load_radar(settings.radar)
    data = functools.cache(lambda: simulate(scene, radar, seed=settings.seed, max_samples=settings.max_surface_samples))
    grid = Grid.from_voxel(scene.lower_m, scene.upper_m, settings.voxel_m)
    config = ReconConfig.model_validate({"init": {"method": "sphere"},
                                         "train": {"steps": FIT_STEPS, "device": str(device)}})

    def fit(problem=None, config=config):
        with tempfile.TemporaryDirectory() as folder:
            return Trainer(problem or Problem(data(), grid), config, folder).fit()

    scan_config = ReconConfig.model_validate({"init": {"method": "sphere"}, "render": {"element_step": 3},
                                              "train": {"steps": SCAN_FIT_STEPS, "device": str(device)}})

    extent = max(u - lo for lo, u in zip(scene.lower_m, scene.upper_m))
    mesh_grid = Grid.from_voxel(scene.lower_m, scene.upper_m, float(extent) / 128)  # the demo's mesh resolution
    timed = {
        "simulate_s": lambda: _seconds(lambda: simulate(scene, radar, seed=settings.seed, device=device,
                                                        max_samples=settings.max_surface_samples), device),
        "matched_filter_s": lambda: _seconds(lambda: matched_filter(data(), grid, method="exact", device=device),
                                             device),
        "clean_one_view_s": lambda: _seconds(lambda: clean_view(data(), 0, grid, method="exact", device=device),
                                             device),
        "fit_step_s": lambda: round((fit(), fit())[1].seconds_per_step, 3),  # the first warms up
        "sdf_on_128_grid_s": lambda: _seconds(lambda: evaluate_on_grid(fit().field.sdf, mesh_grid, device=device),
                                              device),
        "room_facets_ac_s": lambda: _seconds(_room_facets_ac(device), device),
        "scan_fit_step_s": lambda: round((fit(_scan_problem(), scan_config),
                                          fit(_scan_problem(), scan_config))[1].seconds_per_step, 3),
    }
    return {stage: timed[stage]() for stage in stages}


def _room_facets_ac(device: torch.device, facets: int = 100_000):
    """A c over ``facets`` random points of l-room's box with room-60g's acquisition."""
    operator = SensingOperator(load_radar("room-60g").acquisition())
    g = torch.Generator().manual_seed(0)
    points = ((torch.rand(facets, 3, generator=g, dtype=torch.float64) * 2 - 1) * 2).to(device)
    c = torch.ones(8, facets, dtype=torch.complex128, device=device)
    return lambda: operator.forward(points, c)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--stages", default=",".join(STAGES), help=f"comma-separated, of {', '.join(STAGES)}")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/devices.json"))
    args = parser.parse_args()
    stages = args.stages.split(",")
    unknown = set(stages) - set(STAGES)
    if unknown:
        parser.error(f"unknown stages {sorted(unknown)}; known: {', '.join(STAGES)}")
    result: dict = {"threads": torch.get_num_threads(), "cpu": stage_seconds(torch.device("cpu"), stages)}
    if torch.cuda.is_available():
        cuda = resolve_device("cuda")
        result.update(gpu=torch.cuda.get_device_name(cuda), cuda=stage_seconds(cuda, stages))
        result["speedup"] = {k: round(result["cpu"][k] / max(v, 1e-9), 1) for k, v in result["cuda"].items()}
    else:
        result.update(gpu=None, cuda=None, note="torch sees no CUDA GPU on this machine: CPU figures only")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json(result))
    print(to_json(result))


if __name__ == "__main__":
    main()
