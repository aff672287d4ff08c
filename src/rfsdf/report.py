"""The HTML report of a run: one self-contained page (no network) that shows what a run did
and where its surface is wrong.

``write_report(folder)`` writes ``folder/report.html`` for

- a demo folder (``rfsdf demo``): the scene and radar with their resolution figures, the
  matched-filter and CLEAN projections [dB], SDF slices of the fit against the truth
  through each object's centre, the training curves, the metrics of every method with a
  row per object, and 3-D views: the GeRaF mesh and the best baseline's coloured by their
  signed distance to the truth [mm], the true surface coloured by whether any view
  observes it, and the true surface with the radar's elements of every view;
- a run folder (``rfsdf reconstruct``, no truth): its settings, training curves, slices
  through the box's centre and a 3-D view of its surface.

Figures are PNGs embedded as data URIs (also left in the folder) and plotly views (plotly.js
inline once). ``write_view`` writes the 3-D view of any mesh, coloured by error when a
scene is given.
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Literal

import numpy as np
import pydantic
import trimesh

from .atomic import atomic_path
from .config import validate
from .demo import SETTINGS_NAME, metrics_rows
from .errors import RfsdfError
from .limits import input_file
from .material_estimates import check_materials_dict, materials_table, point_classes
from .mesh import extract_mesh
from .model_demo import MODEL_MESHES, MODELS, models_table
from .radar import load_radar, read_measurements
from .radar.coverage import observed_mask
from .radar.acquisition import SPEED_OF_LIGHT
from .radar.waveform import range_resolution_m
from .recon import load_field
from .recon.checkpoint import CHECKPOINT_NAME, CONFIG_NAME, read_log
from .scene import load_scene
from .viz import plot_object_slices, plot_sdf_slices, plot_training_curves
from .viz.scene3d import error_figure, figures_html, material_figure, mesh_figure, observed_figure, views_figure

__all__ = ["REPORT_NAME", "Section", "write_report", "write_view"]

REPORT_NAME = "report.html"
_RUN_MESH_RESOLUTION = 96  # marching cubes of a run folder's field when it has no mesh.ply
# the baseline every demo folder has; those since the thirty-third session also
# "clean_threshold" and "clean_detection", with a matched-filter warm start "mf_detection"
_BASELINES = ("mf_threshold",)


class _Scored(pydantic.BaseModel):
    """What the report reads of one method's entry in metrics.json (other keys pass)."""

    model_config = pydantic.ConfigDict(extra="allow", allow_inf_nan=False)

    label: str
    full: dict[str, float | None]
    observed: dict[str, float | None] | None = None
    observed_fraction: float | None = None
    accuracy_near_observed_mm: float | None = None
    accuracy_near_unobserved_mm: float | None = None
    completeness_observed_mm: float | None = None
    completeness_unobserved_mm: float | None = None
    objects: dict[str, dict[str, float | None]]


class _DemoMetrics(pydantic.BaseModel):
    """What the report reads of a demo's metrics.json: every method's scores, stage times."""

    model_config = pydantic.ConfigDict(extra="allow")

    methods: dict[str, _Scored]
    timings_s: dict[str, float] = {}

    @pydantic.field_validator("methods")
    @classmethod
    def _has_every_method(cls, methods: dict[str, _Scored]) -> dict[str, _Scored]:
        missing = [name for name in ("neural", *_BASELINES) if name not in methods]
        if missing:
            raise ValueError(f"missing method(s) {', '.join(missing)}")
        return methods


class _ModelRow(pydantic.BaseModel):
    """What the report reads of one model's row: its scores (None where none could be had)."""

    model_config = pydantic.ConfigDict(extra="allow")

    chamfer_l1_mm: float | None
    f_score: float | None
    normal_consistency: float | None


class _ModelsMetrics(pydantic.BaseModel):
    """What the report reads of a model demo's metrics.json: per model its scores."""

    model_config = pydantic.ConfigDict(extra="allow")

    f_threshold_m: float
    models: dict[Literal[MODELS], _ModelRow]


_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
img { max-width: 100%; } pre { background: #f4f4f4; padding: .8em; overflow-x: auto; }
table { border-collapse: collapse; font-size: .9em; } td, th { padding: .25em .6em; border-bottom: 1px solid #ddd; }
td { text-align: right; } th { text-align: right; } td:first-child, th:first-child { text-align: left; }
nav a { margin-right: 1em; }
"""


@dataclass(frozen=True)
class Section:
    """One part of the page: ``key`` is its HTML id (tests look for it), ``body`` its HTML."""

    key: str
    title: str
    body: str


def _png(path: Path, alt: str) -> str:
    """An <img> holding the PNG file's bytes (a data URI: the page needs nothing beside it)."""
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _pre(text: str) -> str:
    return f"<pre>{html.escape(text)}</pre>"


def _table(labels: list[str], rows: list[tuple[str, list[str]]]) -> str:
    head = "".join(f"<th>{html.escape(label)}</th>" for label in ["", *labels])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in [name, *cells]) + "</tr>"
                   for name, cells in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _page(title: str, sections: list[Section]) -> str:
    nav = "".join(f'<a href="#{s.key}">{html.escape(s.title)}</a>' for s in sections)
    parts = "".join(f'<section id="{s.key}"><h2>{html.escape(s.title)}</h2>{s.body}</section>' for s in sections)
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1><nav>{nav}</nav>{parts}</body></html>")


def _write_page(path: Path, title: str, sections: list[Section]) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(_page(title, sections), encoding="utf-8")
    return path


def _read_json(path: Path, what: str) -> dict:
    try:
        value = json.loads(input_file(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise RfsdfError(f"{path}: not readable JSON ({exc})") from None
    if not isinstance(value, dict):
        raise RfsdfError(f"{path}: not {what}")
    return value


def _load_mesh(path: Path) -> trimesh.Trimesh:
    try:
        mesh = trimesh.load(input_file(path), force="mesh")
    except RfsdfError:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure to parse means "not a mesh file"
        raise RfsdfError(f"{path}: not a readable mesh ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise RfsdfError(f"{path}: holds no triangles")
    return mesh


def _resolution_text(acquisition, centre_m: np.ndarray) -> str:
    """Range resolution c/2B and cross-range resolution lambda R / (2 D) of the first view,
    R its distance to ``centre_m`` (3,) [m], D the largest extent of its virtual array."""
    f = acquisition.frequencies_hz.numpy()
    frames = acquisition.frames(0)  # one frame, or a scan's
    tx, rx = acquisition.tx_m[frames].numpy(), acquisition.rx_m[frames].numpy()
    virtual = 0.5 * (tx[:, :, None] + rx[:, None]).reshape(-1, 3)
    aperture = float(np.ptp(virtual, axis=0).max())
    distance = float(np.linalg.norm(virtual.mean(0) - centre_m))
    wavelength = SPEED_OF_LIGHT / float(f.mean())
    return (f"range resolution c/2B = {range_resolution_m(acquisition.bandwidth_hz) * 1e3:.1f} mm; cross-range resolution "
            f"lambda R / 2D = {wavelength * distance / (2 * aperture) * 1e3:.1f} mm at R = {distance:.2f} m "
            f"(aperture D = {aperture * 100:.1f} cm, lambda = {wavelength * 1e3:.2f} mm); "
            f"{acquisition.num_views} views")


def _scene_and_radar(folder: Path, settings: dict):
    """A demo folder's scene (as its radar sees it), radar and acquisition, and the report's
    section describing them: (scene, radar, acquisition, Section)."""
    radar = load_radar(settings["radar"])
    scene = load_scene(settings["scene"]).around_radar(radar.positions_m)
    acquisition = read_measurements(folder / "measurements.h5").acquisition
    centre = 0.5 * (scene.lower_m + scene.upper_m)
    summary = Section("summary", "Scene and radar",
                      _pre(f"{scene.summary()}\n{radar.summary()}\n{_resolution_text(acquisition, centre)}\n"
                           f"settings: {json.dumps(settings)}"))
    return scene, radar, acquisition, summary


def _demo_sections(folder: Path, settings: dict, result: dict) -> tuple[str, list[Section]]:
    validate(_DemoMetrics, result, f"{folder / 'metrics.json'}")
    materials = result.get("materials")
    if materials is not None:
        check_materials_dict(materials, str(folder / "metrics.json"))
    labels, rows = metrics_rows(result)
    fraction = next(iter(result["methods"].values()))["observed_fraction"]
    neural, baselines = result["methods"]["neural"], {name: method for name, method in result["methods"].items()
                                                      if not name.startswith("neural")}
    best = min(baselines, key=lambda name: baselines[name]["full"]["chamfer_l1_mm"] or np.inf)
    times = ", ".join(f"{k.removesuffix('_s')} {v:.0f}" for k, v in result.get("timings_s", {}).items())
    observed_text = "" if fraction is None else (
        f"<p>Observed surface: {fraction:.0%} of the true surface is seen near specular by some view; the "
        "observed columns measure completeness over that part only.</p>")
    scene, radar, acquisition, summary = _scene_and_radar(folder, settings)
    field = load_field(folder / "run")
    log = read_log(folder / "run")
    observed = partial(observed_mask, acquisition=acquisition, occluder=scene.sdf)

    meshes = scene.object_meshes()
    object_slices = plot_object_slices(
        field.sdf, scene.sdf, [o.name for o in scene.objects], np.array([m.bounds[0] for m in meshes]),
        np.array([m.bounds[1] for m in meshes]), folder / "object-slices.png",
        title="neural SDF [mm] (black zero set) against the true surfaces (dashed), through each object's centre")
    training = plot_training_curves(log, folder / "training.png", title="GeRaF fit")
    metrics = _table(labels, rows) + observed_text + f"<p>Stage times [s]: {html.escape(times)}.</p>"

    truth = scene.ground_truth_mesh()
    views = [
        error_figure(_load_mesh(folder / "neural.ply"), scene.sdf, "GeRaF reconstruction, coloured by its signed "
                     f"distance to the truth (Chamfer {neural['full']['chamfer_l1_mm']:.2f} mm)",
                     truth=truth),
        error_figure(_load_mesh(folder / f"{best.replace('_', '-')}.ply"), scene.sdf,
                     f"best baseline, {baselines[best]['label']}, the same way "
                     f"(Chamfer {baselines[best]['full']['chamfer_l1_mm']:.2f} mm)", truth=truth),
        observed_figure(truth, observed, "true surface: observed by some view near specular (orange) or by none"),
        views_figure(truth, acquisition.tx_m.numpy(), acquisition.rx_m.numpy(),
                     f"true surface and the radar's {acquisition.num_views} views (Tx red, Rx blue)"),
    ]
    if materials is not None:
        classes = partial(_face_classes, field, frequency_hz=acquisition.center_frequency_hz,
                          scale=materials.get("head_scale", 1.0))  # in the table's gain
        views.insert(1, material_figure(_load_mesh(folder / "neural.ply"), classes, field.materials,
                                        "GeRaF reconstruction, coloured by the class nearest its fitted |Gamma|"))
    sections = [
        summary,
        Section("images", "Matched-filter and CLEAN images",
                "".join(_png(folder / name, name) for name in ("image-mip.png", "clean-mip.png")
                        if (folder / name).is_file())),
        Section("slices", "SDF slices through each object", _png(object_slices, "object slices")),
        Section("training", "Training curves", _png(training, "training curves")),
        Section("metrics", "Metrics against the truth", metrics),
        *([Section("materials", "Materials: truth against prediction", _pre(materials_table(materials)))]
          if materials is not None else []),
        Section("views3d", "3-D views (drag to turn, scroll to zoom)", "".join(figures_html(views))),
    ]
    return f"rfsdf demo: scene {scene.name!r}, radar {radar.name!r}", sections


def _models_sections(folder: Path, settings: dict, result: dict) -> tuple[str, list[Section]]:
    """A model demo's folder (``demo --model ...``): the models side by side, each free
    parameter's start, fit and truth, and each model's mesh coloured by its error."""
    validate(_ModelsMetrics, result, f"{folder / 'metrics.json'}")
    scene, radar, acquisition, summary = _scene_and_radar(folder, settings)
    truth = scene.ground_truth_mesh()
    sections = [summary, Section("models", "The models side by side", _pre(models_table(result)))]
    views = []
    for name, row in result["models"].items():
        if "free" in row:
            rows = [(p["name"], [_lengths_mm(p["start"]), _lengths_mm(p["fitted"]), _lengths_mm(p.get("truth"))])
                    for p in row["free"]]
            sections.append(Section(f"free-{name}", f"{name}: free parameters [mm]",
                                    _table(["start", "fitted", "truth"], rows)))
        mesh_path = folder / MODEL_MESHES[name]
        if mesh_path.is_file():
            views.append(error_figure(_load_mesh(mesh_path), scene.sdf, f"{name} model, coloured by its signed "
                                      f"distance to the truth (Chamfer {row['chamfer_l1_mm']:.1f} mm)", truth=truth))
    views.append(views_figure(truth, acquisition.tx_m.numpy(), acquisition.rx_m.numpy(),
                              f"true surface and the radar's {acquisition.num_views} views (Tx red, Rx blue)"))
    sections.append(Section("views3d", "3-D views (drag to turn, scroll to zoom)", "".join(figures_html(views))))
    return f"rfsdf models: scene {scene.name!r}, radar {radar.name!r}", sections


def _lengths_mm(values) -> str:
    return "-" if values is None else ", ".join(f"{v * 1e3:.1f}" for v in values)


def _face_classes(field, centres: np.ndarray, *, frequency_hz: float, scale: float = 1.0) -> np.ndarray:
    """(F,) at face centres (F, 3) [m], the index of the class nearest the reflectivity the
    material head gives there times ``scale`` (the materials table's ``head_scale``)."""
    import torch

    with torch.no_grad():
        probabilities = field.material(torch.tensor(np.asarray(centres), dtype=torch.float32))
    return point_classes(probabilities, field.materials, frequency_hz, scale)


def _run_sections(folder: Path) -> tuple[str, list[Section]]:
    field, log = load_field(folder), read_log(folder)
    mesh_path = folder / "mesh.ply"
    mesh = (_load_mesh(mesh_path) if mesh_path.is_file()
            else extract_mesh(field.sdf, field.lower_m, field.upper_m, _RUN_MESH_RESOLUTION))
    slices = plot_sdf_slices(field.sdf, field.lower_m, field.upper_m, folder / "slices.png",
                             title="neural SDF [mm] on the box's centre planes (black: zero set)")
    training = plot_training_curves(log, folder / "training.png", title="GeRaF fit")
    config = (folder / CONFIG_NAME).read_text() if (folder / CONFIG_NAME).is_file() else "(no config.toml)"
    sections = [
        Section("summary", "Settings", _pre(config)),
        Section("slices", "SDF slices", _png(slices, "slices")),
        Section("training", "Training curves", _png(training, "training curves")),
        Section("views3d", "3-D view (drag to turn, scroll to zoom)",
                "".join(figures_html([mesh_figure(mesh, "reconstructed surface (no truth to compare with)")]))),
    ]
    return f"rfsdf reconstruction: {folder.name}", sections


def write_report(folder) -> Path:
    """Write ``folder/report.html`` for a demo folder or a reconstruction run folder."""
    folder = Path(folder)
    if (folder / SETTINGS_NAME).is_file():
        if not (folder / "metrics.json").is_file():
            raise RfsdfError(f"{folder}: the demo has not finished (no metrics.json); run `rfsdf demo` with this "
                             "--out again to finish it")
        settings = _read_json(folder / SETTINGS_NAME, "demo settings")
        if not all(isinstance(settings.get(key), str) for key in ("scene", "radar")):
            raise RfsdfError(f"{folder / SETTINGS_NAME}: scene, radar: missing or not names")
        result = _read_json(folder / "metrics.json", "a demo's metrics")
        sections_of = _models_sections if "models" in result else _demo_sections  # demo --model primitive, ...
        title, sections = sections_of(folder, settings, result)
    elif (folder / CHECKPOINT_NAME).is_file():
        title, sections = _run_sections(folder)
    else:
        raise RfsdfError(f"{folder}: neither a demo folder (no {SETTINGS_NAME}) nor a run folder "
                         f"(no {CHECKPOINT_NAME})")
    return _write_page(folder / REPORT_NAME, title, sections)


def write_view(mesh_path, out, *, scene_name: str | None = None) -> Path:
    """Write a page with the 3-D view of a mesh file; coloured by its signed distance to the
    true surface when ``scene_name`` (a preset or TOML file) is given."""
    mesh_path = Path(mesh_path)
    mesh = _load_mesh(mesh_path)
    if scene_name is None:
        figure, title = mesh_figure(mesh, mesh_path.name), f"rfsdf view: {mesh_path.name}"
    else:
        scene = load_scene(scene_name)
        figure = error_figure(mesh, scene.sdf, f"{mesh_path.name}, coloured by its signed distance to scene "
                                               f"{scene.name!r}", truth=scene.ground_truth_mesh())
        title = f"rfsdf view: {mesh_path.name} against scene {scene.name!r}"
    return _write_page(Path(out), title, [Section("views3d", "3-D view (drag to turn, scroll to zoom)",
                                                  "".join(figures_html([figure])))])
