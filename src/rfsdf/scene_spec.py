"""The TOML scene format, as pydantic models: what a scene file may say and how it is checked.

A scene file has a ``name``, ``[bounds]`` (lower_m, upper_m), optional custom
``[[materials]]`` and a list of ``[[objects]]``, each with a ``name``, a ``material``,
a ``shape`` table whose ``type`` picks a primitive, a mesh file or a CSG node, and
optionally a ``roughness`` table (rms_m, correlation_m, seed; smooth without it).
Every shape may carry a ``transform`` (translate_m, rotate_axis, rotate_rad, scale).
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, PositiveFloat, field_validator, model_validator

from .config import Name, StrictModel
from .materials import Material, get_material
from .roughness import Roughness

__all__ = ["SceneSpec", "ObjectSpec", "ShapeSpec", "MaterialSpec", "BoundsSpec", "TransformSpec",
           "RoughnessSpec"]

Vec3 = tuple[float, float, float]
PositiveVec3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]


class TransformSpec(StrictModel):
    """Applied in the order scale, rotate, translate (all about the origin)."""

    translate_m: Vec3 = (0.0, 0.0, 0.0)
    rotate_axis: Vec3 = (0.0, 0.0, 1.0)  # the axis to rotate about (normalised when read)
    rotate_rad: float = 0.0  # the angle about rotate_axis, right-handed [rad]
    scale: PositiveFloat = 1.0  # uniform scale, about the origin


class _Shape(StrictModel):
    transform: TransformSpec | None = None  # applied after the shape's own placement


class SphereSpec(_Shape):
    type: Literal["sphere"]
    radius_m: PositiveFloat
    center_m: Vec3 = (0.0, 0.0, 0.0)


class BoxSpec(_Shape):
    type: Literal["box"]
    half_extents_m: PositiveVec3
    center_m: Vec3 = (0.0, 0.0, 0.0)


class HalfSpaceSpec(_Shape):
    type: Literal["halfspace"]
    normal: Vec3  # outward normal n (normalised when read): inside where n.p <= offset_m
    offset_m: float = 0.0


class CylinderSpec(_Shape):
    type: Literal["cylinder"]
    radius_m: PositiveFloat  # an infinite cylinder about the line through point_m along axis
    axis: Vec3 = (0.0, 0.0, 1.0)
    point_m: Vec3 = (0.0, 0.0, 0.0)


class CappedCylinderSpec(_Shape):
    type: Literal["capped_cylinder"]
    radius_m: PositiveFloat
    height_m: PositiveFloat  # the full height along axis, centred on center_m
    axis: Vec3 = (0.0, 0.0, 1.0)
    center_m: Vec3 = (0.0, 0.0, 0.0)


class TorusSpec(_Shape):
    type: Literal["torus"]
    major_radius_m: PositiveFloat  # radius of the circle the tube follows, normal to axis
    minor_radius_m: PositiveFloat  # radius of the tube, below major_radius_m
    axis: Vec3 = (0.0, 0.0, 1.0)
    center_m: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _radii(self):
        if self.minor_radius_m >= self.major_radius_m:
            raise ValueError("minor_radius_m must be smaller than major_radius_m")
        return self


class CapsuleSpec(_Shape):
    type: Literal["capsule"]
    start_m: Vec3
    end_m: Vec3
    radius_m: PositiveFloat  # all points within radius_m of the segment start_m .. end_m


Matrix4 = tuple[tuple[float, float, float, float], tuple[float, float, float, float],
                tuple[float, float, float, float], tuple[float, float, float, float]]
Reading = Literal["solid", "sheet", "shell"]


class MeshShapeSpec(_Shape):
    """A triangle mesh: a file (``path``, relative to the scene file) or one of Mitsuba 3's
    unit shapes (``builtin``: rectangle, cube, disk, sphere, cylinder), mapped by
    ``to_world`` (a 4 x 4 matrix, rows, metres), then scaled so that its largest
    bounding-box edge is ``size_m`` and moved so that its bounding-box centre is ``center_m``.

    ``reading`` says which solid the surface stands for: ``solid`` (a closed mesh, its
    inside), ``sheet`` (a slab ``thickness_m`` thick centred on the surface: a ray tracer's
    wall, seen from both sides) or ``shell`` (a closed mesh with the radar inside: walls
    ``thickness_m`` thick outside it, the mesh their inner faces). Without it a closed
    mesh is a solid and an open one a sheet."""

    type: Literal["mesh"]
    path: str | None = None  # a PLY, OBJ or STL file, relative to the scene file
    builtin: Literal["rectangle", "cube", "disk", "sphere", "cylinder"] | None = None
    to_world: Matrix4 | None = None
    size_m: PositiveFloat | None = None
    center_m: Vec3 | None = None
    reading: Reading | None = None  # solid, sheet or shell (see the docstring above)
    thickness_m: PositiveFloat | None = None

    @model_validator(mode="after")
    def _one_source(self):
        if (self.path is None) == (self.builtin is None):
            raise ValueError("a mesh shape needs exactly one of path and builtin")
        if self.reading in ("sheet", "shell") and self.thickness_m is None:
            raise ValueError(f"a mesh read as a {self.reading} needs thickness_m")
        return self


class CSGSpec(_Shape):
    type: Literal["union", "intersection", "difference", "smooth_union", "smooth_intersection"]
    # shapes of any type, CSG included; difference: the first less the rest
    children: list[ShapeSpec] = Field(min_length=2)
    blend_m: PositiveFloat | None = None  # the smooth blends' radius [m]

    @model_validator(mode="after")
    def _blend(self):
        if self.type.startswith("smooth") and self.blend_m is None:
            raise ValueError(f"{self.type} needs blend_m")
        return self


ShapeSpec = Annotated[
    Union[SphereSpec, BoxSpec, HalfSpaceSpec, CylinderSpec, CappedCylinderSpec, TorusSpec,
          CapsuleSpec, MeshShapeSpec, CSGSpec],
    Field(discriminator="type"),
]
CSGSpec.model_rebuild()


class MaterialSpec(StrictModel):
    """A custom material: constant relative permittivity and conductivity [S/m]."""

    name: str
    permittivity: float = Field(ge=1.0)
    conductivity_s_per_m: float = Field(default=0.0, ge=0.0)

    def build(self) -> Material:
        return Material.from_permittivity(self.name, self.permittivity, self.conductivity_s_per_m)


class BoundsSpec(StrictModel):
    lower_m: Vec3  # the box every object lies in and the images cover [m]
    upper_m: Vec3

    @model_validator(mode="after")
    def _ordered(self):
        if not all(lo < hi for lo, hi in zip(self.lower_m, self.upper_m)):
            raise ValueError(f"lower_m {list(self.lower_m)} must be below upper_m {list(self.upper_m)} on every axis")
        return self


class RoughnessSpec(StrictModel):
    """A Gaussian random height field on the object's surface (:class:`rfsdf.roughness.Roughness`)."""

    rms_m: float = Field(ge=0.0)  # rms height of the surface about its smooth shape [m]
    correlation_m: PositiveFloat  # correlation length of the heights [m]
    seed: int = 0  # the height field's seed (a fixed surface, not noise)

    def build(self) -> Roughness:
        return Roughness(self.rms_m, self.correlation_m, self.seed)


class ObjectSpec(StrictModel):
    name: str  # unique in the scene
    material: str  # a catalogue name (rfsdf.materials) or a [[materials]] name
    shape: ShapeSpec
    roughness: RoughnessSpec | None = None  # a random height field on the surface; none: smooth


class SceneSpec(StrictModel):
    name: Name  # a plain name (it names files)
    bounds: BoundsSpec
    materials: list[MaterialSpec] = []  # custom materials, beyond the ITU-R P.2040-3 catalogue
    objects: list[ObjectSpec] = Field(min_length=1)
    # the object a radar engineer would calibrate the gain with (its material is known): the
    # demo renders it as its material and reads the other materials absolutely
    calibration_reference: str | None = None

    @field_validator("objects")
    @classmethod
    def _unique_names(cls, objects):
        names = [o.name for o in objects]
        duplicated = sorted({n for n in names if names.count(n) > 1})
        if duplicated:
            raise ValueError(f"object names must be unique, repeated: {', '.join(duplicated)}")
        return objects

    @field_validator("calibration_reference")
    @classmethod
    def _reference_is_an_object(cls, name, info):
        names = [o.name for o in info.data.get("objects", [])]
        if name is not None and names and name not in names:
            raise ValueError(f"no object {name!r} (the objects are {', '.join(names)})")
        return name

    @model_validator(mode="after")
    def _known_materials(self):
        custom = {m.name for m in self.materials}
        for obj in self.objects:
            if obj.material not in custom:
                try:
                    get_material(obj.material)
                except ValueError as exc:
                    raise ValueError(f"object {obj.name!r}: {exc} (or define it under [[materials]])") from None
        return self

    def material(self, name: str) -> Material:
        """The Material called ``name``: a custom one from this file, else the catalogue's."""
        for spec in self.materials:
            if spec.name == name:
                return spec.build()
        return get_material(name)
