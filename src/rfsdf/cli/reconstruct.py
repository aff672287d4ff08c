"""rfsdf reconstruct (neural, primitive, hybrid), mesh, evaluate, materials."""

from __future__ import annotations

from pathlib import Path

import click

from .app import (
    BOUNDS_HELP,
    device_named,
    device_option,
    image_box,
    main,
    one_line_errors,
    POSITIVE,
    refuse_overwriting_inputs,
    voxel_size,
)


@main.command("reconstruct")
@click.argument("data", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Run folder.")
@click.option("--image", "image_path", type=click.Path(path_type=Path), default=None,
              help="A matched-filter image of DATA (from `rfsdf image`): the fit uses its grid.")
@click.option("--bounds", default=None, help=BOUNDS_HELP)
@click.option("--voxel", "voxel_m", type=POSITIVE, default=None, help="Voxel size [m] of the fit's images (default: extent / 50).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None, help="Reconstruction TOML.")
@click.option("--resume", is_flag=True, help="Continue the run in --out from its last checkpoint.")
@click.option("--reference", default=None, metavar="NAME=MATERIAL",
              help="Calibrate the gain with object NAME of --scene, known to be MATERIAL (overrides the config's "
                   "calibration.reference).")
@click.option("--gain", "gain_path", type=click.Path(path_type=Path), default=None,
              help="A gain file from `rfsdf calibrate` (a capture of a known target by the same radar): the fit "
                   "stays relative and `rfsdf materials OUT` reads the materials in this gain (absolute |Gamma|), "
                   "with no reference in the scene (config: calibration.gain).")
@click.option("--scene", "scene_name", default=None,
              help="Scene file or preset that places the calibration reference (only that object is used); with "
                   "--model primitive, the true scene, to report each free parameter's truth.")
@click.option("--through", "through_name", default=None,
              help="With --model neural: a scene file or preset of what stands, known, between the radar and the "
                   "objects (the box they are packed in): the fit sees the objects through its dielectrics, T^2 and "
                   "the slabs' delay on every line of sight; objects are sought away from its walls and, where it is "
                   "closed, inside it. Its own return must be out of DATA (--background).")
@click.option("--background", "background_path", type=click.Path(path_type=Path), default=None,
              help="Measurements of the scene without the objects (the empty box, captured or simulated with the "
                   "same acquisition), subtracted from DATA before anything else.")
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
@click.option("--beams", is_flag=True,
              help="With --fit-to profiles: compare each view's range profiles per beam of its array, summed "
                   "coherently over its channels, not their mean (walls a few dB over the noise).")
@click.option("--transmission", is_flag=True,
              help="With --fit-to profiles: the model's rays go on through dielectric objects (ITU-R P.2040 slabs), "
                   "so walls behind glass or plasterboard vote; metal still stops them.")
@device_option(None, "auto, cpu or cuda[:N] for the fit and its images (default: the config's train.device, auto).")
@one_line_errors
def reconstruct_cmd(data: Path, out: Path, image_path: Path | None, bounds: str | None, voxel_m: float | None,
                    config_path: Path | None, resume: bool, reference: str | None, scene_name: str | None,
                    model_kind: str, scene_model_path: Path | None, steps: int, start_offset: float,
                    free_materials: bool, fit_to: str, device: str | None, gain_path: Path | None,
                    through_name: str | None, background_path: Path | None, beams: bool, transmission: bool):
    """Fit a neural SDF to radar data (GeRaF): checkpoints, log.csv, config.toml, mesh.ply;
    or (--model primitive) a scene model's free parameters: primitive.json,
    fitted-scene.toml, mesh.ply; or (--model neural --fit-to profiles) a room's neural
    model from a start model: neural.json, mesh.ply.

    No scene is needed: the box comes from --image, --bounds, or the bounds stored in DATA.
    A calibration reference (--reference, or calibration.reference in --config) needs the
    --scene that places it; its result goes to calibration.json. Objects in a known box:
    --background (the empty box's measurements) and --through (the box's scene)."""
    seen_through = (("--through", through_name), ("--background", background_path))
    for flag, given in (("--beams", beams), ("--transmission", transmission)):
        if given and fit_to != "profiles":
            raise click.UsageError(f"{flag}: only with --fit-to profiles")
    profile = {"beams": beams, "transmission": transmission}  # rfsdf.recon.range_profile.ProfileSettings
    if model_kind != "neural":
        _refuse_options(f"--model {model_kind}", ("--image", image_path), ("--config", config_path),
                        ("--resume", resume), ("--reference", reference), ("--gain", gain_path), *seen_through)
        if scene_model_path is None and scene_name is None:
            raise click.UsageError(f"--model {model_kind} needs --scene-model, or --scene to start from its truth")
        if model_kind == "hybrid" and fit_to != "profiles":
            raise click.UsageError("--model hybrid fits range profiles only: add --fit-to profiles")
        if free_materials and scene_model_path is not None:
            raise click.UsageError("--free-materials: only without --scene-model (a model file marks its own)")
        _reconstruct_primitive(data, out, bounds, voxel_m, scene_model_path, scene_name, steps, start_offset, fit_to,
                               device_named(device or "auto"), hybrid=model_kind == "hybrid", free_materials=free_materials,
                               profile=profile)
        return
    if fit_to == "profiles":
        _refuse_options("--model neural --fit-to profiles", ("--image", image_path), ("--config", config_path),
                        ("--resume", resume), ("--reference", reference), ("--gain", gain_path),
                        ("--free-materials", free_materials), *seen_through)
        if scene_model_path is None and scene_name is None:
            raise click.UsageError("--model neural --fit-to profiles needs --scene-model, or --scene to start from "
                                   "its truth")
        _reconstruct_neural_profiles(data, out, bounds, scene_model_path, scene_name, steps, start_offset, profile)
        return
    if scene_model_path is not None or free_materials:
        raise click.UsageError("--scene-model and --free-materials: only with --model primitive or hybrid, or "
                               "--fit-to profiles")
    from ..geometry import Grid
    from ..mesh import export_mesh, extract_mesh
    from ..radar import read_image, read_measurements
    from ..recon import Problem, Trainer, load_recon_config
    from ..recon.checkpoint import CHECKPOINT_NAME, read_checkpoint

    refuse_overwriting_inputs(out, data, image_path, config_path, background_path)
    config = load_recon_config(config_path if config_path or not resume else _run_config(out))
    if device is not None:
        config = config.on_device(device_named(device))
    if reference is not None:
        config = _with_reference(config, reference, config_path)
    if resume and (out / CHECKPOINT_NAME).exists():
        read_checkpoint(out / CHECKPOINT_NAME, "cpu")  # refuse a bad checkpoint before the images are made
    measurements = read_measurements(data)
    if background_path is not None:
        background = read_measurements(background_path)  # names its file when unreadable
        try:
            measurements = measurements.less(background)
        except ValueError as error:
            raise ValueError(f"{background_path}: {error}") from None
    through = None
    if through_name is not None:
        from ..scene import load_scene

        through = load_scene(through_name)
    if gain_path is not None:
        from ..radar.capture_gain import read_capture_gain

        if config.calibration.reference is not None or not config.field.materials:
            raise click.UsageError("--gain: with a material head and no calibration reference (the reference "
                                   "calibrates the gain itself)")
        measured = read_capture_gain(gain_path)
        measured.require_radar(measurements.acquisition, f"{gain_path} for {data}")
        given = config.calibration.model_copy(update={"gain": measured.gain})  # applied after the relative fit
        config = config.model_copy(update={"calibration": given})
    calibrator = None
    if config.calibration.reference is not None:
        if scene_name is None:
            raise click.UsageError("a calibration reference needs --scene, the scene file that places it")
        from ..material_estimates import scene_reference
        from ..scene import load_scene

        calibrator = scene_reference(load_scene(scene_name), config.calibration, measurements.acquisition,
                                     source=f"{scene_name}: calibration.reference {config.calibration.reference}")
    if image_path is not None:
        image = read_image(image_path)
        if image.per_view.shape[0] != measurements.acquisition.num_views:
            raise ValueError(f"{image_path}: per_view: the image has {image.per_view.shape[0]} views, "
                             f"{data} has {measurements.acquisition.num_views}")
        grid = image.grid
    else:
        lower, upper = image_box(data, measurements, bounds, None)
        grid = Grid.from_voxel(lower, upper, voxel_size(voxel_m, lower, upper, voxels_per_edge=50))
    known = None if calibrator is None else calibrator.labels(tuple(config.field.materials))
    trainer = Trainer(Problem(measurements, grid, str(data), known_materials=known, through=through),
                      config, out, progress=True)
    fit = trainer.fit(resume=resume)
    mesh = extract_mesh(fit.field.sdf, grid.lower_m, grid.upper_m, config.train.mesh_resolution, device=trainer.device)
    click.echo(f"wrote {export_mesh(mesh, out / 'mesh.ply')} ({len(mesh.faces)} faces)")
    if calibrator is not None:
        from ..jsonio import write_json
        from ..recon.calibration import CALIBRATION_NAME, check_reference

        calibration = check_reference(trainer, calibrator)
        write_json(out / CALIBRATION_NAME, calibration.as_dict())
        click.echo(calibration.text())
        if calibration.warning() is not None:
            click.echo(f"warning: {calibration.warning()}", err=True)


def _reconstruct_primitive(data: Path, out: Path, bounds: str | None, voxel_m: float | None, model_path: Path | None,
                           scene_name: str | None, steps: int, start_offset: float, fit_to: str, device, *,
                           hybrid: bool = False, free_materials: bool = False, profile: dict) -> None:
    """``reconstruct --model primitive|hybrid``: fit the model (``model_path``, else the scene
    ``scene_name`` with every length, and with ``free_materials`` every material, free,
    ``start_offset`` off) to the images or the range
    profiles (``fit_to``, with the ``profile`` settings: ProfileSettings' ``beams`` and
    ``transmission``; the hybrid: profiles, then its residual, rfsdf.recon.hybrid), write its
    parameters, the fitted scene file and its mesh into ``out``."""
    from ..geometry import Grid
    from ..jsonio import write_json
    from ..mesh import export_mesh
    from ..radar import read_measurements
    from ..recon import Problem
    from ..recon.hybrid import fit_hybrid_profiles, project_mesh, residual_amplitude_m
    from ..recon.primitive import fit_primitive, material_text
    from ..recon.range_profile import ProfileSettings, fit_primitive_profiles
    from ..scene import Scene
    from ..scene_model import analytic_spec

    refuse_overwriting_inputs(out, data, model_path)
    measurements = read_measurements(data)
    truth_scene, model, (lower, upper) = _start_model(data, measurements, bounds, model_path, scene_name,
                                                      start_offset, free_materials)
    truth = analytic_spec(truth_scene) if truth_scene is not None else None
    model.require_free()
    model_lower, model_upper = model.spec.bounds.lower_m, model.spec.bounds.upper_m
    if hybrid:
        amplitude = residual_amplitude_m(measurements.acquisition.bandwidth_hz)
        fit = fit_hybrid_profiles(measurements, model, amplitude_m=amplitude, lower_m=model_lower,
                                  upper_m=model_upper, steps=steps, residual_steps=steps,
                                  settings=ProfileSettings(**profile), progress=True)
    elif fit_to == "profiles":
        fit = fit_primitive_profiles(measurements, model, steps=steps, settings=ProfileSettings(**profile),
                                     progress=True)
    else:
        grid = Grid.from_voxel(lower, upper, voxel_size(voxel_m, lower, upper, voxels_per_edge=50))
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
    from ..scene import load_scene
    from ..scene_model import SceneModel, load_scene_model

    import torch

    acq = measurements.acquisition
    # the true scene as the data's radar sees it (a closed room mesh around it: a shell)
    truth_scene = (load_scene(scene_name).around_radar(torch.cat([acq.tx_m, acq.rx_m], 1).reshape(-1, 3))
                   if scene_name is not None else None)
    model = (load_scene_model(model_path) if model_path is not None
             else SceneModel.from_scene(truth_scene, start_offset, seed=0, free_materials=free_materials))
    lower, upper = image_box(data, measurements, bounds, None)
    model.require_overlap(lower, upper, "the data's")
    return truth_scene, model, (lower, upper)


def _reconstruct_neural_profiles(data: Path, out: Path, bounds: str | None, model_path: Path | None,
                                 scene_name: str | None, steps: int, start_offset: float, profile: dict) -> None:
    """``reconstruct --model neural --fit-to profiles``: the room-scale neural model
    (rfsdf.recon.neural_profiles) distilled from the start model (``model_path``, or the
    scene ``scene_name`` ``start_offset`` off), fitted to the range profiles (with the
    ``profile`` settings, as above) for ``steps``, meshed near its zero set at one range resolution:
    ``out``/neural.json and mesh.ply."""
    import dataclasses

    from ..jsonio import write_json
    from ..mesh import export_mesh
    from ..radar import read_measurements
    from ..recon.neural_profiles import NeuralProfileSettings, fit_neural_model
    from ..recon.range_profile import ProfileSettings

    refuse_overwriting_inputs(out, data, model_path)
    measurements = read_measurements(data)
    _, model, _ = _start_model(data, measurements, bounds, model_path, scene_name, start_offset)
    settings = dataclasses.replace(NeuralProfileSettings(), steps=steps)
    fitted = fit_neural_model(measurements, model, settings=settings, profile=ProfileSettings(**profile),
                              progress=True)
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
    from ..config import validate
    from ..recon.config import ReconConfig

    merged = config.model_dump()
    merged["calibration"]["reference"] = reference
    return validate(ReconConfig, merged, "--reference" if config_path is None else f"{config_path} with --reference")


def _run_config(run: Path) -> Path | None:
    from ..recon.checkpoint import CONFIG_NAME

    path = run / CONFIG_NAME
    return path if path.exists() else None


@main.command("mesh")
@click.argument("run", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(path_type=Path), required=True, help="Mesh file (.ply, .obj, .stl).")
@click.option("--resolution", type=click.IntRange(2, 1024), default=128, show_default=True,
              help="Voxels along the longest edge (2 to 1024).")
@device_option()
@one_line_errors
def mesh_cmd(run: Path, out: Path, resolution: int, device: str):
    """Mesh the SDF of a reconstruction run by marching cubes."""
    from ..mesh import export_mesh, extract_mesh
    from ..recon import load_field
    from ..recon.checkpoint import CHECKPOINT_NAME, CONFIG_NAME

    device = device_named(device)
    refuse_overwriting_inputs(out, run / CHECKPOINT_NAME, run / CONFIG_NAME)
    field = load_field(run, device)
    mesh = extract_mesh(field.sdf, field.lower_m, field.upper_m, resolution, device=device, progress=True)
    click.echo(f"wrote {export_mesh(mesh, out)} ({len(mesh.faces)} faces)")


@main.command("evaluate")
@click.argument("mesh_path", type=click.Path(path_type=Path))
@click.option("--scene", "scene_name", required=True, help="Ground-truth scene preset or TOML file.")
@click.option("--threshold", "threshold_m", type=POSITIVE, default=0.005, show_default=True, help="F-score distance [m].")
@click.option("--json", "as_json", is_flag=True, help="Print the metrics as JSON.")
@one_line_errors
def evaluate_cmd(mesh_path: Path, scene_name: str, threshold_m: float, as_json: bool):
    """Compare a mesh with a scene's true surfaces: Chamfer, F-score, normals, Hausdorff, IoU."""
    import trimesh

    from ..jsonio import to_json
    from ..limits import input_file
    from ..metrics import evaluate_mesh
    from ..scene import load_scene

    metrics = evaluate_mesh(trimesh.load(input_file(mesh_path), force="mesh"), load_scene(scene_name), threshold_m=threshold_m)
    if as_json:
        click.echo(to_json(metrics.as_dict()))
    else:
        for key, value in metrics.as_dict().items():
            click.echo(f"{key:>20}  {value if value is None else f'{value:.4g}'}")


@main.command("materials")
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("--data", "data_path", type=click.Path(path_type=Path), default=None,
              help="For a run folder: the measurements it was fitted on (default: the file the checkpoint names).")
@click.option("--scene", "scene_name", default=None, help="For a run folder: the true scene, for a row per object.")
@one_line_errors
def materials_cmd(folder: Path, data_path: Path | None, scene_name: str | None):
    """Print what each surface of a finished run is made of: per object (with the truth) and
    per connected component, class probabilities, eps' with its interval, observed share.

    FOLDER is a demo folder (read from its metrics.json) or a `reconstruct` run folder (its
    field's material head on its mesh.ply, observed by the views of --data, and the data's
    closed-form readout through its fit, rebuilt from the checkpoint)."""
    from ..material_estimates import run_materials

    click.echo(run_materials(folder, data_path=data_path, scene_name=scene_name))
