"""A scene model: a scene file whose shape parameters may be free, for the primitive fit.

Written like a scene file (``rfsdf.scene_spec``); any numeric parameter of a shape (a
length, a vector of lengths, a transform's ``translate_m``) may instead be a table::

    center_m = { start = [0.4, -1.9, 1.5], free = true, bounds_m = 0.3 }

``start`` is where the fit begins; ``free`` (default true) whether it is fitted or held at
its start; ``bounds_m`` how far the fit may take it: a number, the most each component may
move from the start [m], or ``[lower, upper]``, absolute bounds (numbers, or vectors like
the start). Materials are the objects' own (a free material is not built yet).
``SceneModel.from_scene`` makes the start model ``reconstruct --model primitive --scene``
uses without a model file: the true scene with every length parameter free and moved by a
seeded random offset; its mesh objects that are boxes (a ray tracer's room, a wall as one
quad) written first as analytic boxes (:func:`analytic_spec`), so that their lengths are free too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import read_toml, validate
from .errors import RfsdfError
from .materials import MATERIAL_CLASSES, get_material
from .scene import Scene, is_shell
from .scene_spec import SceneSpec

__all__ = ["FreeParameter", "FreeMaterial", "SceneModel", "analytic_spec", "load_scene_model", "POSITION_FIELDS",
           "SIZE_FIELDS"]

POSITION_FIELDS = ("center_m", "point_m", "start_m", "end_m", "translate_m")  # may move either way
SIZE_FIELDS = ("half_extents_m", "radius_m", "height_m", "major_radius_m", "minor_radius_m")  # stay positive
# a free size's lower bound is at least this [m], whatever its bounds_m say: a fitted window pane
# 2 cm thick reached a negative half extent on l-room and stopped the fit
MIN_SIZE_M = 1e-4
_KEYS = {"start", "free", "bounds_m"}
_MATERIAL_KEYS = {"start", "free", "classes"}


@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter: ``name`` (object and field, e.g. ``west.center_m``), ``path``
    into the scene spec, its ``start`` and bounds (lists of floats, one per component; a
    scalar parameter has one), and whether it is a ``scalar``."""

    name: str
    path: tuple
    start: list[float]
    lower: list[float]
    upper: list[float]
    scalar: bool


@dataclass(frozen=True)
class FreeMaterial:
    """One object's fitted material: the object's ``name`` and ``index``, the ``classes`` it
    may be (catalogue names) and the ``start`` class (None: undecided)."""

    name: str
    index: int
    classes: tuple[str, ...]
    start: str | None


def _material(table: dict, where: str) -> tuple[str, tuple[str, ...] | None, str | None]:
    """A material table as (the material to put in the scene file, its classes or None when
    held, its start or None)."""
    unknown = set(table) - _MATERIAL_KEYS
    if unknown:
        raise RfsdfError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} (a material table has "
                         "start, free, classes)")
    free = table.get("free", True)
    if not isinstance(free, bool):
        raise RfsdfError(f"{where}.free: expected true or false, got {free!r}")
    classes = table.get("classes", list(MATERIAL_CLASSES))
    if not isinstance(classes, list) or len(classes) < 2 or not all(isinstance(c, str) for c in classes):
        raise RfsdfError(f"{where}.classes: expected a list of at least two material names, got {classes!r}")
    try:
        classes = tuple(get_material(c).name for c in classes)
        start = None if table.get("start") is None else get_material(str(table["start"])).name
    except ValueError as exc:
        raise RfsdfError(f"{where}: {exc} (a free material is one of the catalogue's)") from None
    if len(set(classes)) != len(classes):
        raise RfsdfError(f"{where}.classes: a class is named twice in {list(classes)}")
    if not free:
        if start is None:
            raise RfsdfError(f"{where}: a held material needs a start")
        return start, None, start
    if start is not None and start not in classes:
        raise RfsdfError(f"{where}.start: {start!r} is not among the classes {list(classes)}")
    return start or classes[0], classes, start


def _is_parameter_table(value) -> bool:
    return isinstance(value, dict) and bool(_KEYS & set(value)) and "type" not in value


def _components(value, where: str) -> tuple[list[float], bool]:
    """A number or a list of numbers as (list of floats, scalar?)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, list)):
        raise RfsdfError(f"{where}: expected a number or a list of numbers, got {value!r}")
    items = value if isinstance(value, list) else [value]
    if not items or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                        for v in items):
        raise RfsdfError(f"{where}: expected finite numbers, got {value!r}")
    return [float(v) for v in items], not isinstance(value, list)


def _parameter(table: dict, where: str, size: bool) -> tuple[object, FreeParameter | None]:
    """The start value to put in the scene file and the FreeParameter (None when held); a
    ``size`` (a SIZE_FIELDS parameter) keeps its lower bounds at least ``MIN_SIZE_M``."""
    unknown = set(table) - _KEYS
    if unknown:
        raise RfsdfError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} (a parameter table has "
                         "start, free, bounds_m)")
    if "start" not in table:
        raise RfsdfError(f"{where}: a parameter table needs a start")
    start, scalar = _components(table["start"], f"{where}.start")
    free = table.get("free", True)
    if not isinstance(free, bool):
        raise RfsdfError(f"{where}.free: expected true or false, got {free!r}")
    bounds = table.get("bounds_m")
    if bounds is None:
        lower, upper = [-math.inf] * len(start), [math.inf] * len(start)
    elif isinstance(bounds, list) and len(bounds) == 2 and (scalar or all(isinstance(b, list) for b in bounds)):
        lower = _components(bounds[0], f"{where}.bounds_m[0]")[0]
        upper = _components(bounds[1], f"{where}.bounds_m[1]")[0]
    else:
        margin, one = _components(bounds, f"{where}.bounds_m")
        if not one or margin[0] <= 0:
            raise RfsdfError(f"{where}.bounds_m: expected a positive number (the most it may move [m]) or "
                             f"[lower, upper] (vectors for a vector), got {bounds!r}")
        lower, upper = [s - margin[0] for s in start], [s + margin[0] for s in start]
    if not len(lower) == len(upper) == len(start):
        raise RfsdfError(f"{where}.bounds_m: start has {len(start)} component(s), its bounds another count")
    if size:
        lower = [max(lo, MIN_SIZE_M) for lo in lower]
    if any(not lo <= s <= hi for lo, s, hi in zip(lower, start, upper)):
        raise RfsdfError(f"{where}.start: {table['start']!r} is outside its bounds {lower} .. {upper}")
    value = start[0] if scalar else start
    return value, (FreeParameter("", (), start, lower, upper, scalar) if free else None)


def _substitute(node, path: tuple, where: str, found: list) -> object:
    """``node`` with every parameter table replaced by its start; the free ones appended to
    ``found`` as (path, FreeParameter)."""
    if _is_parameter_table(node):
        value, parameter = _parameter(node, where, bool(path) and path[-1] in SIZE_FIELDS)
        if parameter is not None:
            found.append((path, parameter))
        return value
    if isinstance(node, dict):
        return {k: _substitute(v, path + (k,), f"{where}.{k}", found) for k, v in node.items()}
    if isinstance(node, list):
        return [_substitute(v, path + (i,), f"{where}[{i}]", found) for i, v in enumerate(node)]
    return node


@dataclass(frozen=True)
class SceneModel:
    """A scene spec at its start, the parameters the fit may move, where it came from (for
    messages) and the folder its mesh paths are relative to."""

    spec: SceneSpec
    free: list[FreeParameter]
    source: str
    base_dir: Path = Path(".")
    materials: tuple[FreeMaterial, ...] = ()  # the objects whose material is fitted

    @classmethod
    def from_table(cls, table: dict, source: str, base_dir: Path = Path(".")) -> SceneModel:
        """A model from a parsed TOML table; RfsdfError 'source: field: reason' on bad input."""
        found: list = []
        substituted, materials = {}, []
        for key, value in table.items():
            if key == "objects" and isinstance(value, list):
                substituted[key] = []
                for i, obj in enumerate(value):
                    where = f"{source}: objects[{i}]"
                    if isinstance(obj, dict) and isinstance(obj.get("material"), dict):
                        material, classes, start = _material(obj["material"], f"{where}.material")
                        obj = {**obj, "material": material}
                        if classes is not None:
                            materials.append(FreeMaterial(str(obj.get("name")), i, classes, start))
                    substituted[key].append(_substitute(obj, ("objects", i), where, found)
                                            if isinstance(obj, dict) else obj)
            elif _is_parameter_table(value) or (isinstance(value, dict) and any(map(_is_parameter_table,
                                                                                 value.values()))):
                raise RfsdfError(f"{source}: {key}: only the objects' shape parameters may be free")
            else:
                substituted[key] = value
        spec = validate(SceneSpec, substituted, source)
        free = []
        for path, parameter in found:
            if len(path) < 3 or path[2] != "shape":
                raise RfsdfError(f"{source}: {_dotted(path)}: only the objects' shape parameters may be free")
            name = f"{spec.objects[path[1]].name}.{_dotted(path[3:])}"
            free.append(FreeParameter(name, path, parameter.start, parameter.lower, parameter.upper, parameter.scalar))
        return cls(spec, free, source, base_dir, tuple(materials))

    @classmethod
    def from_scene(cls, scene: Scene, offset_m: float, seed: int, *, free_materials: bool = False) -> SceneModel:
        """``scene`` (its :func:`analytic_spec`) with every length parameter of every shape
        free, its start moved from the truth by a uniform random offset in [-offset_m,
        offset_m] per component (sizes kept at least half their true value), bounds 2 x
        offset_m about the start; ``free_materials``: every object's material free too,
        undecided among ``MATERIAL_CLASSES``, but the scene's ``calibration_reference``."""
        rng = np.random.default_rng(seed)
        table = analytic_spec(scene).model_dump(mode="json")
        if free_materials:
            for obj in table["objects"]:
                if obj["name"] != table.get("calibration_reference"):
                    obj["material"] = {"free": True}

        def free_lengths(node, offsets: dict | None = None):
            """Free every length under ``node``, each moved by a fresh random offset, or by
            ``offsets`` (key: offset) where given; returns the offsets drawn at this level."""
            drawn = {}
            if isinstance(node, dict):
                # a shell's two boxes move as one (drawn apart, box_knife's 1 cm wall moved 15 cm lost
                # three of its faces): the inner box first, the outer by the same offsets
                shell = is_shell(node)
                if shell:
                    free_lengths(node["children"][0], free_lengths(node["children"][1]))
                for key, value in list(node.items()):
                    if shell and key == "children":
                        continue  # freed above; the shell's own transform is freed as any shape's
                    if key in POSITION_FIELDS + SIZE_FIELDS and value is not None and not _is_parameter_table(value):
                        truth = np.atleast_1d(np.asarray(value, dtype=float))
                        drawn[key] = (offsets[key] if offsets and key in offsets
                                      else rng.uniform(-offset_m, offset_m, size=truth.shape))
                        start = truth + drawn[key]
                        if key in SIZE_FIELDS:
                            start = np.maximum(start, truth / 2)
                        margin = 2 * offset_m
                        start_value = float(start[0]) if np.ndim(value) == 0 else start.tolist()
                        node[key] = {"start": start_value, "free": True, "bounds_m": margin}
                    else:
                        free_lengths(value)
            elif isinstance(node, list):
                for item in node:
                    free_lengths(item)
            return drawn

        for obj in table["objects"]:
            free_lengths(obj["shape"])
        what = "every length and material" if free_materials else "every length"
        return cls.from_table(table, f"scene {scene.name!r} with {what} free", scene.base_dir)

    def require_free(self) -> None:
        """RfsdfError 'source: no free parameter ...' when nothing in the model may move (a
        scene of mesh shapes placed by to_world matrices has no length to free)."""
        if not self.free and not self.materials:
            raise RfsdfError(f"{self.source}: no free parameter, so nothing to fit (a mesh that is not a box has no "
                             "lengths to free; give a model file of analytic shapes with parameter tables)")

    def require_overlap(self, lower_m, upper_m, what: str) -> None:
        """RfsdfError 'source: bounds: ...' when the model's box does not overlap the box
        ``lower_m`` .. ``upper_m`` (3,) [m] (``what``: whose box it is, for the message)."""
        lower, upper = self.spec.bounds.lower_m, self.spec.bounds.upper_m
        if any(lo >= mu or ml >= up for lo, up, ml, mu in zip(lower_m, upper_m, lower, upper)):
            raise RfsdfError(f"{self.source}: bounds: the model's box {list(lower)} .. {list(upper)} does not overlap "
                             f"{what} {list(lower_m)} .. {list(upper_m)}")

    def fitted_spec(self, values: list[list[float]], materials: list[str] = ()) -> SceneSpec:
        """The scene spec with the free parameters at ``values`` (one list per parameter, as
        :attr:`free`) and the free materials ``materials`` (one name each, as
        :attr:`materials`): the fitted scene, a scene file like any other."""
        table = self.spec.model_dump(mode="json")
        for free, name in zip(self.materials, materials):
            table["objects"][free.index]["material"] = name
        for parameter, value in zip(self.free, values):
            node = table
            for step in parameter.path[:-1]:
                node = node[step]
            node[parameter.path[-1]] = value[0] if parameter.scalar else list(value)
        return SceneSpec.model_validate(table)

    def values_in(self, spec: SceneSpec) -> list[list[float]] | None:
        """The free parameters' values in another spec of the same structure (the truth, for
        a report), or None when it has not the same objects and shapes."""
        try:
            table, out = spec.model_dump(mode="json"), []
            for parameter in self.free:
                node = table
                for step in parameter.path:
                    node = node[step]
                out.append([float(v) for v in np.atleast_1d(node)])
            return out
        except (KeyError, IndexError, TypeError):
            return None

    def materials_in(self, spec: SceneSpec) -> list[str] | None:
        """The free materials' objects' materials in another spec of the same objects (the
        truth), or None when it has not the same objects."""
        names = [o.name for o in spec.objects]
        if names != [o.name for o in self.spec.objects]:
            return None
        return [spec.material(spec.objects[m.index].material).name for m in self.materials]

    def shell_ties(self) -> list[tuple[int, int]]:
        """(outer, inner) indices into :attr:`free` of each length a shell's two boxes both
        free (:func:`~rfsdf.scene.is_shell`): the fit moves the outer with the inner, their start's
        difference kept, so that a thin wall neither thickens nor vanishes (its outer faces,
        unseen from inside a room, would hold while the inner ones pass them)."""
        index = {p.path: i for i, p in enumerate(self.free)}
        ties = []
        for i, parameter in enumerate(self.free):
            path = parameter.path
            if len(path) < 3 or path[-3] != "children" or path[-2] != 0:
                continue
            partner = index.get(path[:-2] + (1, path[-1]))
            shape, _ = self.node(path[:-2])
            if partner is not None and is_shell(shape.model_dump(mode="json")):
                ties.append((i, partner))
        return ties

    def node(self, path: tuple):
        """(spec node, field name) that ``path`` points at in :attr:`spec`."""
        node = self.spec
        for step in path[:-1]:
            node = node[step] if isinstance(step, int) else getattr(node, step)
        return node, path[-1]


def analytic_spec(scene: Scene) -> SceneSpec:
    """``scene``'s spec with each mesh object that is a box (:func:`~rfsdf.geometry.cuboids.cuboid_of`:
    a closed cuboid read as a solid or a shell, an open rectangle read as a sheet) written
    as the analytic box (a shell: the box ``thickness_m`` larger less the mesh's box) with
    the same SDF; every other object as it is. A box whose axes are not the scene's is a
    box about the origin turned and moved by its ``transform``."""
    table = scene.spec.model_dump(mode="json")
    for obj, spec, row in zip(scene.objects, scene.spec.objects, table["objects"]):
        if obj.reading is not None and obj.reading.box:  # the box the scene found at load (scene.box_table)
            row["shape"] = obj.reading.box_shape
    return SceneSpec.model_validate(table)


def _dotted(path: tuple) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")


def load_scene_model(path) -> SceneModel:
    """A scene model from a TOML file; RfsdfError 'file: field: reason' on bad input."""
    path = Path(path)
    return SceneModel.from_table(read_toml(path), str(path), path.parent)
