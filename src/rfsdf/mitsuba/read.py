"""Read a Sionna RT scene (a Mitsuba 3 XML file with PLY/OBJ meshes) as an rfsdf scene.

The subset that Sionna RT's scenes and its Blender export use, no more: ``<scene>``,
``<default>`` and ``$name`` substitution, ``<bsdf type="itu-radio-material">`` (``type``,
``thickness``) and ``<bsdf type="radio-material">`` (``relative_permittivity``,
``conductivity``, ``thickness``), ``<shape>`` of type ply, obj (``filename`` inside the
XML's folder) and Mitsuba's rectangle, cube, disk, sphere and cylinder, with ``<ref>`` or
a nested bsdf and a ``<transform name="to_world">`` of translate, rotate, scale and
matrix. Anything else is one error line naming the element, its line and what is
supported.

Mitsuba's shapes are surfaces and rfsdf's objects solids (:class:`~rfsdf.scene_spec.MeshShapeSpec`):
a closed mesh is read as a solid (a shell of the material's thickness when a radar stands
inside it, :meth:`rfsdf.scene.Scene.around_radar`), an open one as a slab of the material's
thickness centred on it. Units are metres, as in Sionna.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import defusedxml
import defusedxml.ElementTree
import numpy as np
import trimesh

from ..config import validate
from ..errors import RfsdfError
from ..geometry.mesh_sdf import load_mesh
from ..geometry.unit_shapes import UNIT_SHAPES, unit_shape
from ..limits import input_file
from ..materials import get_material
from ..scene_spec import SceneSpec
from .ply import check_mesh_file

__all__ = ["read_mitsuba_scene", "is_xml_file", "SIONNA_DEFAULT_THICKNESS_M", "MAX_SHAPES", "MAX_EXTENT_M"]

SIONNA_DEFAULT_THICKNESS_M = 0.1  # Sionna RT's thickness of a radio material that names none
MAX_XML_BYTES = 16 * 2**20  # a room's scene file is a few kB; a city's tens of MB
MAX_SHAPES = 1000
"""More shapes than this is a city or a street, not a scene rfsdf can simulate (its room-scale
simulator needs about a million facets for a 6 x 4 x 3 m room at 60 GHz)."""
MAX_EXTENT_M = 50.0
"""The largest scene extent read: a building floor. Beyond, a simulation at mmWave would need
billions of facets."""
_MARGIN_M = 0.1  # bounds beyond the meshes' extent (plus the thickest sheet's half thickness)
_SUBSTITUTION = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
_MESH_TYPES = ("ply", "obj")
_MATERIAL_TYPES = ("itu-radio-material", "radio-material")
# Properties of a material that are visual only (Sionna's colour in its previews): read and ignored.
_VISUAL = ("color", "reflectance", "base_color")


class _Located(ET.TreeBuilder):
    """A tree builder that remembers the line of each element's start tag."""

    def __init__(self):
        super().__init__()
        self.parser = None
        self.lines: dict[ET.Element, int] = {}

    def start(self, tag, attrs):
        element = super().start(tag, attrs)
        self.lines[element] = self.parser.parser.CurrentLineNumber
        return element


def is_xml_file(path) -> bool:
    """True when the file's first non-blank character is '<' (an XML scene, not a TOML one)."""
    with open(path, "rb") as fh:
        head = fh.read(256).lstrip(b"\xef\xbb\xbf \t\r\n")
    return head.startswith(b"<")


def _parse(path: Path) -> tuple[ET.Element, dict]:
    """The root element and the line of every element; hostile XML (entity expansion, external
    entities, a DTD) is refused by defusedxml before anything expands."""
    if path.stat().st_size > MAX_XML_BYTES:
        raise RfsdfError(f"{path}: {path.stat().st_size / 2**20:.0f} MiB is more than the {MAX_XML_BYTES // 2**20} MiB "
                         "a scene file rfsdf can simulate needs (a city?)")
    builder = _Located()
    parser = defusedxml.ElementTree.DefusedXMLParser(target=builder, forbid_dtd=True)
    builder.parser = parser
    try:
        with path.open("rb") as fh:
            while chunk := fh.read(2**16):
                parser.feed(chunk)
        root = parser.close()
    except defusedxml.DefusedXmlException as exc:
        raise RfsdfError(f"{path}: refused: {exc} (DTDs and entities are not read)") from None
    except ET.ParseError as exc:
        raise RfsdfError(f"{path}: invalid XML: {exc}") from None
    return root, builder.lines


class _Reader:
    """One pass over a parsed scene file; every error names the file and the element's line."""

    def __init__(self, path: Path, root: ET.Element, lines: dict):
        self.path, self.root, self.lines = path, root, lines
        self.defaults: dict[str, str] = {}
        self.materials: dict[str, tuple[str, float]] = {}  # bsdf id -> (rfsdf material name, thickness)
        self.custom: list[dict] = []  # [[materials]] of the scene spec
        self.objects: list[dict] = []
        self.surfaces: list[trimesh.Trimesh] = []

    def fail(self, element: ET.Element, reason: str):
        raise RfsdfError(f"{self.path}: line {self.lines.get(element, '?')}: <{element.tag}"
                         f"{' type=' + repr(element.get('type')) if element.get('type') else ''}>: {reason}")

    def attr(self, element: ET.Element, key: str, required: bool = True) -> str | None:
        """Attribute ``key`` with ``$name`` defaults substituted."""
        value = element.get(key)
        if value is None:
            if required:
                self.fail(element, f"needs the attribute {key!r}")
            return None

        def substitute(match):
            if match.group(1) not in self.defaults:
                self.fail(element, f"${match.group(1)} has no <default name={match.group(1)!r}>")
            return self.defaults[match.group(1)]

        return _SUBSTITUTION.sub(substitute, value)

    def number(self, element: ET.Element, key: str = "value") -> float:
        text = self.attr(element, key)
        try:
            value = float(text)
        except ValueError:
            self.fail(element, f"{key}={text!r} is not a number")
        if not np.isfinite(value):
            self.fail(element, f"{key}={text!r} is not finite")
        return value

    def vector(self, element: ET.Element, key: str = "value", missing: float = 0.0) -> np.ndarray:
        """x, y, z attributes (an absent one is ``missing``: 1 for a scale, as Mitsuba 3
        reads it, 0 otherwise), or ``key`` holding three numbers (commas or spaces)."""
        if element.get(key) is None and any(element.get(axis) is not None for axis in "xyz"):
            return np.array([self.number(element, axis) if element.get(axis) is not None else missing
                             for axis in "xyz"])
        parts = self.attr(element, key).replace(",", " ").split()
        if len(parts) == 1:
            parts = parts * 3
        try:
            values = np.array([float(p) for p in parts])
        except ValueError:
            self.fail(element, f"{key} must be three numbers")
        if len(values) != 3 or not np.isfinite(values).all():
            self.fail(element, f"{key} must be three finite numbers")
        return values

    def properties(self, element: ET.Element, allowed: dict[str, str],
                   structural: tuple[str, ...] = ()) -> dict[str, ET.Element]:
        """The property children (``<float name=...>`` ...) of ``element`` by name; children
        whose tag is in ``structural`` are left to the caller; any other child is an error
        naming what is admitted (``allowed``: {name: tag})."""
        found = {}
        for child in element:
            name = child.get("name")
            if child.tag in structural or name in _VISUAL:
                continue
            if name not in allowed or child.tag != allowed[name]:
                supported = ", ".join([*(f"<{tag}>" for tag in structural),
                                       *(f"<{tag} name={n!r}>" for n, tag in allowed.items())]) or "none"
                self.fail(child, f"not supported inside <{element.tag} type={element.get('type')!r}> "
                                 f"(supported: {supported})")
            found[name] = child
        return found

    # Scene elements ---------------------------------------------------------------
    def read(self) -> dict:
        if self.root.tag != "scene":
            self.fail(self.root, "the root element must be <scene>")
        shapes = [e for e in self.root if e.tag == "shape"]
        if len(shapes) > MAX_SHAPES:
            raise RfsdfError(f"{self.path}: {len(shapes)} shapes: more than the {MAX_SHAPES} rfsdf reads. A city or "
                             "street scene is beyond what rfsdf simulates (rooms and objects, a few metres at mmWave); "
                             "cut out the part you need")
        for element in self.root:
            if element.tag == "default":
                self.defaults[self.attr(element, "name")] = self.attr(element, "value")
            elif element.tag == "bsdf":
                self.material(element)
            elif element.tag == "shape":
                self.shape(element)
            else:
                self.fail(element, "not supported (supported: <default>, <bsdf>, <shape>)")
        if not self.objects:
            raise RfsdfError(f"{self.path}: no <shape> in the scene")
        return self.spec()

    def material(self, element: ET.Element) -> str:
        """Register a bsdf; returns its id (one made up for a nested bsdf)."""
        kind = element.get("type")
        if kind not in _MATERIAL_TYPES:
            self.fail(element, f"not supported (supported bsdf types: {', '.join(_MATERIAL_TYPES)})")
        key = self.attr(element, "id", required=False) or f"bsdf-line-{self.lines.get(element)}"
        if kind == "itu-radio-material":
            props = self.properties(element, {"type": "string", "thickness": "float"})
            if "type" not in props:
                self.fail(element, "needs <string name='type'> (the ITU-R P.2040 material)")
            itu = self.attr(props["type"], "value")
            try:
                name = get_material(itu).name
            except ValueError as exc:
                self.fail(props["type"], str(exc))
        else:
            props = self.properties(element, {"relative_permittivity": "float", "conductivity": "float",
                                              "thickness": "float", "scattering_coefficient": "float",
                                              "xpd_coefficient": "float"})
            for unmodelled in ("scattering_coefficient", "xpd_coefficient"):
                if unmodelled in props and self.number(props[unmodelled]) != 0:
                    self.fail(props[unmodelled], f"{unmodelled} other than 0 is not read: rfsdf scatters with "
                                                 "its own lobe and one polarisation")
            eps = self.number(props["relative_permittivity"]) if "relative_permittivity" in props else 1.0
            sigma = self.number(props["conductivity"]) if "conductivity" in props else 0.0
            if eps < 1 or sigma < 0:
                self.fail(element, f"relative_permittivity {eps:g} must be >= 1 and conductivity {sigma:g} >= 0")
        thickness = self.number(props["thickness"]) if "thickness" in props else SIONNA_DEFAULT_THICKNESS_M
        if not thickness > 0:
            self.fail(props["thickness"], "thickness must be positive [m]")
        if kind != "itu-radio-material":
            name = self.custom_name(key, thickness, eps, sigma)
        self.materials[key] = (name, thickness)
        return key

    def custom_name(self, key: str, thickness: float, eps: float, sigma: float) -> str:
        """The name of a custom material: its bsdf id less Sionna's ``mat-`` and the
        ``-<thickness>mm`` rfsdf's writer appends (so rfsdf's own files read back their
        names), registered once; the id itself where that name is taken by another material."""
        name = re.sub(rf"-{re.escape(f'{thickness * 1e3:g}')}mm$", "", key.removeprefix("mat-"))
        known = {m["name"]: m for m in self.custom}
        if name in known and (known[name]["permittivity"], known[name]["conductivity_s_per_m"]) != (eps, sigma):
            name = key
        if name not in known or name == key:
            self.custom.append({"name": name, "permittivity": eps, "conductivity_s_per_m": sigma})
        return name

    def shape(self, element: ET.Element) -> None:
        kind = element.get("type")
        if kind not in (*_MESH_TYPES, *UNIT_SHAPES):
            self.fail(element, f"not supported (supported shape types: {', '.join((*_MESH_TYPES, *UNIT_SHAPES))})")
        name = (self.attr(element, "id", required=False) or self.attr(element, "name", required=False)
                or f"shape-{len(self.objects)}").removeprefix("mesh-")  # as Sionna RT names objects
        matrix, material = np.eye(4), None
        allowed = {"face_normals": "boolean", "flip_normals": "boolean"}
        allowed |= {"filename": "string"} if kind in _MESH_TYPES else {}
        allowed |= {"center": "point", "radius": "float"} if kind == "sphere" else {}
        allowed |= {"p0": "point", "p1": "point", "radius": "float"} if kind == "cylinder" else {}
        table = self.properties(element, allowed, structural=("transform", "ref", "bsdf"))
        for child in element:
            if child.tag == "transform":
                if child.get("name") != "to_world":
                    self.fail(child, "only the transform named 'to_world' is read")
                matrix = self.transform(child)
            elif child.tag == "ref":
                material = self.attr(child, "id")
                if material not in self.materials:
                    self.fail(child, f"no <bsdf id={material!r}> before this shape")
            elif child.tag == "bsdf":
                material = self.material(child)
        if material is None:
            self.fail(element, "has no material (a <ref id=...> to a bsdf, or a nested <bsdf>)")
        material_name, thickness = self.materials[material]
        shape = {"type": "mesh", "thickness_m": thickness}
        if kind in _MESH_TYPES:
            if "filename" not in table:
                self.fail(element, "needs <string name='filename'>")
            shape["path"] = self.mesh_path(table["filename"])
            try:
                surface = load_mesh(self.path.parent / shape["path"])
            except (RfsdfError, ValueError) as exc:
                self.fail(table["filename"], str(exc))
        else:
            matrix = matrix @ self.unit_frame(kind, table)
            shape["builtin"] = kind
            surface = unit_shape(kind)
        if not np.allclose(matrix, np.eye(4)):
            shape["to_world"] = matrix.tolist()
        surface.apply_transform(matrix)
        self.surfaces.append(surface)
        self.objects.append({"name": name, "material": material_name, "shape": shape})

    def mesh_path(self, element: ET.Element) -> str:
        """The mesh file's path relative to the XML's folder, checked: it stays inside that
        folder, is a regular file, and its header declares no more than its size holds."""
        text = self.attr(element, "value")
        folder = self.path.parent.resolve()
        target = (folder / text).resolve()
        if Path(text).is_absolute() or not target.is_relative_to(folder):
            self.fail(element, f"{text!r} leaves the scene file's folder {folder}")
        try:
            check_mesh_file(input_file(target))
        except (RfsdfError, ValueError) as exc:
            self.fail(element, str(exc))
        return target.relative_to(folder).as_posix()

    def unit_frame(self, kind: str, table: dict) -> np.ndarray:
        """The matrix that places Mitsuba's unit shape by its own properties (a sphere's centre
        and radius, a cylinder's end points and radius) before ``to_world``."""
        frame = np.eye(4)
        radius = self.number(table["radius"]) if "radius" in table else 1.0
        if "radius" in table and not radius > 0:
            self.fail(table["radius"], "radius must be positive")
        if kind == "sphere":
            centre = self.vector(table["center"]) if "center" in table else np.zeros(3)
            frame[:3, :3] *= radius
            frame[:3, 3] = centre
        elif kind == "cylinder":
            p0 = self.vector(table["p0"]) if "p0" in table else np.zeros(3)
            p1 = self.vector(table["p1"]) if "p1" in table else np.array([0.0, 0.0, 1.0])
            axis = p1 - p0
            length = float(np.linalg.norm(axis))
            if not length > 0:
                self.fail(table.get("p1", table.get("p0")), "p0 and p1 must differ")
            w = axis / length
            u = np.cross(w, [1.0, 0.0, 0.0] if abs(w[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            frame[:3, :3] = np.column_stack([u * radius, np.cross(w, u) * radius, axis])
            frame[:3, 3] = p0
        return frame

    def transform(self, element: ET.Element) -> np.ndarray:
        """A ``to_world`` transform: each child applied after the ones before it."""
        matrix = np.eye(4)
        for child in element:
            step = np.eye(4)
            if child.tag == "translate":
                step[:3, 3] = self.vector(child)
            elif child.tag == "scale":
                step[:3, :3] = np.diag(self.vector(child, missing=1.0))
            elif child.tag == "rotate":
                if child.get("value") is None and child.get("x") is None and child.get("y") is None \
                        and child.get("z") is None:
                    self.fail(child, "needs an axis (x, y, z or value)")
                axis = self.vector(child)
                angle = np.radians(self.number(child, "angle"))
                if not np.linalg.norm(axis) > 0:
                    self.fail(child, "the rotation axis must not be zero")
                step = trimesh.transformations.rotation_matrix(angle, axis)
            elif child.tag == "matrix":
                parts = self.attr(child, "value").replace(",", " ").split()
                try:
                    step = np.array([float(p) for p in parts]).reshape(4, 4)
                except ValueError:
                    self.fail(child, "value must be 16 numbers (a 4 x 4 matrix, row by row)")
                if not np.isfinite(step).all():
                    self.fail(child, "value must be finite")
            else:
                self.fail(child, "not supported inside <transform> (supported: translate, rotate, scale, matrix)")
            matrix = step @ matrix
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-12 or not np.allclose(matrix[3], (0, 0, 0, 1)):
            self.fail(element, "the transform must be an invertible affine map")
        return matrix

    def spec(self) -> dict:
        """The rfsdf scene table: bounds from the meshes' extent plus a margin."""
        lower = np.min([s.bounds[0] for s in self.surfaces], axis=0)
        upper = np.max([s.bounds[1] for s in self.surfaces], axis=0)
        extent = float((upper - lower).max())
        if extent > MAX_EXTENT_M:
            raise RfsdfError(f"{self.path}: the scene spans {extent:.0f} m, more than the {MAX_EXTENT_M:g} m rfsdf "
                             "reads: at mmWave that needs billions of surface facets; cut out the part you need")
        margin = _MARGIN_M + max(o["shape"]["thickness_m"] / 2 if not s.is_watertight else 0.0
                                 for o, s in zip(self.objects, self.surfaces))
        name = re.sub(r"[^A-Za-z0-9_.-]", "-", self.path.stem)[:64].lstrip("-._") or "scene"
        table = {"name": name, "bounds": {"lower_m": (lower - margin).tolist(), "upper_m": (upper + margin).tolist()},
                 "objects": self.objects}
        if self.custom:
            table["materials"] = self.custom
        return table


def read_mitsuba_scene(path) -> tuple[SceneSpec, list[trimesh.Trimesh]]:
    """The :class:`~rfsdf.scene_spec.SceneSpec` of a Mitsuba 3 / Sionna RT scene file (mesh
    paths relative to the file's folder, which is the scene's base folder) and each object's
    surface in the scene frame, read once (``Scene(spec, folder, surfaces)`` takes them);
    RfsdfError 'file: line N: <element>: reason' on anything outside the supported subset."""
    path = input_file(path)
    root, lines = _parse(path)
    reader = _Reader(path, root, lines)
    table = reader.read()
    return validate(SceneSpec, table, str(path)), reader.surfaces
