"""What a fitted material head says each surface is made of, per object of a scene (when
the truth is known) and per connected component of the reconstruction (always).

An estimate is never a bare class. The renderer reflects a point by the head's mixture
sum_k p_k Gamma_k, so what the data fitted at a point is that mixture's magnitude, its
**reflectivity** at normal incidence (``point_reflectivity``), not the class the head
favours: a point 52 % metal and 45 % wood reflects 0.60, and on the demo the argmax of such
mixtures read every dielectric as wood where their reflectivities, calibrated by a metal
reference, put glass and plasterboard in their own classes. So a surface's estimate is its
reflectivity (area-weighted over the surface some view observes) with the 10th to 90th
percentile of the per-point values; the ``predicted`` class is the catalogue class nearest
in |Gamma| at normal incidence, and eps' the lossless permittivity with that reflectivity,
((1 + |Gamma|) / (1 - |Gamma|))^2, with its interval from the percentiles (how much the
surface agrees with itself, not a confidence interval of the data). The head's class
probabilities are reported beside it. Classes are absolute only where the gain is (a
reference object, a known gain); with a gain fitted at each step they are relative, and the
calibration line says so. An object whose observed share is below ``MIN_OBSERVED_FRACTION``
is reported but left out of the accuracy: what no view sees, no data can tell.

With the fit at hand (the demo), each surface's |Gamma| is also **read from the data in closed
form** (``readout``, :mod:`rfsdf.recon.material_readout`) on the fitted surface with the
primitives that replaced their fragments, in the same calibration as the head (the reference
object, the known gain, or else the gain the finished fit wants). Where it reads a passive
surface's value (0 < |Gamma| <= ``READOUT_CEILING``) the class is the readout's (``source``
"data"): with the gain known it read every object of six scenes whose surface lies within 0.5 mm
right, where the head read 5 of 11 (docs/results/materials.md); a relative fit's gain, which a
surface the fit lacks biases, biases both alike. A reading above the ceiling says the surface
under it is wrong, and none says the data show nothing of it: the head's class stands there.
Each reading carries its ``readout_spread``, the jackknife's standard error over the views
(:mod:`~rfsdf.recon.material_readout`), and the ``readout_classes`` whose |Gamma| range
its interval, the reading +- ``READOUT_SIGMAS`` spreads, reaches: more than one, and the data
cannot tell those classes apart (the nearest is still ``predicted``, and counted).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import partial
from typing import NamedTuple

import numpy as np
import pydantic
import torch
import trimesh

from .config import validate
from .materials import class_reflectivities, get_material, point_reflectivity, reflectivity_class
from .radar import Acquisition
from .radar.coverage import observed_mask

__all__ = ["MIN_OBSERVED_FRACTION", "READOUT_CEILING", "READOUT_SIGMAS", "MaterialEstimate", "MaterialReport",
           "Reading", "estimate_materials", "object_materials", "component_materials", "read_materials", "known_gain",
           "fit_materials", "with_readout", "readout_classes", "counts", "class_accuracy", "point_classes",
           "eps_of_reflectivity", "paint_mesh", "check_materials_dict", "calibration_text", "scene_reference",
           "materials_table", "run_materials"]

MIN_OBSERVED_FRACTION = 0.15  # observed share of an object's surface for it to count in the accuracy
# no passive surface reflects more than 1; right surfaces' metal read 0.95-1.02, wrong ones up to 2.4
# (garage's bored box), docs/results/materials.md
READOUT_CEILING = 1.1
READOUT_SIGMAS = 2.0  # a readout's interval: the reading +- this many jackknife spreads over views
_CHUNK = 1 << 15
_INTERVAL = (0.1, 0.9)  # the percentiles of per-point reflectivity that make the intervals
_COMPONENT_SAMPLES = 4000  # surface samples per connected component of the reconstruction
_MAX_REFLECTIVITY = 0.999  # eps' of a reflectivity is capped there (1 is metal: no finite eps')


@dataclass(frozen=True)
class MaterialEstimate:
    """One surface's material: the head's ``probabilities`` per class (area-weighted over its
    observed part), its ``reflectivity`` |Gamma| at normal incidence with the
    ``reflectivity_interval``, the ``predicted`` class (nearest in |Gamma|), ``eps_real``
    (None when metal is predicted) and its ``eps_real_interval``, ``observed_fraction`` of its
    area, and for a scene's object its ``true`` material and that material's ``true_eps_real``;
    with the fit at hand the ``readout``, its ``readout_spread``, the ``readout_classes`` its
    interval reaches and the ``source`` of the class (the module docstring)."""

    name: str
    predicted: str
    probabilities: dict[str, float]
    eps_real: float | None
    eps_real_interval: tuple[float, float] | None
    observed_fraction: float
    reflectivity: float | None = None  # None only in metrics.json files written before it was
    reflectivity_interval: tuple[float, float] | None = None
    true: str | None = None
    true_eps_real: float | None = None
    reference: bool = False  # the calibration reference: rendered as its stated material, not counted
    readout: float | None = None  # |Gamma| at normal incidence read from the data in closed form (None: not read)
    source: str = "head"  # what ``predicted`` reads: "head" or "data" (the readout)
    readout_spread: float | None = None  # the readout's jackknife standard error over views (None: not known)
    readout_classes: list[str] | None = None  # the classes the readout +- READOUT_SIGMAS spreads reaches

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class MaterialReport:
    """Per-object and per-component estimates, the class accuracy over the objects observed
    enough, and how the amplitudes were calibrated."""

    objects: list[MaterialEstimate]
    components: list[MaterialEstimate]
    accuracy: float | None
    calibration: str
    head_scale: float = 1.0  # the head's reflectivities were multiplied by it (estimate_materials)

    def as_dict(self) -> dict:
        return {"objects": [o.as_dict() for o in self.objects], "components": [c.as_dict() for c in self.components],
                "accuracy": self.accuracy, "min_observed_fraction": MIN_OBSERVED_FRACTION,
                "calibration": self.calibration, "head_scale": self.head_scale}


def _probabilities(field, points: torch.Tensor) -> torch.Tensor:
    """(N, K) class probabilities of the field at points (N, 3) [m], chunked, no gradient."""
    device = next(field.parameters()).device
    with torch.no_grad():
        return torch.cat([field.material(chunk.to(device).float()).cpu().double()
                          for chunk in points.split(_CHUNK)]) if len(points) else torch.zeros(0, len(field.materials))


def _weighted_quantiles(values: np.ndarray, weights: np.ndarray, quantiles) -> list[float]:
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order]) / weights.sum()
    return [float(values[order][min(np.searchsorted(cumulative, q), len(values) - 1)]) for q in quantiles]


def point_classes(probabilities: torch.Tensor, classes: tuple[str, ...], frequency_hz: float,
                  scale: float = 1.0) -> np.ndarray:
    """(Q,) int index into ``classes`` of the class nearest each point's reflectivity
    (probabilities (Q, K)) times ``scale``: the per-point readout of the tables."""
    names = reflectivity_class(point_reflectivity(probabilities, classes, frequency_hz) * scale, classes, frequency_hz)
    return np.array([classes.index(n) for n in names], dtype=np.int32)


def eps_of_reflectivity(reflectivity) -> np.ndarray:
    """The eps' of a lossless dielectric whose |Gamma| at normal incidence is ``reflectivity``:
    ((1 + r) / (1 - r))^2, r capped below 1 (metal)."""
    r = np.clip(np.asarray(reflectivity, dtype=float), 0.0, _MAX_REFLECTIVITY)
    return ((1 + r) / (1 - r)) ** 2


def _estimate(name: str, probabilities: torch.Tensor, area_m2: torch.Tensor, classes: tuple[str, ...],
              frequency_hz: float, observed_fraction: float, true=None, scale: float = 1.0) -> MaterialEstimate:
    """The estimate of one surface from the probabilities (Q, K) at its samples (areas (Q,)),
    its reflectivities times ``scale``."""
    weights = (area_m2.double() / area_m2.double().sum()).numpy()
    mean = (torch.as_tensor(weights)[:, None] * probabilities).sum(0)
    per_point = point_reflectivity(probabilities, classes, frequency_hz) * scale
    reflectivity = float((weights * per_point).sum())
    interval = tuple(_weighted_quantiles(per_point, weights, _INTERVAL))
    predicted = str(reflectivity_class(reflectivity, classes, frequency_hz))
    eps_real = eps_interval = None
    if not get_material(predicted).pec:
        eps_real = float(eps_of_reflectivity(reflectivity))
        eps_interval = tuple(float(e) for e in eps_of_reflectivity(interval))
    true_eps = None if true is None or true.pec else float(true.permittivity(frequency_hz).real)
    return MaterialEstimate(name, predicted, {c: float(v) for c, v in zip(classes, mean)}, eps_real, eps_interval,
                            observed_fraction, reflectivity, interval,
                            None if true is None else true.name, true_eps)


def _observed_objects(scene, acquisition: Acquisition, spacing_m: float, max_samples: int, seed: int):
    """Samples of ``scene``'s true surface and, per object, (its samples, those some view of
    ``acquisition`` observes, the observed share of its area): (samples, [(mine, seen, fraction)])."""
    samples = scene.sample_surface(spacing_m, seed=seed, max_samples=max_samples, stratified=True)
    observed = observed_mask(samples.points, samples.normals, acquisition, scene.sdf)
    rows = []
    for index in range(len(scene.objects)):
        mine = samples.object_index == index
        seen = mine & observed
        fraction = float(samples.area_m2[seen].sum() / samples.area_m2[mine].sum()) if bool(mine.any()) else 0.0
        rows.append((mine, seen, fraction))
    return samples, rows


def object_materials(field, scene, acquisition: Acquisition, *, spacing_m: float = 0.002,
                     max_samples: int = 40_000, seed: int = 0, scale: float = 1.0) -> list[MaterialEstimate]:
    """One estimate per object of ``scene``, from the field's head on the object's true
    surface where some view of ``acquisition`` observes it (all of it when none does); the
    head's reflectivities times ``scale`` (into the gain the materials are read in)."""
    samples, rows = _observed_objects(scene, acquisition, spacing_m, max_samples, seed)
    estimates = []
    for obj, (mine, seen, fraction) in zip(scene.objects, rows):
        area = samples.area_m2
        use = seen if bool(seen.any()) else mine
        estimates.append(_estimate(obj.name, _probabilities(field, samples.points[use]), area[use], field.materials,
                                   acquisition.center_frequency_hz, fraction, obj.material, scale=scale))
    return estimates


def _components(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """The connected components of ``mesh``, largest first; one of no area (degenerate faces of
    marching cubes) has no surface to read."""
    return sorted((c for c in mesh.split(only_watertight=False) if c.area > 0), key=lambda m: -m.area)


def component_materials(field, mesh: trimesh.Trimesh, acquisition: Acquisition, *, seed: int = 0,
                        scale: float = 1.0) -> list[MaterialEstimate]:
    """One estimate per connected component of the reconstruction's mesh (largest first),
    from samples of its surface, the observed share by the views' facing and cones (no
    shadows: tracing the neural field for every sample and view would cost more than the fit);
    the head's reflectivities times ``scale``."""
    estimates = []
    for index, component in enumerate(_components(mesh)):
        points, faces = trimesh.sample.sample_surface(component, _COMPONENT_SAMPLES, seed=seed + index)
        points = torch.as_tensor(np.asarray(points))
        normals = torch.as_tensor(np.asarray(component.face_normals[faces]))
        area = torch.full((len(points),), component.area / len(points), dtype=torch.float64)
        seen = observed_mask(points, normals, acquisition, None)
        use = seen if bool(seen.any()) else torch.ones(len(points), dtype=torch.bool)
        estimates.append(_estimate(f"component {index} ({component.area * 1e4:.1f} cm^2)",
                                   _probabilities(field, points[use]), area[use], field.materials,
                                   acquisition.center_frequency_hz, float(seen.double().mean()), scale=scale))
    return estimates


class Reading(NamedTuple):
    """The closed-form readout of N surfaces: ``value`` (N,) |Gamma| at normal incidence (NaN where
    the data show nothing of one) and ``spread`` (N,) its jackknife standard error over views (NaN
    where not known)."""

    value: np.ndarray
    spread: np.ndarray


def read_materials(trainer, mesh: trimesh.Trimesh, *, scene=None, reference: tuple[str, str] | None = None,
                   gain: float | None = None) -> tuple[Reading, Reading]:
    """|Gamma| at normal incidence read from the data in closed form (the module docstring) for a
    finished :class:`~rfsdf.recon.Trainer`: per object of ``scene`` (O,) (told apart by the true
    objects) and per component of ``mesh`` (C,) (as :func:`component_materials` orders them), NaN
    where the data show nothing of it, each with its spread over views. Scaled by the ``reference``
    (object name, stated material) as the fit was calibrated, else by ``gain`` (the radar's [data
    units per renderer unit]: a capture's, 1 for simulated data), else by the fit's
    :func:`known_gain`, else by the gain the finished fit wants."""
    from scipy.spatial import cKDTree

    from .recon.calibration import fitted_gain
    from .recon.material_readout import read_surface, with_primitives

    renderer, frequency_hz = trainer.renderer, trainer.problem.measurements.acquisition.center_frequency_hz
    gain = known_gain(trainer) if gain is None else gain
    if gain is None and reference is None:
        gain = fitted_gain(trainer)
    scale = {"gain": gain}
    objects = [] if scene is None else scene.objects
    if reference is not None:
        name, material = reference
        index = next(i for i, obj in enumerate(objects) if obj.name == name)
        scale = {"reference": (index, float(class_reflectivities((material,), frequency_hz)[0]))}
    parts = _components(mesh)
    if not parts:  # no surface was reconstructed: nothing to read
        return _unread(len(objects)), _unread(0)
    vertices = cKDTree(np.concatenate([part.vertices for part in parts]))
    labels = torch.as_tensor(np.repeat(np.arange(len(parts)), [len(part.vertices) for part in parts]))

    def component_of(anchors: torch.Tensor) -> torch.Tensor:  # the component of the nearest mesh vertex
        return labels[vertices.query(anchors.numpy())[1]]

    surface = with_primitives(trainer.field.sdf, trainer.primitives)
    segmenters = [(scene.object_index, len(objects))] if objects else []
    read = read_surface(renderer, surface, segmenters + [(component_of, len(parts))], **scale)
    if read[0].scale is None:  # the reference renders nothing where the data are bright: nothing is absolute
        return _unread(len(objects)), _unread(len(parts))
    by_object = Reading(read[0].reflectivity, read[0].spread) if objects else _unread(0)
    return by_object, Reading(read[-1].reflectivity, read[-1].spread)


def _unread(count: int) -> Reading:
    return Reading(np.full(count, np.nan), np.full(count, np.nan))


def known_gain(trainer) -> float | None:
    """The radar gain a finished fit's materials are read in, when one is known: the gain held in
    its loss (``Problem.gain``), else its config's ``calibration.gain`` (given after the relative fit)."""
    return trainer.problem.gain if trainer.problem.gain is not None else trainer.config.calibration.gain


def fit_materials(trainer, mesh: trimesh.Trimesh, *, scene=None, calibration=None, seed: int = 0) -> MaterialReport:
    """The report of a finished :class:`~rfsdf.recon.Trainer` as the demo and ``rfsdf materials``
    give it: :func:`estimate_materials` on ``mesh`` with the closed-form readout, both in one
    calibration: the reference's (``calibration``, the fit's
    :class:`~rfsdf.recon.calibration.Calibration`), else the gain held in the fit, else the config's
    ``calibration.gain`` given after the relative fit (the head's reflectivities times the fitted
    gain over it), else the gain the finished fit wants."""
    from .recon.calibration import fitted_gain

    stated = None if calibration is None else calibration.stated
    held, given = trainer.problem.gain, trainer.config.calibration.gain
    fitted = fitted_gain(trainer) if calibration is None and held is None and given is not None else None
    text = calibration_text(held if fitted is None else given, calibration, fitted=fitted)
    return estimate_materials(trainer.field, mesh, trainer.problem.measurements.acquisition, scene=scene, seed=seed,
                              calibration=text, reference=None if stated is None else stated[0],
                              readout=read_materials(trainer, mesh, scene=scene, reference=stated),
                              head_scale=1.0 if fitted is None else fitted / given)


def readout_classes(value: float, spread: float, classes: tuple[str, ...], frequency_hz: float) -> list[str]:
    """The ``classes`` nearest in |Gamma| at normal incidence to some reflectivity within ``value``
    +- ``READOUT_SIGMAS`` x ``spread``, in the order of ``classes``: those whose |Gamma| lies in that
    interval and those nearest its ends (each class is nearest on an interval of its own)."""
    low, high = value - READOUT_SIGMAS * spread, value + READOUT_SIGMAS * spread
    levels = class_reflectivities(classes, frequency_hz).numpy()
    reached = set(reflectivity_class(np.array([low, high]), classes, frequency_hz))
    return [c for c, level in zip(classes, levels) if c in reached or low <= level <= high]


def with_readout(estimate: MaterialEstimate, value: float, classes: tuple[str, ...], frequency_hz: float,
                 spread: float = float("nan")) -> MaterialEstimate:
    """``estimate`` with its closed-form ``value`` (NaN: not read) and its ``spread`` (NaN: not
    known) and, where that reads a passive surface (0 < value <= ``READOUT_CEILING``), the class
    and eps' it gives and the classes its interval reaches."""
    if not np.isfinite(value):
        return estimate
    known = float(spread) if np.isfinite(spread) else None
    if not 0 < value <= READOUT_CEILING:
        return replace(estimate, readout=float(value), readout_spread=known)
    predicted = str(reflectivity_class(value, classes, frequency_hz))
    eps_real = None if get_material(predicted).pec else float(eps_of_reflectivity(value))
    reached = None if known is None else readout_classes(value, known, classes, frequency_hz)
    return replace(estimate, readout=float(value), predicted=predicted, eps_real=eps_real, eps_real_interval=None,
                   source="data", readout_spread=known, readout_classes=reached)


def counts(observed_fraction: float, reference: bool, minimum: float = MIN_OBSERVED_FRACTION) -> bool:
    """Whether an object counts in the accuracy: observed at least ``minimum`` of its surface,
    and not a calibration reference (its material was given)."""
    return observed_fraction >= minimum and not reference


def class_accuracy(objects: list[MaterialEstimate]) -> float | None:
    """Share of the objects that :func:`counts` whose predicted class is their true material
    (None when none counts)."""
    counted = [o for o in objects if counts(o.observed_fraction, o.reference)]
    return None if not counted else sum(o.predicted == o.true for o in counted) / len(counted)


def estimate_materials(field, mesh: trimesh.Trimesh, acquisition: Acquisition, *, scene=None,
                       calibration: str, reference: str | None = None, seed: int = 0,
                       readout: tuple[Reading, Reading] | None = None, head_scale: float = 1.0) -> MaterialReport:
    """The full report: per object (with a scene; the object named ``reference`` marked as
    the calibration's), per component, with the ``readout`` of :func:`read_materials` when
    given, the accuracy. ``head_scale``: the factor that puts the head's reflectivities in the
    readout's gain (a relative fit read in a known gain: the fitted gain over the known one)."""
    objects = [] if scene is None else object_materials(field, scene, acquisition, seed=seed, scale=head_scale)
    objects = [replace(o, reference=o.name == reference) for o in objects]
    components = component_materials(field, mesh, acquisition, seed=seed, scale=head_scale)
    if readout is not None:
        read = partial(with_readout, classes=field.materials, frequency_hz=acquisition.center_frequency_hz)
        objects = [read(o, value, spread=spread) for o, value, spread in zip(objects, *readout[0])]
        components = [read(c, value, spread=spread) for c, value, spread in zip(components, *readout[1])]
    return MaterialReport(objects, components, class_accuracy(objects), calibration, head_scale)


def paint_mesh(field, mesh: trimesh.Trimesh, frequency_hz: float, scale: float = 1.0) -> trimesh.Trimesh:
    """``mesh`` with per-vertex properties that PLY files keep: ``material_class`` (int32 index
    into ``field.materials``, in the run's config.toml: the class nearest the vertex's
    reflectivity), ``reflectivity`` (float32, the head's |Gamma| at normal incidence at
    ``frequency_hz`` times ``scale``, as :func:`estimate_materials`'s ``head_scale``) and
    ``eps_real`` (float32; NaN where metal is nearest)."""
    classes = field.materials
    probabilities = _probabilities(field, torch.as_tensor(np.asarray(mesh.vertices)))
    reflectivity = point_reflectivity(probabilities, classes, frequency_hz) * scale
    index = point_classes(probabilities, classes, frequency_hz, scale)
    pec = np.array([get_material(c).pec for c in classes])[index]
    painted = mesh.copy()
    painted.vertex_attributes.update(material_class=index, reflectivity=reflectivity.astype(np.float32),
                                     eps_real=np.where(pec, np.nan, eps_of_reflectivity(reflectivity)).astype(np.float32))
    return painted


class _ReportFields(pydantic.BaseModel):
    """What a reader needs of metrics.json's "materials" (``MaterialReport.as_dict()``)."""

    model_config = pydantic.ConfigDict(extra="allow", allow_inf_nan=False)

    objects: list[MaterialEstimate]  # validated as the dataclass's fields
    components: list[MaterialEstimate]
    accuracy: float | None
    min_observed_fraction: float
    calibration: str
    head_scale: pydantic.PositiveFloat = 1.0  # absent in files written before it


def check_materials_dict(materials, source: str) -> dict:
    """``materials`` as read from a file, refused in one line naming ``source`` and the field
    when it is not a report :func:`materials_table` can print."""
    validate(_ReportFields, materials, f"{source}: materials")
    return materials


def scene_reference(scene, calibration, acquisition: Acquisition, *, source: str = "calibration.reference",
                    spacing_m: float = 0.002, max_samples: int = 40_000):
    """The :class:`~rfsdf.recon.calibration.Reference` that ``calibration`` (a
    CalibrationConfig with a reference) names in ``scene``; RfsdfError naming ``source`` when
    the scene has no such object or no view of ``acquisition`` observes any of its surface
    (a reference the data do not see calibrates nothing; a sphere's glint, a few per cent of
    its surface, is enough)."""
    from .errors import RfsdfError
    from .recon.calibration import Reference

    name = calibration.reference_object
    names = [o.name for o in scene.objects]
    if name not in names:
        raise RfsdfError(f"{source}: scene {scene.name!r} has no object {name!r} (it has {', '.join(names)})")
    index = names.index(name)
    _, rows = _observed_objects(scene, acquisition, spacing_m, max_samples, seed=0)
    _, _, fraction = rows[index]
    if fraction == 0:
        raise RfsdfError(f"{source}: object {name!r} is observed by no view (it faces away from every view, "
                         "or another object shadows it): it cannot calibrate")
    others = [o.sdf for i, o in enumerate(scene.objects) if i != index]
    rest = None if not others else (lambda p: torch.stack([sdf(p) for sdf in others]).min(0).values)
    return Reference(name, calibration.reference_material, scene.objects[index].sdf, rest,
                     calibration.reference_distance_m)


def calibration_text(gain: float | None, reference=None, *, fitted: float | None = None) -> str:
    """How a fit's amplitudes were calibrated, in words: by a reference object (its
    :class:`~rfsdf.recon.calibration.Calibration`), else by a known ``gain``, held in the fit or,
    with the relative fit's own ``fitted`` gain, given after it; else relative."""
    if reference is not None:
        warning = reference.warning()
        return reference.text() + ("" if warning is None else f". WARNING: {warning}")
    if gain is None:
        return "relative: one gain fitted at each step, so only the ratios of the surfaces' |Gamma| are data"
    if fitted is not None:
        return f"known radar gain {gain:g}, given after the relative fit (its own gain {fitted:.3g})"
    return f"known radar gain {gain:g}"


def materials_table(materials: dict) -> str:
    """The material estimates of a result (``MaterialReport.as_dict()``, as in metrics.json):
    one line per object and per component, then the accuracy and the calibration."""
    def number(value) -> str:
        return "-" if value is None else f"{value:.2f}"

    with_truth = bool(materials["objects"])  # a column of true classes, blank for the components

    def line(e: dict) -> str:
        eps = number(e["eps_real"])
        if e["eps_real_interval"] is not None:
            eps += f" [{e['eps_real_interval'][0]:.2f}, {e['eps_real_interval'][1]:.2f}]"
        truth = f"{e.get('true') or '':<13}" if with_truth else ""
        if e.get("reference"):
            return f"  {e['name']:<26}{truth}(the calibration reference, rendered as stated)"
        spread = e.get("readout_spread")
        others = [c for c in e.get("readout_classes") or [] if c != e["predicted"]]
        return (f"  {e['name']:<26}{truth}{e['predicted']:<13}{e.get('source', 'head'):<6}"
                f"{number(e.get('reflectivity')):>6}{number(e.get('readout')):>6}"
                f"{number(None if spread is None else READOUT_SIGMAS * spread):>6}  {eps:<22}"
                f"{e['observed_fraction']:>6.0%}" + (f"  or {', '.join(others)}" if others else ""))

    head = f"  {'':<26}" + ("true         " if with_truth else "")
    lines = ["materials (the class nearest |Gamma| at normal incidence, from the data's closed-form readout where it "
             f"reads a passive surface, else from the head; the readout +- {READOUT_SIGMAS:g} jackknife spreads over "
             "the views, 'or' the other classes that interval reaches; eps' [10-90 % of the head's surface]; "
             "observed share):",
             head + f"{'predicted':<13}{'from':<6}{'head':>6}{'data':>6}{'+-':>6}  {'eps_real':<22}{'seen':>6}"]
    lines += [line(e) for e in materials["objects"]] + [line(e) for e in materials["components"]]
    accuracy = materials["accuracy"]
    counted = [e for e in materials["objects"]
               if counts(e["observed_fraction"], e.get("reference", False), materials["min_observed_fraction"])]
    told = sum(len(e.get("readout_classes") or []) == 1 for e in counted)
    apart = (f" ({told} of {len(counted)} told from every other class by the readout's interval)"
             if any(e.get("readout_classes") for e in counted) else "")  # none: no interval (a file from before it)
    lines.append(f"  accuracy {'-' if accuracy is None else f'{accuracy:.0%}'} over objects at least "
                 f"{materials['min_observed_fraction']:.0%} observed{apart}; calibration: {materials['calibration']}")
    return "\n".join(lines)


def _run_trainer(folder, state: dict, measurements, data_path, scene, stated: tuple[str, str] | None):
    """The finished :class:`~rfsdf.recon.Trainer` of a ``reconstruct`` run folder, rebuilt from its
    checkpoint (config, grid, field, primitives) and ``measurements``; or why it cannot be, in words."""
    from .errors import RfsdfError
    from .geometry import Grid
    from .recon import Problem, ReconConfig, Trainer
    from .recon.checkpoint import CHECKPOINT_NAME

    if "grid" not in state:
        return "the run's checkpoint keeps no grid (written before rfsdf kept one)"
    if stated is not None and (scene is None or stated[0] not in [o.name for o in scene.objects]):
        return f"the calibration reference {stated[0]} needs --scene, a scene file that places it"
    try:
        held = state["grid"]
        box = [tuple(map(float, held[key])) for key in ("lower_m", "upper_m")]
        if not np.isfinite(box).all():
            raise ValueError("its box is not finite")
        grid = Grid(*box, tuple(map(int, held["shape"])))
    except (KeyError, TypeError, ValueError) as exc:
        raise RfsdfError(f"{folder / CHECKPOINT_NAME}: grid: not a grid rfsdf wrote ({exc})") from None
    gain = state.get("gain")
    if gain is not None and not (isinstance(gain, (int, float)) and np.isfinite(gain) and gain > 0):
        raise RfsdfError(f"{folder / CHECKPOINT_NAME}: gain: not a gain rfsdf wrote ({gain!r})")
    problem = Problem(measurements, grid, str(data_path), gain=gain)
    if problem.digest() != state.get("data_digest"):
        return (f"{data_path} on the run's grid is not what it was fitted on (a background taken out, "
                "a scene seen through?)")
    config = validate(ReconConfig, state.get("config"), f"{folder / CHECKPOINT_NAME}: config").on_device("cpu")
    trainer = Trainer(problem, config, folder)
    trainer.load()
    return trainer


def run_materials(folder, *, data_path=None, scene_name: str | None = None) -> str:
    """The table of :func:`materials_table` for a demo folder (its metrics.json) or a
    ``reconstruct`` run folder (its field's head on its mesh.ply and the closed-form readout of
    its fit, seen by the views of the measurements at ``data_path``, default the file its
    checkpoint names; rows per object of the scene ``scene_name`` when given; where the readout
    cannot be read, a last line says why)."""
    import json
    from pathlib import Path

    from .errors import RfsdfError
    from .limits import input_file
    from .mesh import extract_mesh
    from .radar import read_measurements
    from .recon import load_field
    from .recon.calibration import CALIBRATION_NAME, Calibration
    from .recon.checkpoint import CHECKPOINT_NAME, read_checkpoint
    from .scene import load_scene

    folder = Path(folder)
    if (folder / "metrics.json").is_file():
        try:
            materials = json.loads(input_file(folder / "metrics.json").read_text()).get("materials")
        except (ValueError, AttributeError) as exc:
            raise RfsdfError(f"{folder / 'metrics.json'}: not readable JSON ({exc})") from None
        if materials is None:
            raise RfsdfError(f"{folder / 'metrics.json'}: materials: the fit had no material head (--no-materials)")
        return materials_table(check_materials_dict(materials, str(folder / "metrics.json")))
    field = load_field(folder)
    if field.material_head is None:
        raise RfsdfError(f"{folder}: the fit had no material head (field.materials = [] in its config.toml)")
    state = read_checkpoint(folder / CHECKPOINT_NAME, "cpu")
    data_path = data_path or state.get("data_source")
    if data_path is None or not Path(data_path).is_file():
        raise RfsdfError(f"{folder}: the measurements it was fitted on ({data_path}) are not at hand; pass --data")
    measurements = read_measurements(data_path)
    mesh_path = folder / "mesh.ply"
    mesh = (trimesh.load(mesh_path, force="mesh") if mesh_path.is_file()
            else extract_mesh(field.sdf, field.lower_m, field.upper_m, 96))
    scene = load_scene(scene_name) if scene_name is not None else None
    reference, stated = None, None  # the reference's calibration of the fit, and (its object, its material)
    if (folder / CALIBRATION_NAME).is_file():
        try:
            held = json.loads(input_file(folder / CALIBRATION_NAME).read_text())
            reference = Calibration(held["reference"], float(held["gain"]),
                                    None if held["ratio"] is None else float(held["ratio"]))
            stated = reference.stated
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise RfsdfError(f"{folder / CALIBRATION_NAME}: not a calibration rfsdf wrote ({exc})") from None
    trainer = _run_trainer(folder, state, measurements, data_path, scene, stated)
    if not isinstance(trainer, str):
        return materials_table(fit_materials(trainer, mesh, scene=scene, calibration=reference).as_dict())
    report = estimate_materials(field, mesh, measurements.acquisition, scene=scene, reference=stated and stated[0],
                                calibration=calibration_text(state.get("gain"), reference))
    try:
        given = state["config"]["calibration"]["gain"]  # a known gain given after the relative fit
    except (KeyError, TypeError):
        given = None
    unscaled = "" if given is None else f"; the head's reflectivities stay relative, not in the known gain {given}"
    return materials_table(report.as_dict()) + f"\n  (no closed-form readout: {trainer}{unscaled})"
