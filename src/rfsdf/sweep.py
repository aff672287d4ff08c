"""Many demos at once: a grid or list of (scene, radar, reconstruction settings, seed) jobs,
run in a local process pool or as Ray tasks, summarised in one table.

A sweep file (TOML)::

    [defaults]                 # optional: every job starts from these
    quick = true
    recon = { train = { steps = 6 } }

    [grid]                     # optional: the Cartesian product of these lists
    scene = ["objects", "sphere"]
    seed = [0, 1]

    [[jobs]]                   # optional: jobs listed one by one
    scene = "objects"
    radar = "dense-77g"

Each job is what ``rfsdf demo`` takes (``scene``, ``radar``: preset names or files,
relative to the sweep file; ``seed``; ``quick``; ``voxel_m``; ``recon``: the
reconstruction overrides) and runs in its own folder ``OUT/NNN-scene-radar-seedS`` with the
same files as ``rfsdf demo``. A rerun skips finished jobs (their ``metrics.json`` is read
back) and continues unfinished fits from their checkpoints; a job that fails is recorded
with its error line and the others go on. ``summary.csv`` / ``summary.json`` hold one row
per job (its settings, status, every metric of its ``metrics.json``, stage times) and
``summary.png`` each job's Chamfer-L1 by method.

Execution is :func:`rfsdf.parallel.map_tasks`: ``concurrent.futures`` processes locally,
Ray tasks with ``ray_address`` (``"local"`` starts a Ray instance, anything else is passed
to ``ray.init``).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import itertools
import json
import math
from pathlib import Path
from typing import Any, Callable

import pydantic

from .atomic import atomic_path
from .config import StrictModel, merge_tables, read_toml, validate
from .demo import QUICK, SETTINGS_NAME, DemoSettings, load_scene_and_radar, run_demo
from .errors import RfsdfError
from .jsonio import to_json, write_json
from .parallel import error_line, map_tasks, threads_per_worker, use_threads
from .recon import ReconConfig

__all__ = ["JobSpec", "SweepSpec", "Job", "MAX_JOBS", "count_jobs", "load_sweep", "run_job", "run_sweep", "summary_row"]


class JobSpec(StrictModel):
    """One job's settings; every key optional (the demo's defaults)."""

    scene: str = "objects"
    radar: str = "near-77g"
    seed: int = pydantic.Field(0, ge=0, le=2**32 - 1)
    quick: bool = False
    voxel_m: float | None = pydantic.Field(None, gt=0)
    recon: dict[str, Any] = pydantic.Field(default_factory=dict)


class SweepSpec(StrictModel):
    """A sweep file: defaults, a grid of lists over JobSpec's keys, and listed jobs."""

    defaults: dict[str, Any] = pydantic.Field(default_factory=dict)
    grid: dict[str, list] = pydantic.Field(default_factory=dict)
    jobs: list[dict[str, Any]] = pydantic.Field(default_factory=list)

    @pydantic.field_validator("grid")
    @classmethod
    def _grid_keys(cls, grid: dict[str, list]) -> dict[str, list]:
        unknown = sorted(set(grid) - set(JobSpec.model_fields))
        if unknown:
            raise ValueError(f"unknown job key(s) {', '.join(unknown)}; known: {', '.join(JobSpec.model_fields)}")
        if any(len(values) == 0 for values in grid.values()):
            raise ValueError("every grid list needs at least one value")
        return grid


@dataclasses.dataclass(frozen=True)
class Job:
    """A named job: its folder name and the demo settings it runs."""

    name: str
    spec: JobSpec
    settings: DemoSettings


def _resolve(name_or_file: str, base: Path) -> str:
    """A preset name as is; a file path relative to the sweep file's folder made absolute."""
    candidate = base / name_or_file
    return str(candidate.resolve()) if not Path(name_or_file).is_absolute() and candidate.exists() else name_or_file


def _job(index: int, fields: dict, source: str, base: Path) -> Job:
    spec = validate(JobSpec, fields, f"{source}: job {index}")
    scene, radar = _resolve(spec.scene, base), _resolve(spec.radar, base)
    settings = dataclasses.replace(QUICK if spec.quick else DemoSettings(), scene=scene, radar=radar, seed=spec.seed)
    if spec.voxel_m is not None:
        settings = dataclasses.replace(settings, voxel_m=spec.voxel_m)
    if spec.recon:
        settings = dataclasses.replace(settings, recon=merge_tables(settings.recon, spec.recon))
    stem = lambda text: Path(text).stem if text.endswith(".toml") else text  # noqa: E731
    name = f"{index:03d}-{stem(spec.scene)}-{stem(spec.radar)}-seed{spec.seed}"
    return Job(name, spec, settings)


MAX_JOBS = 5000
"""Most jobs one sweep may ask for unless told (``rfsdf sweep --max-jobs``)."""


def count_jobs(spec: SweepSpec) -> int:
    """Jobs a sweep file asks for, from its list lengths alone (nothing is expanded)."""
    return (math.prod(len(values) for values in spec.grid.values()) if spec.grid else 0) + len(spec.jobs)


def load_sweep(path, *, max_jobs: int = MAX_JOBS) -> list[Job]:
    """The jobs of a sweep file, in order (grid first, then the listed jobs), each checked as
    ``rfsdf demo`` would check it (scene, radar, reconstruction settings) before any runs;
    one-line errors. A file asking for more than ``max_jobs`` is refused before its grid is
    expanded."""
    path = Path(path)
    spec = validate(SweepSpec, read_toml(path), str(path))
    count = count_jobs(spec)
    if count == 0:
        raise RfsdfError(f"{path}: (top level): no jobs (give a [grid] table or [[jobs]] entries)")
    if count > max_jobs:
        sizes = " x ".join(f"{len(values)} {key}" for key, values in spec.grid.items())
        listed = f" + {len(spec.jobs)} listed" if spec.jobs else ""
        raise RfsdfError(f"{path}: grid: asks for {count:,} jobs ({sizes or 'no grid'}{listed}), more than the "
                         f"{max_jobs:,} allowed; split the sweep or raise the limit with --max-jobs")
    combos = (dict(zip(spec.grid, values)) for values in itertools.product(*spec.grid.values())) if spec.grid else ()
    fields = itertools.chain((merge_tables(spec.defaults, combo) for combo in combos),
                             (merge_tables(spec.defaults, job) for job in spec.jobs))
    jobs = [_job(i, f, str(path), path.parent) for i, f in enumerate(fields)]
    _check_jobs(jobs, str(path))
    return jobs


def _check_jobs(jobs: list[Job], source: str) -> None:
    """Every job's scene, radar and reconstruction settings, checked before the first runs
    (each scene and radar pair loaded once); RfsdfError naming the first bad job and field."""
    scene_and_radar = functools.cache(load_scene_and_radar)
    for job in jobs:
        where = f"{source}: job {job.name}"
        try:
            scene_and_radar(job.settings.scene, job.settings.radar)
        except RfsdfError as exc:
            raise RfsdfError(f"{where}: {exc}") from None
        validate(ReconConfig, job.settings.recon, f"{where}: recon")


def run_job(job: Job, folder: str, threads: int) -> dict:
    """Run one job into ``folder`` (skipped when finished); its summary row. Never raises:
    a failure is the row's status and error line."""
    use_threads(threads)
    folder = Path(folder)
    try:
        metrics = _finished(folder, job.settings)
        status = "reused"
        if metrics is None:
            folder.mkdir(parents=True, exist_ok=True)
            run_demo(folder, job.settings, log=lambda _: None, progress=False)
            metrics = json.loads((folder / "metrics.json").read_text())
            status = "done"
        return summary_row(job, status, metrics=metrics)
    except Exception as exc:  # noqa: BLE001 - a failed job is a row, not the end of the sweep
        return summary_row(job, "failed", error=error_line(exc))


def _finished(folder: Path, settings: DemoSettings) -> dict | None:
    """The metrics of a finished run of these settings in ``folder``, else None."""
    try:
        held = json.loads((folder / SETTINGS_NAME).read_text())
        metrics = json.loads((folder / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
    return metrics if held == json.loads(to_json(dataclasses.asdict(settings))) else None


def summary_row(job: Job, status: str, *, metrics: dict | None = None, error: str = "") -> dict:
    """One job's row: settings, status, error, then every metric of metrics.json flattened
    as METHOD.PART.KEY (PART: full, observed, object name) and the stage times."""
    spec = job.spec
    row: dict[str, Any] = {"job": job.name, "scene": spec.scene, "radar": spec.radar, "seed": spec.seed,
                           "quick": spec.quick, "recon": json.dumps(spec.recon, sort_keys=True),
                           "status": status, "error": error}
    if metrics is None:
        return row
    row["fit_steps"], row["seconds_per_step"] = metrics["fit_steps"], metrics["seconds_per_step"]
    for method, values in metrics["methods"].items():
        for part in ("full", "observed"):
            for key, value in (values.get(part) or {}).items():
                row[f"{method}.{part}.{key}"] = value
        for obj, per_object in values["objects"].items():
            for key in ("chamfer_l1_mm", "precision", "recall", "found"):
                row[f"{method}.{obj}.{key}"] = per_object[key]
    row.update({f"time.{stage}": seconds for stage, seconds in metrics["timings_s"].items()})
    return row


def run_sweep(jobs: list[Job], out, *, workers: int = 1, ray_address: str | None = None,
              log: Callable[[str], None] = print) -> list[dict]:
    """Run every job into ``out``/job.name; write summary.csv, summary.json and summary.png."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    threads = threads_per_worker(workers)
    rows = map_tasks(run_job, [(job, str(out / job.name), threads) for job in jobs], workers=workers,
                     ray_address=ray_address, cpus_per_task=threads, on_result=lambda i, row: log(_status_line(row)))
    write_summary(rows, out)
    return rows


def _status_line(row: dict) -> str:
    score = row.get("neural.full.chamfer_l1_mm")
    detail = row["error"] if row["status"] == "failed" else (f"GeRaF Chamfer {score:.2f} mm" if score else "")
    return f"{row['job']}: {row['status']} {detail}".rstrip()


def write_summary(rows: list[dict], out: Path) -> None:
    """summary.json, summary.csv (the union of every row's columns) and summary.png."""
    columns = list(dict.fromkeys(key for row in rows for key in row))
    write_json(out / "summary.json", {"columns": columns, "rows": rows})
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, restval="")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(out / "summary.csv") as tmp:
        tmp.write_text(text.getvalue())
    from .viz.sweep import plot_sweep_summary

    plot_sweep_summary(rows, out / "summary.png")
