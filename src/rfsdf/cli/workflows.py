"""Whole pipelines and their outputs: rfsdf demo, report, view, sweep, study."""

from __future__ import annotations

from pathlib import Path

import click

from .app import (
    BATCH_EXIT,
    device_option,
    exit_on_failures,
    main,
    one_line_errors,
    POSITIVE,
    RAY_HELP,
    refuse_overwriting_inputs,
    SEED,
)


@main.command()
@click.option("--out", type=click.Path(path_type=Path), default=Path("rfsdf-demo"), show_default=True)
@click.option("--scene", "scene_name", default=None,
              help="Scene preset or TOML file (default: objects; handheld for a radar whose views are scans).")
@click.option("--radar", "radar_name", default="near-77g", show_default=True,
              help="Radar preset or TOML file (sar-77g: GeRaF's scanned set-up, each scan one view).")
@click.option("--quick", is_flag=True, help="A tiny, seconds-long version (coarse grid, few steps): a smoke test.")
@click.option("--no-materials", is_flag=True,
              help="Fit a free reflectivity instead of the material head (no material estimates).")
@click.option("--reference", default=None, metavar="NAME=MATERIAL",
              help="Calibrate the gain with the scene's object NAME, known to be MATERIAL (e.g. metal_ball=metal); "
                   "default: the scene's calibration_reference, if it names one.")
@click.option("--relative", is_flag=True,
              help="No calibration reference: one gain fitted per step, materials only relative to each other.")
@device_option()
@click.option("--model", "model_kind", type=click.Choice(["neural", "primitive", "hybrid", "all"]), default="neural",
              show_default=True,
              help="neural: the GeRaF fit and its baselines; primitive, hybrid: a scene model fitted to the range "
                   "profiles (rooms); all: those two and the GeRaF network distilled from the same start and fitted "
                   "to the same profiles, side by side.")
@click.option("--scene-model", "scene_model_path", type=click.Path(path_type=Path), default=None,
              help="With --model primitive/hybrid/all: the start model (a scene file with free parameters); "
                   "default: --scene with every length free, --start-offset off.")
@click.option("--start-offset", type=POSITIVE, default=None,
              help="With --model primitive/hybrid/all and no --scene-model: the largest start offset [m] per length "
                   "(default 0.15).")
@click.option("--seed", type=SEED, default=None,
              help="With --model primitive/hybrid/all: the seed of the data's noise and of the start offsets (default 0).")
@click.option("--free-materials", is_flag=True,
              help="With --model primitive/hybrid/all and no --scene-model: fit every object's material too "
                   "(undecided among metal, glass, concrete, plasterboard, wood), but the scene's calibration_reference.")
@click.option("--max-samples", type=click.IntRange(1, 10**8), default=None,
              help="With --model primitive/hybrid/all: the simulator's facet budget (default 3,000,000; --quick 40,000).")
@click.option("--transmission", is_flag=True,
              help="With --model primitive/hybrid/all: lines of sight go on through dielectric objects (ITU-R P.2040 "
                   "slabs) in the simulator and in the models' renderer; metal still stops them.")
@click.option("--beams", is_flag=True,
              help="With --model primitive/hybrid/all: fit each view's range profiles per beam of its array, "
                   "summed coherently over its channels (a wall at a beam's centre Tx x Rx times over the same "
                   "noise), not their mean over the channels.")
@one_line_errors
def demo(out: Path, scene_name: str | None, radar_name: str, quick: bool, no_materials: bool, reference: str | None,
         relative: bool, device: str, model_kind: str, scene_model_path: Path | None, start_offset: float | None,
         seed: int | None, free_materials: bool, max_samples: int | None, transmission: bool, beams: bool):
    """Simulate, image, reconstruct, mesh and evaluate a scene; all artefacts go to --out.

    Ends with a table of metrics for the GeRaF reconstruction and the baselines, and what
    the material head says each object is made of. A second run with the same --out
    continues (or reuses) the fit. With --model primitive, hybrid or all (rooms), a table
    of the models side by side instead.
    """
    import dataclasses

    from ..demo import demo_settings, metrics_table, run_demo
    from ..config import merge_tables

    if relative and reference is not None:
        raise click.UsageError("--relative and --reference exclude each other")
    if model_kind != "neural":
        neural_only = [name for name, given in (("--no-materials", no_materials), ("--reference", reference),
                                                ("--relative", relative)) if given]
        if neural_only:
            raise click.UsageError(f"{', '.join(neural_only)}: only with --model neural")
        if free_materials and scene_model_path is not None:
            raise click.UsageError("--free-materials: only without --scene-model (a model file marks its own)")
        _model_demo(out, scene_name or "objects", radar_name, quick, model_kind, scene_model_path,
                    0.15 if start_offset is None else start_offset, seed or 0, free_materials, max_samples,
                    transmission, beams, device)
        return
    given = [name for name, value in (("--scene-model", scene_model_path), ("--seed", seed),
                                      ("--start-offset", start_offset), ("--free-materials", free_materials or None),
                                      ("--max-samples", max_samples), ("--transmission", transmission or None),
                                      ("--beams", beams or None))
             if value is not None]
    if given:
        raise click.UsageError(f"{', '.join(given)}: only with --model primitive, hybrid or all")
    settings = demo_settings(radar_name, quick=quick)
    settings = dataclasses.replace(settings, scene=scene_name or settings.scene, relative=relative)
    if no_materials:
        settings = dataclasses.replace(settings, recon=merge_tables(settings.recon, {"field": {"materials": []}}))
    if reference is not None:
        settings = dataclasses.replace(settings, recon=merge_tables(settings.recon,
                                                                    {"calibration": {"reference": reference}}))
    from ..report import write_report

    result = run_demo(out, settings, device=device, log=click.echo)
    click.echo(metrics_table(result))
    click.echo(f"total {result.timings_s['total_s']:.0f} s; every artefact and metrics.json are in {out}")
    click.echo(f"report (open in a browser): {write_report(out)}")


def _model_demo(out: Path, scene_name: str, radar_name: str, quick: bool, model_kind: str,
                scene_model_path: Path | None, start_offset: float, seed: int, free_materials: bool,
                max_samples: int | None, transmission: bool, beams: bool, device: str) -> None:
    """``demo --model primitive|hybrid|all``: the scene models side by side (rfsdf.model_demo);
    ``device`` runs the simulation."""
    import dataclasses

    from ..model_demo import MODELS, QUICK_MODELS, ModelDemoSettings, models_table, run_model_demo
    from ..report import write_report

    settings = dataclasses.replace(QUICK_MODELS if quick else ModelDemoSettings(), scene=scene_name, radar=radar_name,
                                   start_offset_m=start_offset, seed=seed, free_materials=free_materials,
                                   scene_model=None if scene_model_path is None else str(scene_model_path),
                                   transmission=transmission, beams=beams)
    if max_samples is not None:
        settings = dataclasses.replace(settings, max_surface_samples=max_samples)
    result = run_model_demo(out, settings, MODELS if model_kind == "all" else (model_kind,), device=device,
                            log=click.echo)
    click.echo(models_table(result))
    click.echo(f"total {result['timings_s']['total_s']:.0f} s; every artefact and metrics.json are in {out}")
    click.echo(f"report (open in a browser): {write_report(out)}")


@main.command("report")
@click.argument("folder", type=click.Path(path_type=Path))
@one_line_errors
def report_cmd(folder: Path):
    """Write FOLDER/report.html for a demo folder or a reconstruction run folder: scene, radar,
    images, slices through each object, training curves, metrics, and 3-D views of the errors."""
    from ..report import write_report

    click.echo(f"wrote {write_report(folder)}")


@main.command("view")
@click.argument("mesh_path", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", default=None, help="Colour the mesh by its signed distance to this scene's surfaces.")
@click.option("--out", type=click.Path(path_type=Path), default=None, help="HTML file (default: MESH with .html).")
@one_line_errors
def view_cmd(mesh_path: Path, scene_name: str | None, out: Path | None):
    """Write an interactive 3-D view of a mesh file (PLY, OBJ, STL) as a self-contained HTML page."""
    from ..report import write_view

    out = out or mesh_path.with_suffix(".html")
    refuse_overwriting_inputs(out, mesh_path)
    click.echo(f"wrote {write_view(mesh_path, out, scene_name=scene_name)}")


@main.command("sweep", epilog=BATCH_EXIT)
@click.argument("sweep_file", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Folder: one run folder per job + summary.")
@click.option("--workers", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="Jobs at once in the local process pool (the cores are shared between them).")
@click.option("--ray", "ray_address", is_flag=False, flag_value="local", default=None, help=RAY_HELP)
@click.option("--max-jobs", type=click.IntRange(1, 10**7), default=5000, show_default=True,
              help="Refuse a sweep file that asks for more jobs (counted before anything is expanded).")
@one_line_errors
def sweep_cmd(sweep_file: Path, out: Path, workers: int, ray_address: str | None, max_jobs: int):
    """Run every job of a sweep file (scene, radar, reconstruction settings, seed), each as
    `rfsdf demo` into its own folder; write summary.csv, summary.json and summary.png.
    Every job's settings are checked before the first runs; a rerun skips finished jobs and
    resumes unfinished fits."""
    from ..sweep import load_sweep, run_sweep

    jobs = load_sweep(sweep_file, max_jobs=max_jobs)
    refuse_overwriting_inputs(out, sweep_file)
    where = f"Ray ({ray_address})" if ray_address else f"{workers} local worker{'s' * (workers > 1)}"
    click.echo(f"{len(jobs)} jobs on {where} -> {out}")
    rows = run_sweep(jobs, out, workers=workers, ray_address=ray_address, log=click.echo)
    failed = sum(row["status"] == "failed" for row in rows)
    click.echo(f"wrote {out / 'summary.csv'}, summary.json, summary.png ({len(rows) - failed} finished, {failed} failed)")
    exit_on_failures(failed)


@main.command("study")
@click.argument("name", required=False)
@click.option("--out", type=click.Path(path_type=Path), default=Path("studies"), show_default=True,
              help="Folder for NAME.json and NAME.png.")
@click.option("--quick", is_flag=True, help="The test-suite size: seconds, same claims, coarser numbers.")
@click.option("--list", "list_studies", is_flag=True, help="Name every study with one line each.")
@one_line_errors
def study_cmd(name: str | None, out: Path, quick: bool, list_studies: bool):
    """Reproduce one claim behind the method on the library itself: a figure (PNG) and its
    numbers (JSON); docs/studies/NAME.md says what they show."""
    from ..studies import STUDIES, run_study

    if list_studies:
        width = max(map(len, STUDIES))
        for study in STUDIES.values():
            click.echo(f"{study.NAME:<{width}}  {study.SUMMARY}")
        return
    if name not in STUDIES:
        raise ValueError(f"unknown study {name!r}; known: {', '.join(STUDIES)} (rfsdf study --list)")
    json_path, png_path = run_study(STUDIES[name], out, quick=quick)
    click.echo(f"wrote {json_path} and {png_path}")
