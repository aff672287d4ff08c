"""Simulated datasets: many seeded random scenes (:mod:`rfsdf.random_scenes`), each written
as a scene file and its measurements, on the engines of :mod:`rfsdf.parallel`.

Folder layout::

    scene-00000.toml, scene-00000.h5    scene i (seed base_seed + i) and its measurements
    ...
    dataset.json                        one row per scene: name, seed, objects, materials,
                                        status (done, reused, failed), error, seconds

A rerun skips the scenes whose measurements exist (files are written atomically, so an
existing file is complete); a scene that fails is recorded and the others go on.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import tomli_w

from .atomic import atomic_path
from .jsonio import write_json
from .parallel import error_line, map_tasks, threads_per_worker, use_threads
from .random_scenes import random_scene_spec

__all__ = ["check_dataset", "simulate_scene_file", "simulate_dataset"]

_SCENE_FILE_BYTES = 4096  # a random scene's TOML, rounded up [bytes]


def check_dataset(count: int, out, *, radar: str = "near-77g", base_seed: int = 0) -> str:
    """Refuse, before any scene is drawn, a dataset that cannot be made: a radar that does not
    load, cannot image the random scenes' box or has a catalogue material out of band, or
    more data than the disk under ``out`` has free. Returns the line that says how much."""
    import shutil

    from .errors import RfsdfError
    from .materials import get_material
    from .radar import check_radar_for_scene, load_radar
    from .radar.checks import check_material_in_band
    from .random_scenes import MATERIALS

    system = load_radar(radar)
    bounds = random_scene_spec(base_seed)["bounds"]  # every random scene has the same box
    check_radar_for_scene(system, bounds["lower_m"], bounds["upper_m"], source=radar)
    for name in MATERIALS:  # any random scene may use any of them
        check_material_in_band(get_material(name), system, where=f"{radar} (random scenes use {', '.join(MATERIALS)})")
    views, txs, rxs = len(system.rotations), len(system.tx_m), len(system.rx_m)
    # complex64 samples (gzip cannot shrink noise) and float64 element positions per view
    per_scene = 8 * views * txs * rxs * len(system.frequencies_hz) + 24 * views * (txs + rxs + 1) + _SCENE_FILE_BYTES
    total = per_scene * count
    folder = next(p for p in (Path(out).resolve(), *Path(out).resolve().parents) if p.exists())
    free = shutil.disk_usage(folder).free
    amount = f"{count:,} scenes of about {per_scene / 2**20:.3g} MiB each, {total / 2**30:.3g} GiB in all"
    if total > free:
        raise RfsdfError(f"{out}: {amount}, more than the {free / 2**30:.3g} GiB free on its disk; "
                         "ask for fewer scenes or write elsewhere")
    return f"{amount} ({free / 2**30:.3g} GiB free)"


def simulate_scene_file(name: str, seed: int, radar_name: str, folder: str, threads: int,
                        device: str = "auto") -> dict:
    """Write ``folder``/name.toml (random scene ``seed``) and name.h5 (its measurements by
    the radar, simulation seed ``seed``, on ``device`` as the worker resolves it); the dataset
    row. Never raises: a failure is the row."""
    from .device import resolve_device
    from .radar import check_materials_in_band, check_radar_for_scene, load_radar, simulate, write_measurements
    from .scene import load_scene

    use_threads(threads)
    spec = random_scene_spec(seed)
    row = {"name": name, "seed": seed, "objects": len(spec["objects"]),
           "materials": sorted({o["material"] for o in spec["objects"]}), "status": "reused", "error": "", "seconds": 0.0}
    scene_path, data_path = Path(folder) / f"{name}.toml", Path(folder) / f"{name}.h5"
    if data_path.exists():
        return row
    start = time.perf_counter()
    try:
        with atomic_path(scene_path) as tmp:
            tmp.write_text(tomli_w.dumps(spec))
        scene, radar = load_scene(scene_path), load_radar(radar_name)
        check_radar_for_scene(radar, scene.lower_m, scene.upper_m, source=radar_name)
        check_materials_in_band(scene, radar, source=str(scene_path))
        write_measurements(data_path, simulate(scene, radar, seed=seed, device=resolve_device(device)))
        row["status"] = "done"
    except Exception as exc:  # noqa: BLE001 - one failed scene is a row, not the end of the dataset
        row.update(status="failed", error=error_line(exc))
    row["seconds"] = round(time.perf_counter() - start, 2)
    return row


def simulate_dataset(count: int, out, *, radar: str = "near-77g", base_seed: int = 0, workers: int = 1,
                     ray_address: str | None = None, device: str = "auto",
                     log: Callable[[str], None] = print) -> list[dict]:
    """Simulate ``count`` random scenes into folder ``out``; writes dataset.json; the rows."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    threads = threads_per_worker(workers)
    tasks = [(f"scene-{i:05d}", base_seed + i, radar, str(out), threads, device) for i in range(count)]
    rows = map_tasks(simulate_scene_file, tasks, workers=workers, ray_address=ray_address, cpus_per_task=threads,
                     on_result=lambda i, row: log(f"{row['name']}: {row['status']} {row['error']}".rstrip()))
    write_json(out / "dataset.json", {"radar": radar, "base_seed": base_seed, "scenes": rows})
    return rows
