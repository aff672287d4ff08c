"""Scenes: objects (an SDF and a material each) inside bounds; loading, presets, surface sampling.

A scene is loaded from a TOML file (see :mod:`rfsdf.scene_spec`) or a preset name
(``objects``, ``l-room``, ``sphere``; the files live in ``examples/scenes``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np
import tomli_w
import torch
import trimesh
from pydantic import TypeAdapter
from scipy.spatial.transform import Rotation

from . import geometry as geo
from .atomic import atomic_path
from .config import preset_names, read_toml, resolve_preset, validate
from .errors import RfsdfError
from .limits import input_file
from .geometry.cuboids import Cuboid, cuboid_of
from .geometry.differential import gradient
from .geometry.surface_sampling import stratified_surface_points
from .geometry.unit_shapes import unit_shape
from .materials import Material
from .mesh import extract_mesh, extract_mesh_near_surface
from .mitsuba.read import is_xml_file, read_mitsuba_scene
from .roughness import Roughness
from .scene_spec import CSGSpec, MeshShapeSpec, SceneSpec, ShapeSpec

__all__ = ["Scene", "SceneObject", "MeshReading", "SurfaceSamples", "load_scene", "scene_presets", "build_shape",
           "surface_mesh", "mesh_reading", "is_shell", "shell_mesh"]

_SHAPE = TypeAdapter(ShapeSpec)
_MESH_RESOLUTION = 192  # marching-cubes cells along an analytic object's longest edge
_COARSE_RESOLUTION = 64  # first pass that finds each object's extent inside the bounds
_CHECK_RESOLUTION = 24  # grid on which every object must come near the bounds at load time
_CELLS_ACROSS = 3  # marching-cubes cells across an object's thinnest part, at least
_MAX_SPLITS = 12  # rounds of splitting triangles in four (4096 x smaller edges at most)
_THIN_QUANTILE = 0.1  # of the chords through an object from its surface points: its thinnest part
_NEWTON_STEPS = 2  # projections p <- p - f grad f onto the exact zero set
_CHORD_SAMPLES, _BISECTIONS = 96, 30  # along a line through an object, and to where it leaves it
_CREASE_CELLS = 3  # a crease's triangles are refined to a third of the marching-cubes cell


def scene_presets() -> list[str]:
    """Names of the built-in scenes."""
    return preset_names("rfsdf.presets.scenes")


@dataclass(frozen=True)
class MeshReading:
    """How a mesh shape's surface became a solid: whether the surface is closed, its area
    [m^2] in the scene frame, and the reading (solid, sheet or shell)."""

    closed: bool
    area_m2: float
    reading: str
    box_shape: dict | None = None  # the analytic box it is (:func:`box_table`): its SDF; sampled from the mesh

    @property
    def box(self) -> bool:
        """Whether the mesh is a box, evaluated in closed form."""
        return self.box_shape is not None


@dataclass(frozen=True)
class SceneObject:
    """One object: its name, SDF (scene frame, metres), material, for mesh objects the mesh,
    the roughness of its surface (None: smooth at the wavelength) and, for a mesh shape, how
    its surface was read."""

    name: str
    sdf: geo.SDF
    material: Material
    mesh: trimesh.Trimesh | None = None
    roughness: Roughness | None = None
    reading: MeshReading | None = None


@dataclass(frozen=True)
class SurfaceSamples:
    """Points on the scene surface (N samples).

    points : (N, 3) float32 [m]; normals : (N, 3) outward unit; area_m2 : (N,) area each
    sample stands for [m^2]; object_index : (N,) int64 into ``Scene.objects``; corners_m :
    (N, 3, 3) float64 [m] when each sample is a flat triangle (``radar/facets.py``), its
    corners relative to the point, its centroid; None for points.
    """

    points: torch.Tensor
    normals: torch.Tensor
    area_m2: torch.Tensor
    object_index: torch.Tensor
    corners_m: torch.Tensor | None = None

    def _map(self, op) -> SurfaceSamples:
        return SurfaceSamples(*(None if t is None else op(t) for t in (
            self.points, self.normals, self.area_m2, self.object_index, self.corners_m)))

    def to(self, device) -> SurfaceSamples:
        """The same samples on ``device``."""
        return self._map(lambda t: t.to(device))

    def select(self, keep: torch.Tensor) -> SurfaceSamples:
        """The samples where ``keep`` (N,) bool is true."""
        return self._map(lambda t: t[keep.to(t.device)])


def _vec(v) -> torch.Tensor:
    return torch.as_tensor(v, dtype=torch.float64)


def surface_mesh(spec: MeshShapeSpec, base_dir: Path = Path(".")) -> trimesh.Trimesh:
    """The surface a mesh shape names, in the scene frame [m]: the file's (``path``
    relative to ``base_dir``) or the built-in unit shape, through ``to_world``, ``size_m``
    and ``center_m``; before any ``transform`` and before it is read as a solid."""
    if spec.builtin is not None:
        mesh = unit_shape(spec.builtin)
    else:
        path = Path(spec.path)
        mesh = geo.load_mesh(path if path.is_absolute() else base_dir / path)
    if spec.to_world is not None:
        matrix = np.asarray(spec.to_world, dtype=float)
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-12 or np.any(matrix[3] != (0, 0, 0, 1)):
            raise ValueError(f"{mesh.metadata['name']}: to_world must be an invertible affine matrix "
                             "(last row 0 0 0 1)")
        mesh.apply_transform(matrix)
    if spec.size_m is not None:
        mesh.apply_scale(spec.size_m / float(mesh.extents.max()))
    if spec.center_m is not None:
        mesh.apply_translation(np.asarray(spec.center_m) - mesh.bounds.mean(axis=0))
    return mesh


def transformed(surface: trimesh.Trimesh, spec: ShapeSpec) -> trimesh.Trimesh:
    """A copy of ``surface`` (a mesh shape's :func:`surface_mesh`, or any shape's own) moved
    by the shape's ``transform`` (scale, rotation, then translation), where it has one."""
    surface = surface.copy()
    if spec.transform is not None:
        tf = spec.transform
        matrix = np.eye(4)
        matrix[:3, :3] = geo.rotation_matrix(tf.rotate_axis, tf.rotate_rad).numpy() * tf.scale
        matrix[:3, 3] = tf.translate_m
        surface.apply_transform(matrix)
    return surface


def is_shell(table: dict) -> bool:
    """Whether a shape table is a shell: a box less a smaller box about the same centre,
    neither turned on its own (:func:`box_table`'s; the difference may carry a transform)."""
    children = table.get("children") if table.get("type") == "difference" else None
    if not children or len(children) != 2 or any(c.get("type") != "box" or c.get("transform") for c in children):
        return False
    outer, inner = children
    return (list(outer.get("center_m", (0.0, 0.0, 0.0))) == list(inner.get("center_m", (0.0, 0.0, 0.0)))
            and bool((np.asarray(outer["half_extents_m"], float) > np.asarray(inner["half_extents_m"], float)).all()))


def shell_mesh(shape: ShapeSpec) -> trimesh.Trimesh | None:
    """The exact triangles of a shell (:func:`is_shell`): both boxes, the inner one's faces
    turned in, through the shape's transform; None for any other shape. Marching cubes of a
    wall 1 cm thick around a 10 x 10 x 5 m room needs cells of 3 mm over its 400 m^2 (it
    filled the machine)."""
    if not is_shell(shape.model_dump(mode="json")):
        return None
    outer, inner = (trimesh.creation.box(extents=2 * np.asarray(box.half_extents_m),
                                         transform=trimesh.transformations.translation_matrix(box.center_m))
                    for box in shape.children)
    inner.invert()
    return transformed(trimesh.util.concatenate([outer, inner]), shape)


def mesh_reading(spec: MeshShapeSpec, surface: trimesh.Trimesh) -> str:
    """How a mesh shape is read: its ``reading``, else solid when the surface is closed and
    sheet when it is open."""
    return spec.reading or ("solid" if surface.is_watertight else "sheet")


def _mesh_shape(spec: MeshShapeSpec, base_dir: Path, surface: trimesh.Trimesh | None = None) -> geo.MeshSDF:
    """The solid a mesh shape describes, from its ``surface`` when already loaded."""
    surface = surface if surface is not None else surface_mesh(spec, base_dir)
    reading = mesh_reading(spec, surface)
    if reading == "solid":
        return geo.MeshSDF(surface)
    if spec.thickness_m is None:
        raise ValueError(f"{surface.metadata['name']}: an open mesh is read as a sheet, which needs thickness_m")
    below, above = (spec.thickness_m / 2, spec.thickness_m / 2) if reading == "sheet" else (0.0, spec.thickness_m)
    if reading == "shell" and not surface.is_watertight:
        raise ValueError(f"{surface.metadata['name']}: only a closed mesh can be read as a shell")
    if surface.is_watertight and surface.volume < 0:
        surface.invert()  # outward, so that a shell grows outside
    return geo.MeshSDF(geo.thicken(surface, below, above))


def box_table(shape: MeshShapeSpec, reading: str, surface: trimesh.Trimesh) -> dict | None:
    """The shape table of the analytic box with the SDF of mesh ``shape`` (its
    :func:`surface_mesh` ``surface``, left as it is) read as ``reading``, or None when it is
    no box (:func:`~rfsdf.geometry.cuboids.cuboid_of`: a closed cuboid read as a solid or a
    shell, a flat rectangle read as a sheet). A shell is the box ``thickness_m`` larger less
    the mesh's box; a box whose axes are not the scene's is a box about the origin turned
    and moved by its ``transform``."""
    surface = transformed(surface, shape)
    scale = shape.transform.scale if shape.transform is not None else 1.0
    box = cuboid_of(surface)
    if box is None or box.flat != (reading == "sheet"):
        return None
    thickness = None if shape.thickness_m is None else shape.thickness_m * scale
    if reading == "sheet":
        return _box_table(box, box.half_extents_m + np.array([0.0, 0.0, thickness / 2]))
    if reading == "solid":
        return _box_table(box, box.half_extents_m)
    outer, inner = (_box_table(box, box.half_extents_m + d, placed=False) for d in (thickness, 0.0))
    return _placed({"type": "difference", "children": [outer, inner]}, box)


def _box_table(box: Cuboid, half_extents_m: np.ndarray, placed: bool = True) -> dict:
    """A box shape table of ``box``'s frame and centre with ``half_extents_m`` (3,) [m]
    along its axes; ``placed=False``: about the origin, for :func:`_placed` to place."""
    aligned = np.abs(box.axes).max(1) > 1 - 1e-9  # every axis one of the scene's
    if aligned.all():
        order = np.abs(box.axes).argmax(1)
        world = np.empty(3)
        world[order] = half_extents_m
        return {"type": "box", "half_extents_m": world.tolist(), "center_m": box.center_m.tolist()}
    table = {"type": "box", "half_extents_m": np.asarray(half_extents_m).tolist()}
    return _placed(table, box) if placed else table


def _placed(table: dict, box: Cuboid) -> dict:
    """``table`` (a shape about the origin in ``box``'s frame, unless its axes are the
    scene's) turned into ``box``'s frame and moved to its centre by a transform."""
    if np.abs(box.axes).max(1).min() > 1 - 1e-9:
        return table  # its children were placed already
    rotation = Rotation.from_matrix(box.axes.T).as_rotvec()
    angle = float(np.linalg.norm(rotation))
    return {**table, "transform": {"translate_m": box.center_m.tolist(), "rotate_axis": (rotation / angle).tolist(),
                                   "rotate_rad": angle}}


def build_shape(spec, base_dir: Path = Path("."), values: dict | None = None,
                surface: trimesh.Trimesh | None = None) -> geo.SDF:
    """The SDF described by a shape table (recursively for CSG), with its transform applied.

    ``values`` maps (id of a spec node, field name) to a value used instead of the node's
    own, e.g. a fitted tensor (``rfsdf.recon.primitive``): the SDF is then differentiable in it.
    ``surface`` is a mesh shape's :func:`surface_mesh` when the caller has loaded it."""
    values = values or {}

    def get(node, field: str):
        return values.get((id(node), field), getattr(node, field))

    t = spec.type
    v = partial(get, spec)
    if t == "sphere":
        sdf = geo.Sphere(v("radius_m"), v("center_m"))
    elif t == "box":
        sdf = geo.Box(v("half_extents_m"), v("center_m"))
    elif t == "halfspace":
        sdf = geo.HalfSpace(v("normal"), v("offset_m"))
    elif t == "cylinder":
        sdf = geo.Cylinder(v("radius_m"), v("axis"), v("point_m"))
    elif t == "capped_cylinder":
        sdf = geo.CappedCylinder(v("radius_m"), v("height_m"), v("axis"), v("center_m"))
    elif t == "torus":
        sdf = geo.Torus(v("major_radius_m"), v("minor_radius_m"), v("axis"), v("center_m"))
    elif t == "capsule":
        sdf = geo.Capsule(v("start_m"), v("end_m"), v("radius_m"))
    elif t == "mesh":
        sdf = _mesh_shape(spec, base_dir, surface)
    elif isinstance(spec, CSGSpec):
        children = [build_shape(c, base_dir, values) for c in spec.children]
        combine = {
            "union": geo.union, "intersection": geo.intersection, "difference": geo.difference,
            "smooth_union": lambda *c: geo.smooth_union(*c, blend_m=spec.blend_m),
            "smooth_intersection": lambda *c: geo.smooth_intersection(*c, blend_m=spec.blend_m),
        }[t]
        sdf = combine(*children)
    else:  # pragma: no cover - the spec's discriminator admits nothing else
        raise AssertionError(t)
    tf = spec.transform
    if tf is not None:
        if tf.scale != 1.0:
            sdf = sdf.scale(tf.scale)
        if tf.rotate_rad != 0.0:
            sdf = sdf.rotate(tf.rotate_axis, tf.rotate_rad)
        translate = get(tf, "translate_m")
        if (id(tf), "translate_m") in values or any(translate):
            sdf = sdf.translate(translate)
    return sdf


class Scene:
    """Objects inside axis-aligned bounds; the scene SDF is the union of the objects'."""

    def __init__(self, spec: SceneSpec, base_dir: Path = Path("."), surfaces: list | None = None):
        """``surfaces``: per object, its mesh shape's :func:`surface_mesh` when the caller
        has loaded it (the XML reader has), else None; loaded here when not given."""
        self.spec = spec
        self.base_dir = base_dir
        self.name = spec.name
        self.lower_m = np.asarray(spec.bounds.lower_m, dtype=float)
        self.upper_m = np.asarray(spec.bounds.upper_m, dtype=float)
        self.objects: list[SceneObject] = []
        for index, obj in enumerate(spec.objects):
            shape, surface, reading = obj.shape, surfaces[index] if surfaces else None, None
            if isinstance(shape, MeshShapeSpec):
                surface = surface if surface is not None else surface_mesh(shape, base_dir)
                scale = shape.transform.scale if shape.transform is not None else 1.0
                reading = MeshReading(surface.is_watertight, surface.area * scale ** 2, mesh_reading(shape, surface))
            sdf = build_shape(shape, base_dir, surface=surface)
            mesh = sdf.mesh if isinstance(sdf, geo.MeshSDF) and shape.transform is None else None
            box = box_table(shape, reading.reading, surface) if reading is not None else None
            if box is not None:  # the same SDF in closed form: a mesh query per shadow-ray step was a room's cost
                sdf = build_shape(_SHAPE.validate_python(box))
                reading = dataclasses.replace(reading, box_shape=box)
            roughness = obj.roughness.build() if obj.roughness is not None else None
            self.objects.append(SceneObject(obj.name, sdf, spec.material(obj.material), mesh, roughness, reading))
        self._meshes: list[trimesh.Trimesh] | None = None
        # (sdf, bounding sphere or None) per object, the unbounded (cheap) ones first, for sdf()
        bounded = [(o.sdf, o.sdf.bounding_sphere()) for o in self.objects]
        self._cheap_first = sorted(bounded, key=lambda pair: pair[1] is not None)
        for obj in self.objects:  # every command sees the same scene, so check here, once
            if not self._near_points(obj, _CHECK_RESOLUTION).numel():
                raise RfsdfError(f"scene {self.name!r}: object {obj.name!r} lies outside the bounds")

    # Fields -------------------------------------------------------------------------
    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        """Scene SDF (N,) [m] at ``points`` (N, 3) [m]: min over objects, differentiable.

        An object with a bounding sphere (a mesh) is evaluated only at the points where that
        sphere is nearer than the other objects' surfaces: elsewhere it cannot be the least,
        and shadow rays traced through a mesh scene would otherwise query it at every step."""
        points = geo.as_points(points)
        values = None
        for sdf, sphere in self._cheap_first:
            if values is None or sphere is None:
                v = sdf(points)
                values = v if values is None else torch.minimum(values, v)
                continue
            centre, radius = sphere
            near = ((points - centre.to(points)).norm(dim=1) - radius < values).nonzero().squeeze(1)
            if len(near):
                values = values.index_put((near,), torch.minimum(values[near], sdf(points[near])))
        return values

    def object_index(self, points: torch.Tensor) -> torch.Tensor:
        """(N,) int64 index of the object nearest to (or containing) each point."""
        with torch.no_grad():
            return self._object_values(points).argmin(dim=0)

    def material_at(self, points: torch.Tensor) -> list[Material]:
        """The material of the nearest object at each point, a list of N Materials."""
        return [self.objects[i].material for i in self.object_index(points).tolist()]

    def permittivities(self, frequency_hz: float, device=None) -> torch.Tensor:
        """(N,) complex128: each object's relative permittivity at ``frequency_hz`` (inf for
        metal), in the objects' order (so ``[object_index(points)]`` gives each point's)."""
        return torch.tensor([complex(o.material.permittivity(frequency_hz)) for o in self.objects],
                            dtype=torch.complex128, device=device)

    def _object_values(self, points):
        points = geo.as_points(points)
        return torch.stack([o.sdf(points) for o in self.objects], dim=0)

    @property
    def extent_m(self) -> np.ndarray:
        """(3,) size of the bounds [m]."""
        return self.upper_m - self.lower_m

    # Meshes and sampling -------------------------------------------------------------
    def object_meshes(self) -> list[trimesh.Trimesh]:
        """One watertight mesh per object (the file's for mesh objects, a shell's own
        triangles, marching cubes otherwise)."""
        if self._meshes is None:
            self._meshes = [o.mesh if o.mesh is not None else self._mesh_of(o, spec.shape)
                            for o, spec in zip(self.objects, self.spec.objects)]
        return self._meshes

    def _coarse_grid(self, resolution: int) -> geo.Grid:
        return geo.Grid.from_voxel(self.lower_m, self.upper_m, float(self.extent_m.max()) / resolution)

    def _near_points(self, obj: SceneObject, resolution: int) -> torch.Tensor:
        """(M, 3) [m] points of a grid of the bounds (``resolution`` voxels along the longest
        edge) inside the object or within a voxel diagonal of its surface: none when the
        object lies outside the bounds, however small it is."""
        coarse = self._coarse_grid(resolution)
        pts = coarse.points(dtype=torch.float64)
        with torch.no_grad():
            return pts[obj.sdf(pts) < np.linalg.norm(coarse.voxel_m)]

    def _object_box(self, near: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners (3,) [m] of a box around an object's points ``near``
        (:meth:`_near_points` of the coarse grid), clipped to the bounds, two coarse voxels wider."""
        pad = 2 * self._coarse_grid(_COARSE_RESOLUTION).voxel_m
        lower = np.maximum(near.min(0).values.numpy() - pad, self.lower_m - pad)
        upper = np.minimum(near.max(0).values.numpy() + pad, self.upper_m + pad)
        return lower, upper

    def thinnest_m(self, obj: SceneObject) -> float:
        """The thickness [m] of ``obj`` at its thinnest (a box's smallest edge, a shell's
        wall; inf for an object outside the bounds)."""
        return _thickness(obj.sdf, self._near_points(obj, _COARSE_RESOLUTION))

    def _mesh_of(self, obj: SceneObject, shape: ShapeSpec) -> trimesh.Trimesh:
        """A shell's own triangles (:func:`shell_mesh`), else
        marching cubes of an analytic object: ``_MESH_RESOLUTION`` cells along its longest
        edge, or, where its thinnest part is thinner than ``_CELLS_ACROSS`` such cells (a
        plasterboard sheet, a window pane in a room), cells that fit that many times across
        it, evaluated near its surface only (:func:`~rfsdf.mesh.extract_mesh_near_surface`)."""
        exact = shell_mesh(shape)
        if exact is not None:
            return exact
        near = self._near_points(obj, _COARSE_RESOLUTION)
        lower, upper = self._object_box(near)
        sdf64 = lambda p: obj.sdf(p.double())  # noqa: E731 - evaluate in float64 for a clean surface
        longest = float((upper - lower).max())
        thickness = self.thinnest_m(obj)
        if thickness >= _CELLS_ACROSS * longest / _MESH_RESOLUTION:
            return extract_mesh(sdf64, lower, upper, _MESH_RESOLUTION)
        try:
            return extract_mesh_near_surface(sdf64, lower, upper, thickness / _CELLS_ACROSS)
        except (ValueError, RuntimeError) as exc:
            raise RfsdfError(f"scene {self.name!r}: object {obj.name!r}: {thickness * 1e3:.3g} mm thick at its "
                             f"thinnest and {longest:.3g} m long: cannot mesh it ({exc})") from None

    def ground_truth_mesh(self) -> trimesh.Trimesh:
        """All object meshes in one (objects are expected not to overlap)."""
        return trimesh.util.concatenate(self.object_meshes())

    def sample_surface(self, spacing_m: float, *, seed: int = 0, max_samples: int | None = None,
                       stratified: bool = False) -> SurfaceSamples:
        """Random area-uniform samples of every object's surface, about ``spacing_m`` [m] apart;
        ``stratified``: one in each stratum of equal area instead of independent
        (:func:`~rfsdf.geometry.surface_sampling.stratified_surface_points`).

        Analytic surfaces are sampled on their mesh and projected onto the exact zero set
        by Newton steps; normals come from grad f. Samples buried inside another object
        are dropped. With ``max_samples`` the spacing grows so that the count fits
        (:meth:`sample_spacing`).
        """
        spacing_m = self.sample_spacing(spacing_m, max_samples)
        meshes = self.object_meshes()
        rng = np.random.default_rng(seed)
        parts = []
        for index, (obj, mesh) in enumerate(zip(self.objects, meshes)):
            count = max(1, int(round(mesh.area / spacing_m**2)))
            sampler = stratified_surface_points if stratified else trimesh.sample.sample_surface
            pts, faces = sampler(mesh, count, seed=int(rng.integers(2**31)))
            p = torch.as_tensor(pts, dtype=torch.float64)
            if obj.mesh is None:
                for _ in range(_NEWTON_STEPS):
                    g = gradient(obj.sdf, p)
                    p = p - (obj.sdf(p) / (g * g).sum(1).clamp(min=1e-12))[:, None] * g
                n = torch.nn.functional.normalize(gradient(obj.sdf, p), dim=1)
            else:
                n = torch.as_tensor(mesh.face_normals[faces], dtype=torch.float64)
            parts.append((p, n, torch.full((count,), mesh.area / count, dtype=torch.float64), index))
        points = torch.cat([p for p, *_ in parts])
        keep = torch.ones(len(points), dtype=torch.bool)
        if len(self.objects) > 1:
            with torch.no_grad():
                keep = self.sdf(points) > -0.25 * spacing_m
        return SurfaceSamples(
            points=points[keep].float(),
            normals=torch.cat([n for _, n, *_ in parts])[keep].float(),
            area_m2=torch.cat([a for _, _, a, _ in parts])[keep].float(),
            object_index=torch.cat([torch.full((len(p),), i) for p, _, _, i in parts])[keep],
        )

    def surface_facets(self, max_edge_m: Callable[[np.ndarray], np.ndarray]) -> SurfaceSamples:
        """Every object's surface as flat triangles, each a sample at its centroid with its
        corners (``SurfaceSamples.corners_m``), face normal and area: the objects' meshes
        (:meth:`object_meshes`), their triangles split in four until each one's longest
        edge is within ``max_edge_m(centroids (F, 3)) -> (F,)`` [m] at its centroid.
        Triangles whose centroid is buried in another object are dropped."""
        parts = []
        for index, mesh in enumerate(self.object_meshes()):
            vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
            for _ in range(_MAX_SPLITS):
                triangles = vertices[faces]
                longest = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(1)
                too_big = np.flatnonzero(longest > max_edge_m(triangles.mean(1)))
                if not len(too_big):
                    break
                vertices, faces = trimesh.remesh.subdivide(vertices, faces, face_index=too_big)
            triangles = torch.as_tensor(vertices[faces], dtype=torch.float64)  # (F, 3, 3)
            centroids = triangles.mean(1)
            cross = torch.linalg.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
            area = 0.5 * cross.norm(dim=1)
            keep = area > 0
            parts.append((centroids[keep], cross[keep] / (2 * area[keep, None]), area[keep],
                          torch.full((int(keep.sum()),), index), triangles[keep] - centroids[keep, None]))
        samples = SurfaceSamples(*(torch.cat(t) for t in zip(*parts)))
        if len(self.objects) > 1:
            with torch.no_grad():
                edges = samples.corners_m.norm(dim=2).max(1).values
                samples = samples.select(self.sdf(samples.points) > -0.25 * edges)
        return SurfaceSamples(samples.points.float(), samples.normals.float(), samples.area_m2.float(),
                              samples.object_index, samples.corners_m)

    def zero_set_meshes(self, cell_m: float, *, seed: int = 0) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """Each object's surface as a mesh on its zero set, (vertices (N, 3) float64 [m], faces
        (F, 3) int64, unit normals (N, 3) at the vertices): analytic objects by marching cubes
        of cells ``cell_m`` [m] on a grid offset by a random fraction of a cell (``seed``:
        another seed, another mesh), vertices projected onto the exact zero set, creases
        refined (:mod:`~rfsdf.geometry.zero_set`); mesh objects as their own triangles split
        to edges within ``cell_m``, with zero normals (flat: no height to restore)."""
        rng = np.random.default_rng(seed)
        meshes = []
        for obj in self.objects:
            offset = rng.random(3) * cell_m
            if obj.mesh is not None:
                vertices, faces = trimesh.remesh.subdivide_to_size(obj.mesh.vertices, obj.mesh.faces, max_edge=cell_m,
                                                                   max_iter=_MAX_SPLITS)
                vertices = torch.as_tensor(vertices, dtype=torch.float64)
                meshes.append((vertices, torch.as_tensor(faces, dtype=torch.int64), torch.zeros_like(vertices)))
                continue
            lower, upper = self._object_box(self._near_points(obj, _COARSE_RESOLUTION))
            sdf64 = lambda p, sdf=obj.sdf: sdf(p.double())  # noqa: E731
            mesh = extract_mesh_near_surface(sdf64, lower - offset, upper, cell_m)
            vertices = geo.project_to_zero_set(sdf64, torch.as_tensor(mesh.vertices))
            vertices, faces = geo.refine_creases(sdf64, vertices, torch.as_tensor(mesh.faces, dtype=torch.int64),
                                                 min_edge_m=cell_m / _CREASE_CELLS)
            meshes.append((vertices, faces, geo.vertex_normals(sdf64, vertices)))
        return meshes

    def zero_set_facets(self, cell_m: float, *, seed: int = 0, meshes=None, move=None) -> SurfaceSamples:
        """Every object's surface as flat triangles that converge to it: the facets of
        :meth:`zero_set_meshes` (``meshes``, when the caller has them), each moved to the
        surface's mean height over it (:func:`~rfsdf.geometry.facet_geometry`). ``move``:
        (vertices (N, 3), normals (N, 3)) -> vertices, applied first (a perturbed surface).
        Triangles buried in another object (before the move) are dropped."""
        parts = []
        for index, (vertices, faces, normals) in enumerate(meshes or self.zero_set_meshes(cell_m, seed=seed)):
            moved = vertices if move is None else move(vertices, normals)
            centroids, face_normals, area, corners = geo.facet_geometry(moved, faces, normals)
            keep = area > geo.SLIVER_AREA * cell_m**2  # degenerate ones too: facet_geometry leaves them about 0
            if len(self.objects) > 1:
                with torch.no_grad():
                    keep &= self.sdf(vertices[faces].mean(1)) > -0.25 * cell_m
            parts.append((centroids[keep], face_normals[keep], area[keep], torch.full((int(keep.sum()),), index),
                          corners[keep]))
        points, normals, area, index, corners = (torch.cat(t) for t in zip(*parts))
        return SurfaceSamples(points.float(), normals.float(), area.float(), index, corners)

    def sample_spacing(self, spacing_m: float, max_samples: int | None = None) -> float:
        """The spacing [m] :meth:`sample_surface` uses: ``spacing_m``, or wider where the
        surface would otherwise take more than ``max_samples`` samples."""
        if not spacing_m > 0:
            raise ValueError(f"spacing_m must be positive, got {spacing_m}")
        if max_samples is None:
            return float(spacing_m)
        return max(float(spacing_m), float(np.sqrt(sum(m.area for m in self.object_meshes()) / max_samples)))

    def rough_points(self, samples: SurfaceSamples) -> torch.Tensor:
        """(N, 3) [m]: the samples moved along their normals by their object's height field
        (:class:`~rfsdf.roughness.Roughness`, keyed by the object's name, so every sampling
        sees the same surface); samples of smooth objects stay where they are."""
        points = samples.points.clone()
        for index, obj in enumerate(self.objects):
            if obj.roughness is None:
                continue
            mine = (samples.object_index == index).nonzero().squeeze(1)
            height = obj.roughness.height(samples.points[mine], obj.name).to(points)
            points[mine] += height[:, None] * samples.normals[mine]
        return points

    def around_radar(self, positions_m) -> Scene:
        """This scene as a radar at ``positions_m`` (V, 3) [m] sees it: a closed mesh with no
        ``reading`` of its own that holds one of the positions is a room around the radar,
        so it is read as a shell (walls ``thickness_m`` thick outside the mesh) instead of a
        solid the radar would stand in; the same scene when there is none. RfsdfError when
        a position lies inside any other object."""
        points = torch.as_tensor(np.asarray(positions_m, dtype=float).reshape(-1, 3))
        objects, changed = [], False
        for obj, spec in zip(self.objects, self.spec.objects):
            with torch.no_grad():
                inside = (obj.sdf(points) < 0).nonzero().flatten()
            shape = spec.shape
            if len(inside):
                room = obj.reading is not None and shape.reading is None and shape.transform is None \
                    and shape.thickness_m is not None and obj.reading.reading == "solid"
                if not room:
                    where = np.round(points[int(inside[0])].numpy(), 3).tolist()
                    raise RfsdfError(f"scene {self.name!r}: the radar's view {int(inside[0])} at {where} m lies inside "
                                     f"object {obj.name!r}; move the radar (its views' target_m and distance_m)")
                spec = spec.model_copy(update={"shape": shape.model_copy(update={"reading": "shell"})})
                changed = True
            objects.append(spec)
        return Scene(self.spec.model_copy(update={"objects": objects}), self.base_dir) if changed else self

    def write_toml(self, path) -> None:
        """This scene's spec as a scene TOML file at ``path``, atomically (:func:`load_scene` reads it)."""
        with atomic_path(path) as tmp:
            tmp.write_text(tomli_w.dumps(self.spec.model_dump(mode="json", exclude_none=True)))

    def summary(self) -> str:
        """A few lines describing the scene for people."""
        lines = [f"scene {self.name!r}: bounds {self.lower_m.tolist()} .. {self.upper_m.tolist()} m, "
                 f"{len(self.objects)} object(s)"]
        for obj, spec in zip(self.objects, self.spec.objects):
            eps = obj.material.permittivity(79e9) if obj.material.in_band(79e9) else None
            eps_text = "PEC" if obj.material.pec else (f"eps(79 GHz)={eps.real:.2f}{eps.imag:+.2f}j" if eps else "")
            rough = obj.roughness
            rough_text = (f"  rough: {rough.rms_m * 1e3:g} mm rms, {rough.correlation_m * 1e3:g} mm correlation"
                          if rough else "")
            lines.append(f"  {obj.name:<16} {spec.shape.type:<16} {obj.material.name:<13} {eps_text}"
                         f"{'' if obj.sdf.exact else '  (distance is a bound)'}{rough_text}"
                         f"{_reading_text(obj, spec.shape)}")
        return "\n".join(lines)



def _reading_text(obj: SceneObject, shape) -> str:
    """How a mesh object's surface was read, with its area: '' for other objects."""
    if obj.reading is None:
        return ""
    reading = obj.reading.reading
    thick = f" {shape.thickness_m * 1e3:g} mm" if reading != "solid" else ""
    radar = " (a shell when a radar is inside)" if reading == "solid" and shape.reading is None \
        and shape.thickness_m is not None else ""
    closed = "closed" if obj.reading.closed else "open"
    box = ", a box" if obj.reading.box else ""
    return f"  {closed} surface {obj.reading.area_m2:.4g} m^2 read as a {reading}{thick}{radar}{box}"


def _thickness(sdf, near: torch.Tensor) -> float:
    """The thickness [m] of a solid at its thinnest: from points ``near`` (M, 3) [m] its surface,
    projected onto it by Newton steps, the chord to where the line along -grad f (taken where
    the point was) first leaves the solid (a slab's chord is its thickness, a
    ball's its diameter), its ``_THIN_QUANTILE`` quantile over the points (inf without
    points). The deepest -f along the line instead reads a face's depth near its rim (a side
    face meets the line there) and called a 3 mm pane 0.35 mm thick, a 10 cm partition 4 cm."""
    if not len(near):
        return float("inf")
    # jittered off the grid they came from: a face in a grid plane (common in designed
    # scenes) would send the lines from its rim along itself
    extent = float((near.max(0).values - near.min(0).values).max())
    jitter = torch.rand(near.shape, generator=torch.Generator().manual_seed(0), dtype=torch.float64) - 0.5
    p = near.double() + 0.5 * extent / _COARSE_RESOLUTION * jitter
    inward = -torch.nn.functional.normalize(gradient(sdf, p), dim=1)
    for _ in range(_NEWTON_STEPS):
        g = gradient(sdf, p)
        p = p - (sdf(p) / (g * g).sum(1).clamp(min=1e-12))[:, None] * g
    # the line sampled from just inside to twice the points' extent, the first sample outside
    # bracketing the exit, which bisection finds: a line grazing a face (inside by t sin of a
    # small angle) gains too little -f for steps of -f to reach the far side
    reach = max(extent, 1e-3)
    t = torch.logspace(np.log10(1e-6 * reach), np.log10(2 * reach), _CHORD_SAMPLES, dtype=torch.float64)[:, None]
    with torch.no_grad():
        inside = torch.stack([sdf(p + ti * inward) < 0 for ti in t])  # (S, M)
        entered = inside[0]  # a point Newton left off the surface sees no inside
        first_out = (~inside).double().argmax(0).clamp(min=1)  # the first sample outside (none: the last)
        low, high = t[first_out - 1, 0], t[first_out, 0]
        for _ in range(_BISECTIONS):
            middle = 0.5 * (low + high)
            out = sdf(p + middle[:, None] * inward) >= 0
            low, high = torch.where(out, low, middle), torch.where(out, middle, high)
    return float(torch.quantile(high[entered], _THIN_QUANTILE)) if bool(entered.any()) else float("inf")


def load_scene(name_or_path) -> Scene:
    """A scene from a preset name, a TOML file or a Mitsuba 3 / Sionna RT XML file (told apart
    by their content, :mod:`rfsdf.mitsuba`); RfsdfError 'file: field: reason' on bad input."""
    path = resolve_preset(name_or_path, "rfsdf.presets.scenes", "scene")
    surfaces = None
    if is_xml_file(input_file(path)):
        spec, surfaces = read_mitsuba_scene(path)
    else:
        spec = validate(SceneSpec, read_toml(path), str(path))
    try:
        return Scene(spec, base_dir=path.parent, surfaces=surfaces)
    except ValueError as exc:
        raise RfsdfError(f"{path}: {exc}") from None
