"""The ``rfsdf`` command: parses arguments, calls the library, turns bad input into one line."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import click

from .errors import RfsdfError
from .progress import set_quiet

__all__ = ["main"]


def _one_line_errors(func):
    """Show RfsdfError / ValueError as 'error: ...' with exit code 2, never a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (RfsdfError, ValueError, OSError) as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(2)

    return wrapper


def _refuse_overwriting_inputs(out: Path, *inputs) -> None:
    """ValueError when ``out`` is (or would replace) one of the command's input files."""
    import os

    for given in inputs:
        if given is None or not Path(given).exists() or not out.exists():
            continue
        if os.path.samefile(out, given):
            raise ValueError(f"{out}: --out is the input {given}; writing it would destroy the input, "
                             "choose another output")


class _PositiveFinite(click.ParamType):
    """A float > 0 that is finite (click's FloatRange lets nan and inf through)."""

    name = "positive number"

    def convert(self, value, param, ctx):
        import math

        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(number) and number > 0):
            self.fail(f"{value!r} is not a positive, finite number", param, ctx)
        return number


POSITIVE = _PositiveFinite()
SEED = click.IntRange(0, 2**32 - 1)


class _OneLineGroup(click.Group):
    """Click's own usage errors (bad option values, unknown options) as one 'error:' line
    with exit code 2, the same promise the commands keep, instead of a usage block."""

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        try:
            return super().main(*args, standalone_mode=False, **kwargs)
        except click.exceptions.Abort:
            click.echo("error: aborted", err=True)
            sys.exit(1)
        except click.exceptions.NoArgsIsHelpError as exc:  # a bare group name: its help, as click does
            click.echo(exc.format_message(), err=True)
            sys.exit(2)
        except click.ClickException as exc:
            click.echo(f"error: {exc.format_message()}", err=True)
            sys.exit(2)


def _checkout_commit() -> str | None:
    """``git describe --always --dirty`` (tags excluded: the commit) of the checkout this package runs from, or None
    (an installed wheel, no git, or git failing)."""
    import subprocess

    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        described = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty", "--abbrev=12",
                                    "--exclude", "*"], capture_output=True, text=True, timeout=5, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return described.stdout.strip() or None


def _print_version(ctx: click.Context, _param, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    from . import __version__

    commit = _checkout_commit()
    click.echo(f"rfsdf {__version__}" + ("" if commit is None else f" (commit {commit})"))
    ctx.exit()


@click.group(cls=_OneLineGroup)
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the version (and the commit, when run from a git checkout) and exit.")
@click.option("--quiet", is_flag=True, help="No progress bars (results and errors still print).")
def main(quiet: bool):
    """rfsdf: neural SDF reconstruction from mmWave MIMO radar (GeRaF).

    Progress bars go to stderr; in a log (stderr not a terminal) they become a plain line
    every 30 s of a long stage."""
    set_quiet(quiet)


@main.group()
def scene():
    """Inspect and export scenes (presets, TOML files or Sionna RT / Mitsuba XML files)."""


@scene.command("show")
@click.argument("name_or_file")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="PNG of SDF slices (default: NAME-slices.png in the current folder).")
@_one_line_errors
def scene_show(name_or_file: str, out: Path | None):
    """Print a summary of a scene and write a picture of its SDF slices."""
    from .scene import load_scene
    from .viz import plot_sdf_slices

    sc = load_scene(name_or_file)
    out = out or Path(f"{sc.name}-slices.png")
    _refuse_overwriting_inputs(out, name_or_file)
    click.echo(sc.summary())
    plot_sdf_slices(sc.sdf, sc.lower_m, sc.upper_m, out, title=f"scene {sc.name!r}: SDF slices")
    click.echo(f"wrote {out}")


@scene.command("export")
@click.argument("name_or_file")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder to write scene.xml and meshes/*.ply into (not the scene's own folder).")
@_one_line_errors
def scene_export(name_or_file: str, out: Path):
    """Write a scene as a Sionna RT / Mitsuba 3 scene: OUT/scene.xml and OUT/meshes/*.ply."""
    from .mitsuba.write import export_scene
    from .scene import load_scene

    sc = load_scene(name_or_file)
    if Path(name_or_file).is_file() and out.exists() and out.resolve() == Path(name_or_file).resolve().parent:
        raise ValueError(f"{out}: --out is the folder of the input {name_or_file}; exporting there could replace "
                         "its meshes, choose another folder")
    path = export_scene(sc, out)
    click.echo(f"wrote {path} and {len(sc.objects)} mesh(es) in {path.parent / 'meshes'}")


def _simulate(scene_name: str, radar_name: str, seed: int, device, max_samples: int = 150_000,
              surface: str = "facets"):
    from .radar import check_materials_in_band, check_radar_for_scene, load_radar, simulate
    from .scene import load_scene

    rad = load_radar(radar_name)
    sc = load_scene(scene_name).around_radar(rad.positions_m)
    check_radar_for_scene(rad, sc.lower_m, sc.upper_m, source=radar_name)
    check_materials_in_band(sc, rad, source=scene_name)
    click.echo(sc.summary())
    click.echo(rad.summary())
    measurements = simulate(sc, rad, seed=seed, device=device, max_samples=max_samples, surface=surface,
                            progress=True)
    click.echo(measurements.metadata["surface_sampling"])
    return sc, measurements


def _image(measurements, lower_m, upper_m, voxel_m: float, out_image: Path, out_png: Path, method: str, device):
    from .geometry import Grid
    from .radar import matched_filter, write_image
    from .radar.imaging import imaging_method, require_image_memory
    from .viz import plot_mip

    grid = Grid.from_voxel(lower_m, upper_m, voxel_m)
    require_image_memory(measurements.acquisition.shape[0], grid)
    chosen = imaging_method(measurements.acquisition, method, device)
    why = {"fast": "range-profile back-projection", "exact": "the sensing operator's adjoint"}[chosen]
    click.echo(f"matched filter on {grid.shape} voxels of {voxel_m * 1e3:.2f} mm "
               f"({measurements.acquisition.num_measurements} measurements): {chosen} ({why}"
               f"{', chosen by --method auto' if method == 'auto' else ''}) on {device}")
    image = matched_filter(measurements, grid, method=chosen, device=device, progress=True)
    write_image(out_image, image)
    plot_mip(image.power().numpy(), grid.lower_m, grid.upper_m, out_png, title="matched-filter power (mean over views)")
    click.echo(f"wrote {out_image} and {out_png}")
    return image


def _device_option(default: str | None = "auto", text: str = "Where the tensors live: auto (CUDA when there is a GPU), cpu or cuda[:N]."):
    return click.option("--device", default=default, show_default=default is not None, help=text)


def _device(name: str | None):
    from .device import resolve_device

    return resolve_device(name)


def _exit_on_failures(failed: int) -> None:
    """Exit status 1 when some of a batch's jobs failed (they are rows of its summary), so
    that `rfsdf sweep ... && next-step` and a cluster's job runner notice."""
    if failed:
        sys.exit(1)


_BATCH_EXIT = ("Exit status: 0 when every job finished, 1 when some failed (each failure is a row of the summary "
               "with its error line), 2 when the input was refused before any job ran.")


_RAY_HELP = "Run as Ray tasks: bare --ray starts a local Ray instance, --ray ADDRESS joins a cluster."


@main.command("simulate", epilog="With --random: " + _BATCH_EXIT)
@click.argument("scene_name", required=False)
@click.option("--radar", "radar_name", default="near-77g", show_default=True, help="Radar preset or TOML file.")
@click.option("--out", type=click.Path(path_type=Path), required=True,
              help="Measurements file (.h5); with --random a dataset folder.")
@click.option("--seed", type=SEED, default=0, show_default=True,
              help="Noise and sampling seed (0 to 2^32-1); with --random the first scene's seed.")
@click.option("--random", "random_count", type=click.IntRange(1, 10**6), default=None,
              help="Instead of SCENE_NAME: this many seeded random scenes, each a scene file + measurements.")
@click.option("--workers", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="With --random: scenes at once in a local process pool.")
@click.option("--ray", "ray_address", is_flag=False, flag_value="local", default=None, help=_RAY_HELP)
@click.option("--max-samples", type=click.IntRange(1, 10**8), default=150_000, show_default=True,
              help="Most surface samples: the surface on lambda/3 cells when points that far apart would fit, "
                   "else facets sized to their range (a room), else refused with the count it needs.")
@click.option("--surface", type=click.Choice(["facets", "points"]), default="facets", show_default=True,
              help="How the surface is summed: flat facets of its zero set with their phase integrated (converged), "
                   "or points (a Monte Carlo quadrature, for comparison).")
@_device_option()
@_one_line_errors
def simulate_cmd(scene_name: str | None, radar_name: str, out: Path, seed: int, random_count: int | None,
                 workers: int, ray_address: str | None, max_samples: int, surface: str, device: str):
    """Simulate radar measurements of a scene and write them to an HDF5 file, or (--random N)
    a dataset of N random scenes: OUT/scene-NNNNN.toml + .h5 and OUT/dataset.json."""
    if (scene_name is None) == (random_count is None):
        raise ValueError("give a SCENE_NAME or --random N (not both)")
    if random_count is not None:
        from .dataset import check_dataset, simulate_dataset

        _device(device)  # refuse a device this machine lacks before any scene is drawn
        _refuse_overwriting_inputs(out, radar_name)
        click.echo(check_dataset(random_count, out, radar=radar_name, base_seed=seed))
        rows = simulate_dataset(random_count, out, radar=radar_name, base_seed=seed, workers=workers,
                                ray_address=ray_address, device=device, log=click.echo)
        failed = sum(row["status"] == "failed" for row in rows)
        click.echo(f"wrote {out / 'dataset.json'} ({len(rows) - failed} scenes, {failed} failed)")
        _exit_on_failures(failed)
        return
    from .radar import write_measurements

    _refuse_overwriting_inputs(out, scene_name, radar_name)
    _, measurements = _simulate(scene_name, radar_name, seed, _device(device), max_samples, surface)
    write_measurements(out, measurements)
    click.echo(f"wrote {out}")


def _image_box(data: Path, measurements, bounds: str | None, scene_name: str | None):
    """The box to image, from --bounds, else the bounds stored in the file, else a scene's."""
    from .radar import parse_bounds
    from .scene import load_scene

    if bounds is not None:
        return parse_bounds(bounds, "--bounds")
    if scene_name is None and "bounds_m" in measurements.metadata:
        return parse_bounds(measurements.metadata["bounds_m"], f"{data}: meta_bounds_m")
    name = scene_name or measurements.metadata.get("scene")
    if name is None:
        raise ValueError(f"{data}: no bounds or scene recorded in the file; pass --bounds XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX")
    sc = load_scene(name)
    return tuple(sc.lower_m), tuple(sc.upper_m)


def _voxel(voxel_m: float | None, lower, upper, voxels_per_edge: int = 64) -> float:
    """--voxel, or the box's longest edge / ``voxels_per_edge`` when unset."""
    import numpy as np

    return float(np.max(np.subtract(upper, lower))) / voxels_per_edge if voxel_m is None else voxel_m


_BOUNDS_HELP = "Box to image [m], XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (default: the bounds stored in DATA, else --scene's)."


@main.command("image")
@click.argument("data", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Image file (.h5); MIPs go beside it.")
@click.option("--voxel", "voxel_m", type=POSITIVE, default=None, help="Voxel size [m] (default: box extent / 64).")
@click.option("--bounds", default=None, help=_BOUNDS_HELP)
@click.option("--scene", "scene_name", default=None, help="Scene whose bounds to image.")
@click.option("--method", type=click.Choice(["auto", "exact", "fast"]), default="auto", show_default=True,
              help="exact adjoint, or fast range-profile back-projection (auto: fast from 32 frequencies, on a CPU).")
@_device_option()
@_one_line_errors
def image_cmd(data: Path, out: Path, voxel_m: float | None, bounds: str | None, scene_name: str | None, method: str,
              device: str):
    """Matched-filter image of a measurements file, plus maximum-intensity projections (PNG)."""
    from .radar import read_measurements

    device = _device(device)
    _refuse_overwriting_inputs(out, data, scene_name)
    _refuse_overwriting_inputs(out.with_suffix(".mip.png"), data, scene_name)
    measurements = read_measurements(data)
    lower, upper = _image_box(data, measurements, bounds, scene_name)
    _image(measurements, lower, upper, _voxel(voxel_m, lower, upper), out, out.with_suffix(".mip.png"), method, device)


@main.command("import-fmcw")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True)
@click.option("--conjugate", is_flag=True, help="Flip the IF phase sign (e.g. TI mmWave captures).")
@_one_line_errors
def import_fmcw_cmd(capture: Path, out: Path, conjugate: bool):
    """Convert a real FMCW capture (layout: docs/reference/formats.md) into a measurements file."""
    from .radar import import_fmcw, write_measurements

    _refuse_overwriting_inputs(out, capture)
    write_measurements(out, import_fmcw(capture, conjugate=conjugate))
    click.echo(f"wrote {out}")


@main.command("reconstruct")
@click.argument("data", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Run folder.")
@click.option("--image", "image_path", type=click.Path(path_type=Path), default=None,
              help="A matched-filter image of DATA (from `rfsdf image`): the fit uses its grid.")
@click.option("--bounds", default=None, help=_BOUNDS_HELP)
@click.option("--voxel", "voxel_m", type=POSITIVE, default=None, help="Voxel size [m] of the fit's images (default: extent / 50).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None, help="Reconstruction TOML.")
@click.option("--resume", is_flag=True, help="Continue the run in --out from its last checkpoint.")
@click.option("--reference", default=None, metavar="NAME=MATERIAL",
              help="Calibrate the gain with object NAME of --scene, known to be MATERIAL (overrides the config's "
                   "calibration.reference).")
@click.option("--gain", "gain_path", type=click.Path(path_type=Path), default=None,
              help="A gain file from `rfsdf calibrate` (a capture of a known target by the same radar): the "
                   "materials are then absolute, with no reference in the scene.")
@click.option("--scene", "scene_name", default=None,
              help="Scene file or preset that places the calibration reference (only that object is used); with "
                   "--model primitive, the true scene, to report each free parameter's truth.")
@click.option("--model", "model_kind", type=click.Choice(["neural", "primitive", "hybrid"]), default="neural",
              show_default=True,
              help="neural: the GeRaF fit (with --fit-to profiles, the room-scale network from a start model); "
                   "primitive: the free parameters of --scene-model; hybrid: those plus a bounded neural residual "
                   "(range profiles only).")
@click.option("--scene-model", "scene_model_path", type=click.Path(path_type=Path), default=None,
              help="With --model primitive or hybrid: a scene file whose parameters may be free tables "
                   "(docs/reference/formats.md); with --model neural --fit-to profiles: the network's start.")
@click.option("--steps", type=click.IntRange(1, 100_000), default=150, show_default=True,
              help="With --model primitive: gradient steps; hybrid: as many again for its residual; neural --fit-to "
                   "profiles: the profile fit's steps.")
@click.option("--start-offset", type=POSITIVE, default=0.15, show_default=True,
              help="With --model primitive and no --scene-model: start from --scene with every length free and moved "
                   "by up to this much [m] (seeded).")
@click.option("--free-materials", is_flag=True,
              help="With --model primitive/hybrid and no --scene-model: fit every object's material of --scene too "
                   "(undecided among metal, glass, concrete, plasterboard, wood), but its calibration_reference.")
@click.option("--fit-to", "fit_to", type=click.Choice(["images", "profiles"]), default="images", show_default=True,
              help="The data term. images: the coherent renderer on the image grid (small scenes); profiles: each "
                   "view's range profile, rendered by ray votes (rooms; with --model neural, the network "
                   "distilled from --scene-model or --scene).")
@_device_option(None, "auto, cpu or cuda[:N] for the fit and its images (default: the config's train.device, auto).")
@_one_line_errors
def reconstruct_cmd(data: Path, out: Path, image_path: Path | None, bounds: str | None, voxel_m: float | None,
                    config_path: Path | None, resume: bool, reference: str | None, scene_name: str | None,
                    model_kind: str, scene_model_path: Path | None, steps: int, start_offset: float,
                    free_materials: bool, fit_to: str, device: str | None, gain_path: Path | None):
    """Fit a neural SDF to radar data (GeRaF): checkpoints, log.csv, config.toml, mesh.ply;
    or (--model primitive) a scene model's free parameters: primitive.json,
    fitted-scene.toml, mesh.ply; or (--model neural --fit-to profiles) a room's neural
    model from a start model: neural.json, mesh.ply.

    No scene is needed: the box comes from --image, --bounds, or the bounds stored in DATA.
    A calibration reference (--reference, or calibration.reference in --config) needs the
    --scene that places it; its result goes to calibration.json."""
    if model_kind != "neural":
        _refuse_options(f"--model {model_kind}", ("--image", image_path), ("--config", config_path),
                        ("--resume", resume), ("--reference", reference), ("--gain", gain_path))
        if scene_model_path is None and scene_name is None:
            raise click.UsageError(f"--model {model_kind} needs --scene-model, or --scene to start from its truth")
        if model_kind == "hybrid" and fit_to != "profiles":
            raise click.UsageError("--model hybrid fits range profiles only: add --fit-to profiles")
        if free_materials and scene_model_path is not None:
            raise click.UsageError("--free-materials: only without --scene-model (a model file marks its own)")
        _reconstruct_primitive(data, out, bounds, voxel_m, scene_model_path, scene_name, steps, start_offset, fit_to,
                               _device(device or "auto"), hybrid=model_kind == "hybrid", free_materials=free_materials)
        return
    if fit_to == "profiles":
        _refuse_options("--model neural --fit-to profiles", ("--image", image_path), ("--config", config_path),
                        ("--resume", resume), ("--reference", reference), ("--gain", gain_path),
                        ("--free-materials", free_materials))
        if scene_model_path is None and scene_name is None:
            raise click.UsageError("--model neural --fit-to profiles needs --scene-model, or --scene to start from "
                                   "its truth")
        _reconstruct_neural_profiles(data, out, bounds, scene_model_path, scene_name, steps, start_offset)
        return
    if scene_model_path is not None or free_materials:
        raise click.UsageError("--scene-model and --free-materials: only with --model primitive or hybrid, or "
                               "--fit-to profiles")
    from .geometry import Grid
    from .mesh import export_mesh, extract_mesh
    from .radar import read_image, read_measurements
    from .recon import Problem, Trainer, load_recon_config
    from .recon.checkpoint import CHECKPOINT_NAME, read_checkpoint

    _refuse_overwriting_inputs(out, data, image_path, config_path)
    config = load_recon_config(config_path if config_path or not resume else _run_config(out))
    if device is not None:
        config = config.on_device(_device(device))
    if reference is not None:
        config = _with_reference(config, reference, config_path)
    if resume and (out / CHECKPOINT_NAME).exists():
        read_checkpoint(out / CHECKPOINT_NAME, "cpu")  # refuse a bad checkpoint before the images are made
    measurements = read_measurements(data)
    gain = None
    if gain_path is not None:
        from .radar.capture_gain import read_capture_gain

        if config.calibration.reference is not None or not config.field.materials:
            raise click.UsageError("--gain: with a material head and no calibration reference (the reference "
                                   "calibrates the gain itself)")
        measured = read_capture_gain(gain_path)
        measured.require_radar(measurements.acquisition, f"{gain_path} for {data}")
        gain = measured.gain
    calibrator = None
    if config.calibration.reference is not None:
        if scene_name is None:
            raise click.UsageError("a calibration reference needs --scene, the scene file that places it")
        from .material_estimates import scene_reference
        from .scene import load_scene

        calibrator = scene_reference(load_scene(scene_name), config.calibration, measurements.acquisition,
                                     source=f"{scene_name}: calibration.reference {config.calibration.reference}")
    if image_path is not None:
        image = read_image(image_path)
        if image.per_view.shape[0] != measurements.acquisition.shape[0]:
            raise ValueError(f"{image_path}: per_view: the image has {image.per_view.shape[0]} views, "
                             f"{data} has {measurements.acquisition.shape[0]}")
        grid = image.grid
    else:
        lower, upper = _image_box(data, measurements, bounds, None)
        grid = Grid.from_voxel(lower, upper, _voxel(voxel_m, lower, upper, voxels_per_edge=50))
    known = None if calibrator is None else calibrator.labels(tuple(config.field.materials))
    trainer = Trainer(Problem(measurements, grid, str(data), gain=gain, known_materials=known), config, out,
                      progress=True)
    fit = trainer.fit(resume=resume)
    mesh = extract_mesh(fit.field.sdf, grid.lower_m, grid.upper_m, config.train.mesh_resolution, device=trainer.device)
    click.echo(f"wrote {export_mesh(mesh, out / 'mesh.ply')} ({len(mesh.faces)} faces)")
    if calibrator is not None:
        from .jsonio import write_json
        from .recon.calibration import CALIBRATION_NAME, check_reference

        calibration = check_reference(trainer, calibrator)
        write_json(out / CALIBRATION_NAME, calibration.as_dict())
        click.echo(calibration.text())
        if calibration.warning() is not None:
            click.echo(f"warning: {calibration.warning()}", err=True)


def _reconstruct_primitive(data: Path, out: Path, bounds: str | None, voxel_m: float | None, model_path: Path | None,
                           scene_name: str | None, steps: int, start_offset: float, fit_to: str, device, *,
                           hybrid: bool = False, free_materials: bool = False) -> None:
    """``reconstruct --model primitive|hybrid``: fit the model (``model_path``, else the scene
    ``scene_name`` with every length, and with ``free_materials`` every material, free,
    ``start_offset`` off) to the images or the range
    profiles (``fit_to``; the hybrid: profiles, then its residual, rfsdf.recon.hybrid), write
    its parameters, the fitted scene file and its mesh into ``out``."""
    from .geometry import Grid
    from .jsonio import write_json
    from .mesh import export_mesh
    from .radar import read_measurements
    from .recon import Problem
    from .recon.hybrid import fit_hybrid_profiles, project_mesh, residual_amplitude_m
    from .recon.primitive import fit_primitive, material_text
    from .recon.range_profile import fit_primitive_profiles
    from .scene import Scene
    from .scene_model import analytic_spec

    _refuse_overwriting_inputs(out, data, model_path)
    measurements = read_measurements(data)
    truth_scene, model, (lower, upper) = _start_model(data, measurements, bounds, model_path, scene_name,
                                                      start_offset, free_materials)
    truth = analytic_spec(truth_scene) if truth_scene is not None else None
    model.require_free()
    model_lower, model_upper = model.spec.bounds.lower_m, model.spec.bounds.upper_m
    if hybrid:
        amplitude = residual_amplitude_m(measurements.acquisition.bandwidth_hz)
        fit = fit_hybrid_profiles(measurements, model, amplitude_m=amplitude, lower_m=model_lower,
                                  upper_m=model_upper, steps=steps, residual_steps=steps, progress=True)
    elif fit_to == "profiles":
        fit = fit_primitive_profiles(measurements, model, steps=steps, progress=True)
    else:
        grid = Grid.from_voxel(lower, upper, _voxel(voxel_m, lower, upper, voxels_per_edge=50))
        fit = fit_primitive(Problem(measurements, grid, str(data)), model, steps=steps, device=device, progress=True)
    fitted = Scene(fit.fitted_spec(), model.base_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "primitive.json", fit.as_dict(truth))
    fitted.write_toml(out / "fitted-scene.toml")
    mesh = fitted.ground_truth_mesh()
    if hybrid:
        mesh = project_mesh(fit.field.frozen_sdf(), mesh)
    click.echo(f"wrote {out / 'primitive.json'}, {out / 'fitted-scene.toml'} and "
               f"{export_mesh(mesh, out / 'mesh.ply')} ({len(mesh.faces)} faces)")
    for row in fit.free_table(truth):
        truth_text = "" if row["truth"] is None else f"  truth {_mm(row['truth'])}"
        click.echo(f"  {row['name']:<40} start {_mm(row['start'])}  fitted {_mm(row['fitted'])}{truth_text}")
    for row in fit.material_table(truth):
        click.echo(f"  material: {material_text(row)}")
    if fit.calibration is not None:
        click.echo(f"  materials read from the data at the fitted model; gain: {fit.calibration}")


def _start_model(data: Path, measurements, bounds: str | None, model_path: Path | None, scene_name: str | None,
                 start_offset: float, free_materials: bool = False):
    """(the true scene or None, the start model, the data's box (lower, upper) [m]) of a model
    fit: the file ``model_path``, else the scene ``scene_name`` with every length free,
    ``start_offset`` off (seed 0); refused in one line unless it overlaps the data's box."""
    from .scene import load_scene
    from .scene_model import SceneModel, load_scene_model

    import torch

    acq = measurements.acquisition
    # the true scene as the data's radar sees it (a closed room mesh around it: a shell)
    truth_scene = (load_scene(scene_name).around_radar(torch.cat([acq.tx_m, acq.rx_m], 1).reshape(-1, 3))
                   if scene_name is not None else None)
    model = (load_scene_model(model_path) if model_path is not None
             else SceneModel.from_scene(truth_scene, start_offset, seed=0, free_materials=free_materials))
    lower, upper = _image_box(data, measurements, bounds, None)
    model.require_overlap(lower, upper, "the data's")
    return truth_scene, model, (lower, upper)


def _reconstruct_neural_profiles(data: Path, out: Path, bounds: str | None, model_path: Path | None,
                                 scene_name: str | None, steps: int, start_offset: float) -> None:
    """``reconstruct --model neural --fit-to profiles``: the room-scale neural model
    (rfsdf.recon.neural_profiles) distilled from the start model (``model_path``, or the
    scene ``scene_name`` ``start_offset`` off), fitted to the range profiles for ``steps``,
    meshed near its zero set at one range resolution: ``out``/neural.json and mesh.ply."""
    import dataclasses

    from .jsonio import write_json
    from .mesh import export_mesh
    from .radar import read_measurements
    from .recon.neural_profiles import NeuralProfileSettings, fit_neural_model

    _refuse_overwriting_inputs(out, data, model_path)
    measurements = read_measurements(data)
    _, model, _ = _start_model(data, measurements, bounds, model_path, scene_name, start_offset)
    settings = dataclasses.replace(NeuralProfileSettings(), steps=steps)
    fitted = fit_neural_model(measurements, model, settings=settings, progress=True)
    out.mkdir(parents=True, exist_ok=True)
    start = {"scene_model": str(model_path)} if model_path is not None else {"scene": scene_name,
                                                                             "start_offset_m": start_offset}
    write_json(out / "neural.json", {**fitted.as_dict(), "losses": fitted.fit.losses, "start": start,
                                     "settings": dataclasses.asdict(settings)})
    click.echo(f"wrote {out / 'neural.json'} and {export_mesh(fitted.mesh, out / 'mesh.ply')} "
               f"({len(fitted.mesh.faces)} faces)")
    click.echo(f"  {fitted.summary()}")


def _refuse_options(context: str, *options) -> None:
    """click.UsageError naming each of ``options`` ((flag, value) pairs) that was given."""
    given = [flag for flag, value in options if value]
    if given:
        raise click.UsageError(f"{', '.join(given)}: not for {context}")


def _mm(values: list[float]) -> str:
    return "[" + ", ".join(f"{v * 1e3:.1f}" for v in values) + "] mm"


def _with_reference(config, reference: str, config_path: Path | None):
    """``config`` with calibration.reference set, checked as if the file had said it."""
    from .config import validate
    from .recon.config import ReconConfig

    merged = config.model_dump()
    merged["calibration"]["reference"] = reference
    return validate(ReconConfig, merged, "--reference" if config_path is None else f"{config_path} with --reference")


def _run_config(run: Path) -> Path | None:
    from .recon.checkpoint import CONFIG_NAME

    path = run / CONFIG_NAME
    return path if path.exists() else None


@main.command("mesh")
@click.argument("run", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Mesh file (.ply, .obj, .stl).")
@click.option("--resolution", type=click.IntRange(2, 1024), default=128, show_default=True,
              help="Voxels along the longest edge (2 to 1024).")
@_device_option()
@_one_line_errors
def mesh_cmd(run: Path, out: Path, resolution: int, device: str):
    """Mesh the SDF of a reconstruction run by marching cubes."""
    from .mesh import export_mesh, extract_mesh
    from .recon import load_field
    from .recon.checkpoint import CHECKPOINT_NAME, CONFIG_NAME

    device = _device(device)
    _refuse_overwriting_inputs(out, run / CHECKPOINT_NAME, run / CONFIG_NAME)
    field = load_field(run, device)
    mesh = extract_mesh(field.sdf, field.lower_m, field.upper_m, resolution, device=device, progress=True)
    click.echo(f"wrote {export_mesh(mesh, out)} ({len(mesh.faces)} faces)")


@main.command("evaluate")
@click.argument("mesh_path", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", required=True, help="Ground-truth scene preset or TOML file.")
@click.option("--threshold", "threshold_m", type=POSITIVE, default=0.005, show_default=True, help="F-score distance [m].")
@click.option("--json", "as_json", is_flag=True, help="Print the metrics as JSON.")
@_one_line_errors
def evaluate_cmd(mesh_path: Path, scene_name: str, threshold_m: float, as_json: bool):
    """Compare a mesh with a scene's true surfaces: Chamfer, F-score, normals, Hausdorff, IoU."""
    import trimesh

    from .jsonio import to_json
    from .limits import input_file
    from .metrics import evaluate_mesh
    from .scene import load_scene

    metrics = evaluate_mesh(trimesh.load(input_file(mesh_path), force="mesh"), load_scene(scene_name), threshold_m=threshold_m)
    if as_json:
        click.echo(to_json(metrics.as_dict()))
    else:
        for key, value in metrics.as_dict().items():
            click.echo(f"{key:>20}  {value if value is None else f'{value:.4g}'}")


@main.command()
@click.option("--out", type=click.Path(path_type=Path), default=Path("rfsdf-demo"), show_default=True)
@click.option("--scene", "scene_name", default="objects", show_default=True, help="Scene preset or TOML file.")
@click.option("--radar", "radar_name", default="near-77g", show_default=True, help="Radar preset or TOML file.")
@click.option("--quick", is_flag=True, help="A tiny, seconds-long version (coarse grid, few steps): a smoke test.")
@click.option("--no-materials", is_flag=True,
              help="Fit a free reflectivity instead of the material head (no material estimates).")
@click.option("--reference", default=None, metavar="NAME=MATERIAL",
              help="Calibrate the gain with the scene's object NAME, known to be MATERIAL (e.g. metal_ball=metal); "
                   "default: the scene's calibration_reference, if it names one.")
@click.option("--relative", is_flag=True,
              help="No calibration reference: one gain fitted per step, materials only relative to each other.")
@_device_option()
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
@_one_line_errors
def demo(out: Path, scene_name: str, radar_name: str, quick: bool, no_materials: bool, reference: str | None,
         relative: bool, device: str, model_kind: str, scene_model_path: Path | None, start_offset: float | None,
         seed: int | None, free_materials: bool, max_samples: int | None):
    """Simulate, image, reconstruct, mesh and evaluate a scene; all artefacts go to --out.

    Ends with a table of metrics for the GeRaF reconstruction and the baselines, and what
    the material head says each object is made of. A second run with the same --out
    continues (or reuses) the fit. With --model primitive, hybrid or all (rooms), a table
    of the models side by side instead.
    """
    import dataclasses

    from .demo import QUICK, DemoSettings, metrics_table, run_demo
    from .config import merge_tables

    if relative and reference is not None:
        raise click.UsageError("--relative and --reference exclude each other")
    if model_kind != "neural":
        neural_only = [name for name, given in (("--no-materials", no_materials), ("--reference", reference),
                                                ("--relative", relative)) if given]
        if neural_only:
            raise click.UsageError(f"{', '.join(neural_only)}: only with --model neural")
        if free_materials and scene_model_path is not None:
            raise click.UsageError("--free-materials: only without --scene-model (a model file marks its own)")
        _model_demo(out, scene_name, radar_name, quick, model_kind, scene_model_path,
                    0.15 if start_offset is None else start_offset, seed or 0, free_materials, max_samples, device)
        return
    given = [name for name, value in (("--scene-model", scene_model_path), ("--seed", seed),
                                      ("--start-offset", start_offset), ("--free-materials", free_materials or None),
                                      ("--max-samples", max_samples)) if value is not None]
    if given:
        raise click.UsageError(f"{', '.join(given)}: only with --model primitive, hybrid or all")
    settings = dataclasses.replace(QUICK if quick else DemoSettings(), scene=scene_name, radar=radar_name,
                                   relative=relative)
    if no_materials:
        settings = dataclasses.replace(settings, recon=merge_tables(settings.recon, {"field": {"materials": []}}))
    if reference is not None:
        settings = dataclasses.replace(settings, recon=merge_tables(settings.recon,
                                                                    {"calibration": {"reference": reference}}))
    from .report import write_report

    result = run_demo(out, settings, device=device, log=click.echo)
    click.echo(metrics_table(result))
    click.echo(f"total {result.timings_s['total_s']:.0f} s; every artefact and metrics.json are in {out}")
    click.echo(f"report (open in a browser): {write_report(out)}")


def _model_demo(out: Path, scene_name: str, radar_name: str, quick: bool, model_kind: str,
                scene_model_path: Path | None, start_offset: float, seed: int, free_materials: bool,
                max_samples: int | None, device: str) -> None:
    """``demo --model primitive|hybrid|all``: the scene models side by side (rfsdf.model_demo);
    ``device`` runs the simulation."""
    import dataclasses

    from .model_demo import MODELS, QUICK_MODELS, ModelDemoSettings, models_table, run_model_demo
    from .report import write_report

    settings = dataclasses.replace(QUICK_MODELS if quick else ModelDemoSettings(), scene=scene_name, radar=radar_name,
                                   start_offset_m=start_offset, seed=seed, free_materials=free_materials,
                                   scene_model=None if scene_model_path is None else str(scene_model_path))
    if max_samples is not None:
        settings = dataclasses.replace(settings, max_surface_samples=max_samples)
    result = run_model_demo(out, settings, MODELS if model_kind == "all" else (model_kind,), device=device,
                            log=click.echo)
    click.echo(models_table(result))
    click.echo(f"total {result['timings_s']['total_s']:.0f} s; every artefact and metrics.json are in {out}")
    click.echo(f"report (open in a browser): {write_report(out)}")


@main.command("calibrate")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", required=True,
              help="The capture's scene: the known target (a metal sphere or plate) where it stood, with its material.")
@click.option("--out", type=click.Path(path_type=Path), required=True, help="The gain file (JSON) reconstruct --gain reads.")
@_one_line_errors
def calibrate_cmd(capture: Path, scene_name: str, out: Path):
    """Measure the radar's gain from CAPTURE, a capture of a known target: against the
    simulator's noise-free data of --scene through the capture's own antennas, frequencies
    and views. `reconstruct --gain OUT` then reads materials absolutely from data of the same
    radar and settings (rfsdf.radar.capture_gain)."""
    from .jsonio import write_json
    from .radar import read_measurements
    from .radar.capture_gain import capture_gain
    from .scene import load_scene

    _refuse_overwriting_inputs(out, capture, scene_name)
    measured = capture_gain(read_measurements(capture), load_scene(scene_name), capture_name=str(capture))
    write_json(out, measured.as_dict())
    click.echo(f"gain {measured.gain:.6g} (scene {measured.scene!r} explains {measured.explained:.1%} of the "
               f"capture's energy); wrote {out}")


@main.command("materials")
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--data", "data_path", type=click.Path(path_type=Path), default=None,
              help="For a run folder: the measurements it was fitted on (default: the file the checkpoint names).")
@click.option("--scene", "scene_name", default=None, help="For a run folder: the true scene, for a row per object.")
@_one_line_errors
def materials_cmd(folder: Path, data_path: Path | None, scene_name: str | None):
    """Print what each surface of a finished run is made of: per object (with the truth) and
    per connected component, class probabilities, eps' with its interval, observed share.

    FOLDER is a demo folder (read from its metrics.json) or a `reconstruct` run folder (its
    field's material head on its mesh.ply, observed by the views of --data)."""
    from .material_estimates import run_materials

    click.echo(run_materials(folder, data_path=data_path, scene_name=scene_name))


@main.command("report")
@click.argument("folder", type=click.Path(path_type=Path))
@_one_line_errors
def report_cmd(folder: Path):
    """Write FOLDER/report.html for a demo folder or a reconstruction run folder: scene, radar,
    images, slices through each object, training curves, metrics, and 3-D views of the errors."""
    from .report import write_report

    click.echo(f"wrote {write_report(folder)}")


@main.command("view")
@click.argument("mesh_path", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", default=None, help="Colour the mesh by its signed distance to this scene's surfaces.")
@click.option("--out", type=click.Path(path_type=Path), default=None, help="HTML file (default: MESH with .html).")
@_one_line_errors
def view_cmd(mesh_path: Path, scene_name: str | None, out: Path | None):
    """Write an interactive 3-D view of a mesh file (PLY, OBJ, STL) as a self-contained HTML page."""
    from .report import write_view

    out = out or mesh_path.with_suffix(".html")
    _refuse_overwriting_inputs(out, mesh_path)
    click.echo(f"wrote {write_view(mesh_path, out, scene_name=scene_name)}")


@main.command("sweep", epilog=_BATCH_EXIT)
@click.argument("sweep_file", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Folder: one run folder per job + summary.")
@click.option("--workers", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="Jobs at once in the local process pool (the cores are shared between them).")
@click.option("--ray", "ray_address", is_flag=False, flag_value="local", default=None, help=_RAY_HELP)
@click.option("--max-jobs", type=click.IntRange(1, 10**7), default=5000, show_default=True,
              help="Refuse a sweep file that asks for more jobs (counted before anything is expanded).")
@_one_line_errors
def sweep_cmd(sweep_file: Path, out: Path, workers: int, ray_address: str | None, max_jobs: int):
    """Run every job of a sweep file (scene, radar, reconstruction settings, seed), each as
    `rfsdf demo` into its own folder; write summary.csv, summary.json and summary.png.
    Every job's settings are checked before the first runs; a rerun skips finished jobs and
    resumes unfinished fits."""
    from .sweep import load_sweep, run_sweep

    jobs = load_sweep(sweep_file, max_jobs=max_jobs)
    _refuse_overwriting_inputs(out, sweep_file)
    where = f"Ray ({ray_address})" if ray_address else f"{workers} local worker{'s' * (workers > 1)}"
    click.echo(f"{len(jobs)} jobs on {where} -> {out}")
    rows = run_sweep(jobs, out, workers=workers, ray_address=ray_address, log=click.echo)
    failed = sum(row["status"] == "failed" for row in rows)
    click.echo(f"wrote {out / 'summary.csv'}, summary.json, summary.png ({len(rows) - failed} finished, {failed} failed)")
    _exit_on_failures(failed)


@main.command("study")
@click.argument("name", required=False)
@click.option("--out", type=click.Path(path_type=Path), default=Path("studies"), show_default=True,
              help="Folder for NAME.json and NAME.png.")
@click.option("--quick", is_flag=True, help="The test-suite size: seconds, same claims, coarser numbers.")
@click.option("--list", "list_studies", is_flag=True, help="Name every study with one line each.")
@_one_line_errors
def study_cmd(name: str | None, out: Path, quick: bool, list_studies: bool):
    """Reproduce one claim behind the method on the library itself: a figure (PNG) and its
    numbers (JSON); docs/studies/NAME.md says what they show."""
    from .studies import STUDIES, run_study

    if list_studies:
        width = max(map(len, STUDIES))
        for study in STUDIES.values():
            click.echo(f"{study.NAME:<{width}}  {study.SUMMARY}")
        return
    if name not in STUDIES:
        raise ValueError(f"unknown study {name!r}; known: {', '.join(STUDIES)} (rfsdf study --list)")
    json_path, png_path = run_study(STUDIES[name], out, quick=quick)
    click.echo(f"wrote {json_path} and {png_path}")
