"""The demo of scene models: a scene (a room) simulated, then a primitive model, a hybrid
model and a neural model reconstructed from the same data, each meshed and scored.

``rfsdf demo --model primitive|hybrid|neural|all``. All three are fitted to each view's
range profile through the same ray-vote renderer (:mod:`rfsdf.recon.range_profile`), which
is what a few-centimetre array resolves at room scale, from the same start: a scene model
file, or the true scene with every length free and moved by a seeded random offset
(:meth:`~rfsdf.scene_model.SceneModel.from_scene`). The primitive model fits the start's
free parameters, the hybrid adds a bounded neural residual (:mod:`rfsdf.recon.hybrid`), the
neural model is the GeRaF geometry network distilled from the start and then free in every
weight (:mod:`rfsdf.recon.neural_profiles`). Every model is scored against the true scene:
Chamfer, F at half the radar's range resolution, normal consistency, and the seen surface
(|f| at the specular foot points, :func:`~rfsdf.metrics.specular_feet`).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable


from .demo import claim_folder, load_scene_and_radar, simulated_in
from .device import resolve_device
from .jsonio import write_json
from .mesh import export_mesh
from .metrics import evaluate_scene, once_per_samples, seen_surface_errors, specular_feet
from .radar import read_measurements, simulate
from .radar.coverage import observed_mask
from .radar.waveform import range_resolution_m
from .recon.hybrid import RANGE_RESOLUTIONS, fit_hybrid_profiles, project_mesh, residual_amplitude_m
from .recon.neural_profiles import NeuralProfileSettings, fit_neural_model
from .recon.primitive import material_text
from .recon.range_profile import ProfileSettings, fit_primitive_profiles
from .scene import Scene
from .scene_model import SceneModel, analytic_spec, load_scene_model

__all__ = ["MODELS", "MODEL_MESHES", "ModelDemoSettings", "QUICK_MODELS", "run_model_demo", "models_table"]

MODELS = ("primitive", "hybrid", "neural")
MODEL_MESHES = {name: f"{name}/mesh.ply" for name in MODELS}


@dataclass(frozen=True)
class ModelDemoSettings:
    """What the model demo runs; ``QUICK_MODELS`` is the test suite's seconds-long version.

    ``residual_range_resolutions``: the hybrid residual's amplitude in range resolutions
    c / 2B of the radar; ``hybrid_joint``: fit the hybrid's primitives and residual together
    (then the residual alone), not the residual after the primitives; ``scene_model``: a
    model file (None: the true scene, every length free, ``start_offset_m`` off, drawn with
    ``seed``, and with ``free_materials`` every material but the scene's calibration
    reference); ``transmission``: lines of sight go on through dielectrics, in the simulator
    and in the models' renderer alike (:mod:`rfsdf.radar.transmission`,
    :mod:`rfsdf.recon.range_profile`); ``beams``: the fits compare each view's profiles per
    beam of its array, coherent over its channels (``ProfileSettings.beams``)."""

    scene: str = "l-room"
    radar: str = "room-60g"
    scene_model: str | None = None
    start_offset_m: float = 0.15
    seed: int = 0
    free_materials: bool = False
    steps: int = 150
    residual_steps: int = 100
    residual_range_resolutions: float = RANGE_RESOLUTIONS
    hybrid_joint: bool = False
    max_surface_samples: int = 3_000_000
    rays_per_side: int = 48
    metric_samples: int = 50_000
    neural: NeuralProfileSettings = NeuralProfileSettings()
    transmission: bool = False
    beams: bool = False


QUICK_MODELS = ModelDemoSettings(steps=8, residual_steps=4, max_surface_samples=40_000, rays_per_side=16,
                                 metric_samples=5_000,
                                 neural=NeuralProfileSettings(width=32, depth=3, distil_steps=60, batch=2048, steps=4))


def _profile_settings(settings: ModelDemoSettings) -> ProfileSettings:
    return ProfileSettings(rays_per_side=settings.rays_per_side, transmission=settings.transmission,
                           beams=settings.beams)


def run_model_demo(out, settings: ModelDemoSettings, models=("primitive",), *, start: SceneModel | None = None,
                   device: str = "auto", log: Callable[[str], None] = print, progress: bool = True) -> dict:
    """Run ``models`` (names of ``MODELS``) with ``settings`` into folder ``out``; returns
    (and writes as metrics.json) {"scene", "radar", "f_threshold_m", "models": {name: ...},
    "timings_s"}, with the models an earlier run of the same settings put there (a model the
    folder holds already is read back).
    ``start``: the fit's start model instead of the settings' (a benchmark's: another scene's
    model, which lacks an object of this one). ``device`` (auto, cpu, cuda) runs the
    simulation (scattering and A c over the facets: the room's hot stage) there; the
    profile fits run on the CPU."""
    out = Path(out)
    device = resolve_device(device)
    inputs = load_scene_and_radar(settings.scene, settings.radar)
    scene, radar = inputs.scene, inputs.radar
    if start is None:
        start = (load_scene_model(settings.scene_model) if settings.scene_model is not None
                 else SceneModel.from_scene(scene, settings.start_offset_m, settings.seed,
                                            free_materials=settings.free_materials))
    start.require_overlap(scene.lower_m.tolist(), scene.upper_m.tolist(), f"scene {scene.name!r}'s")
    if set(models) - {"neural"}:  # the neural model is free in every weight whatever the start
        start.require_free()
    claim_folder(out, settings)
    log(scene.summary())
    log(radar.summary())
    for true, modelled in zip(scene.spec.objects, start.spec.objects if settings.scene_model is None else []):
        if true.shape.type == "mesh" and modelled.shape.type != "mesh":
            log(f"start model: {true.name}'s mesh is a box, modelled as an analytic "
                f"{'box' if modelled.shape.type == 'box' else 'box less a box (a shell)'} whose lengths are free")
    timings: dict[str, float] = {}
    clock = time.perf_counter()
    if (out / "measurements.h5").exists():  # written atomically by a run of these settings
        measurements = read_measurements(out / "measurements.h5")
    else:
        measurements = simulated_in(out, partial(simulate, scene, radar, seed=settings.seed,
                                                 max_samples=settings.max_surface_samples,
                                                 transmission=settings.transmission, device=device, progress=progress))
    timings["simulate_s"] = round(time.perf_counter() - clock, 2)
    acq = measurements.acquisition
    threshold = range_resolution_m(acq.bandwidth_hz) / 2
    feet = specular_feet(scene, acq, transmission=settings.transmission)
    score = partial(_score, scene=scene, feet=feet, threshold_m=threshold, samples=settings.metric_samples,
                    seed=settings.seed,
                    observed=once_per_samples(partial(observed_mask, acquisition=acq, occluder=scene.sdf)))
    log(f"{len(feet)} specular foot points: where the data see the true surface; F at {threshold * 1e3:.1f} mm")
    earlier = json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").is_file() else {}
    rows = earlier.get("models", {})
    for name in models:
        clock = time.perf_counter()
        if (out / name / "model.json").is_file():  # written atomically by a run of these settings
            rows[name] = json.loads((out / name / "model.json").read_text())
        elif name == "neural":
            seen = partial(seen_surface_errors, feet=feet, within_m=threshold)
            rows[name] = _neural(out / name, measurements, start, settings, score, seen, progress)
        else:
            rows[name] = _fitted_model(name, out / name, measurements, start, scene, settings, score, progress)
        timings[f"{name}_s"] = round(time.perf_counter() - clock, 2)
        log(f"{name}: " + _summary(rows[name]))
    result = {"scene": scene.name, "radar": radar.name, "f_threshold_m": threshold, "start_offset_m":
              settings.start_offset_m if settings.scene_model is None else None, "seed": settings.seed,
              "models": {name: rows[name] for name in MODELS if name in rows},
              "timings_s": {**timings, "total_s": round(sum(timings.values()), 2)}}
    write_json(out / "metrics.json", result)
    return result


def _score(mesh, sdf, *, scene: Scene, feet, threshold_m: float, samples: int, seed: int, observed) -> dict:
    """A model's mesh and SDF against the truth: Chamfer, F, normals and the seen surface,
    also per true object (the feet nearest it)."""
    metrics = evaluate_scene(mesh, scene, observed=observed, threshold_m=threshold_m, samples=samples, seed=seed)
    owner = scene.object_index(feet) if len(feet) else feet[:, 0].long()
    full = metrics.full
    return {"chamfer_l1_mm": full.chamfer_l1_mm, "f_score": full.fscore,
            "normal_consistency": full.normal_consistency,
            "observed_chamfer_l1_mm": None if metrics.observed is None else metrics.observed.chamfer_l1_mm,
            "seen_surface": {**seen_surface_errors(sdf, feet, within_m=threshold_m), "objects": {
                obj.name: seen_surface_errors(sdf, feet[owner == index], within_m=threshold_m)
                for index, obj in enumerate(scene.objects) if (owner == index).any()}}}


def _fitted_model(name: str, folder: Path, measurements, start: SceneModel, scene: Scene,
                  settings: ModelDemoSettings, score, progress: bool) -> dict:
    """Fit the primitive or hybrid model to the range profiles, mesh and score it, and write
    its folder: ``model.json`` (free parameters), ``fitted-scene.toml`` and ``mesh.ply``."""
    profile = _profile_settings(settings)
    if name == "primitive":
        fit = fit_primitive_profiles(measurements, start, steps=settings.steps, settings=profile, progress=progress)
    else:
        amplitude = residual_amplitude_m(measurements.acquisition.bandwidth_hz, settings.residual_range_resolutions)
        fit = fit_hybrid_profiles(measurements, start, amplitude_m=amplitude, lower_m=scene.lower_m,
                                  upper_m=scene.upper_m, steps=settings.steps, residual_steps=settings.residual_steps,
                                  joint=settings.hybrid_joint, settings=profile, progress=progress)
    fitted = Scene(fit.fitted_spec(), start.base_dir)
    mesh, sdf = fitted.ground_truth_mesh(), fitted.sdf
    if name == "hybrid":  # the primitive mesh moved onto the residual's zero set
        mesh, sdf = project_mesh(fit.field.sdf, mesh), fit.field.frozen_sdf()
    folder.mkdir(parents=True, exist_ok=True)
    fitted.write_toml(folder / "fitted-scene.toml")
    export_mesh(mesh, folder / "mesh.ply")
    truth = analytic_spec(scene)
    free = fit.free_table(truth)
    row = {**score(mesh, sdf), "mesh": MODEL_MESHES[name], "parameters": sum(len(p["start"]) for p in free),
           "fit_s": round(fit.seconds, 2), "steps": len(fit.losses), "loss_first": fit.losses[0],
           "loss_last": fit.losses[-1], "free": free, "materials": fit.material_table(truth)}
    if name == "hybrid":
        row["residual_amplitude_m"] = fit.field.amplitude_m
        row["residual_weights"] = sum(p.numel() for p in fit.field.residual_parameters())
        row["joint"] = settings.hybrid_joint
    write_json(folder / "model.json", row)
    return row


def _neural(folder: Path, measurements, start: SceneModel, settings: ModelDemoSettings, score, seen,
            progress: bool) -> dict:
    """The neural model from ``start`` (:func:`~rfsdf.recon.neural_profiles.fit_neural_model`),
    scored (``seen``: an SDF's seen-surface errors, for the distilled start too), and its
    folder: ``model.json`` and ``mesh.ply``."""
    start_seen = {}
    model = fit_neural_model(measurements, start, settings=settings.neural, profile=_profile_settings(settings),
                             seed=settings.seed, progress=progress,
                             distilled=lambda field: start_seen.update(seen(field.frozen_sdf())))
    folder.mkdir(parents=True, exist_ok=True)
    export_mesh(model.mesh, folder / "mesh.ply")
    row = {**score(model.mesh, model.field.frozen_sdf()), "mesh": MODEL_MESHES["neural"], **model.as_dict(),
           "start_seen_surface": start_seen}
    write_json(folder / "model.json", row)
    return row


def _summary(row: dict) -> str:
    seen = row.get("seen_surface") or {}
    seen_text = (f", seen surface {seen['mean_mm']:.1f} mm mean, {seen['within']:.0%} within "
                 f"{seen['within_m'] * 1e3:.0f} mm" if seen.get("mean_mm") is not None else "")
    materials = "".join(f"; {material_text(m)}" for m in row.get("materials", []))
    return f"Chamfer {row['chamfer_l1_mm']:.1f} mm, F {row['f_score']:.3f}{seen_text}, {row['fit_s']:.0f} s{materials}"


def models_table(result: dict) -> str:
    """The models side by side, for the terminal."""
    lines = [f"{'model':<10} {'Chamfer mm':>11} {'F':>6} {'normals':>8} {'seen mm':>8} {'seen <':>7} "
             f"{'params':>7} {'fit s':>7}"]
    for name, row in result["models"].items():
        seen = row.get("seen_surface") or {}
        cell = lambda v, fmt: "-" if v is None else format(v, fmt)  # noqa: E731
        lines.append(f"{name:<10} {cell(row['chamfer_l1_mm'], '11.1f')} {cell(row['f_score'], '6.3f')} "
                     f"{cell(row['normal_consistency'], '8.3f')} {cell(seen.get('mean_mm'), '8.1f')} "
                     f"{cell(seen.get('within'), '7.0%')} {cell(row.get('parameters'), '7d')} "
                     f"{cell(row.get('fit_s'), '7.0f')}")
    lines.append(f"F at {result['f_threshold_m'] * 1e3:.1f} mm (half the range resolution); seen: |f| at the "
                 "specular foot points, and the share within that threshold")
    return "\n".join(lines)
