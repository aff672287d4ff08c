"""Write an rfsdf scene as a Sionna RT scene: ``scene.xml`` (Mitsuba 3) and ``meshes/*.ply``.

Each object's surface is its mesh (:meth:`rfsdf.scene.Scene.object_meshes`): a mesh
object's own triangles, or marching cubes of an analytic SDF (192 cells along the object's
longest edge, or a third of its thickness where it is thinner than 3 such cells). A mesh
read as a sheet or a shell is written as its surface, not as the walls rfsdf makes of it:
Sionna models a wall as one surface with its material's thickness, and would take the
walls' two faces for two walls (twice the transmission loss). Catalogue
materials become ``itu-radio-material`` (the names are ITU-R P.2040's, as Sionna's), custom
ones ``radio-material`` with their constant permittivity and conductivity. The thickness
Sionna gives a material (its slab model) is the object's: a sheet's or shell's own, else
its thickness at its thinnest (a hollow box's wall, a torus's tube; at most the smallest
edge of its bounding box; to 0.1 mm). Ids follow Sionna's scenes
(``mesh-<object>``, ``mat-<material>-<thickness>mm``, one bsdf per material and thickness),
since Sionna names objects and materials by them less the prefix and wants every name
distinct.
"""

from __future__ import annotations

import os
import re
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import trimesh

from ..errors import RfsdfError
from ..materials import MATERIALS
from ..scene import Scene, surface_mesh, transformed
from ..scene_spec import MeshShapeSpec

__all__ = ["export_scene", "write_ply"]

SCENE_FILE = "scene.xml"
MESH_FOLDER = "meshes"


def write_ply(mesh: trimesh.Trimesh, path: Path) -> None:
    """A binary little-endian PLY as Sionna's own scenes have them: float32 x, y, z per
    vertex and a uchar-counted int list per face."""
    vertices = np.asarray(mesh.vertices, dtype="<f4")
    faces = np.asarray(mesh.faces, dtype="<i4")
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    records = np.zeros(len(faces), dtype=[("count", "u1"), ("index", "<i4", (3,))])
    records["count"], records["index"] = 3, faces
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(vertices.tobytes())
        fh.write(records.tobytes())


def _identifier(name: str, taken: set[str]) -> str:
    """A file stem and (after 'mesh-') XML id from an object name: letters, digits and '_',
    unique. Sionna RT names an object by its id less 'mesh-' and a material by its id less
    'mat-', and wants every name distinct: material names carry a '-', object names never."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_") or "object"
    ident, n = base, 1
    while ident in taken:
        n += 1
        ident = f"{base}_{n}"
    taken.add(ident)
    return ident


def _property(parent: ET.Element, tag: str, name: str, value) -> None:
    ET.SubElement(parent, tag, name=name, value=str(value))


def _thickness(scene: Scene, obj, spec_shape, mesh: trimesh.Trimesh) -> float:
    if isinstance(spec_shape, MeshShapeSpec) and spec_shape.thickness_m is not None:
        return float(spec_shape.thickness_m) * (spec_shape.transform.scale if spec_shape.transform is not None else 1.0)
    # to 0.1 mm: marching cubes leaves digits that mean nothing
    return round(min(float(mesh.extents.min()), scene.thinnest_m(obj)), 4)


def export_scene(scene: Scene, folder: Path) -> Path:
    """Write ``folder``/scene.xml and ``folder``/meshes/<object>.ply; returns the XML's path.

    The meshes are written first and scene.xml last, each by rename, so a crash never
    leaves a scene file naming a half-written mesh."""
    folder = Path(folder)
    meshes = scene.object_meshes()
    root = ET.Element("scene", version="2.1.0")
    taken: set[str] = set()
    files: list[tuple[str, trimesh.Trimesh]] = []
    materials: dict[tuple[str, float], str] = {}  # (material, thickness) -> bsdf id, shared as in Sionna's scenes
    for obj, spec, mesh in zip(scene.objects, scene.spec.objects, meshes):
        if obj.reading is not None and obj.reading.reading in ("sheet", "shell"):
            mesh = transformed(surface_mesh(spec.shape, scene.base_dir), spec.shape)
        ident = _identifier(obj.name, taken)
        material, thickness = obj.material, _thickness(scene, obj, spec.shape, mesh)
        bsdf_id = materials.get((material.name, thickness))
        if bsdf_id is None:
            bsdf_id = f"mat-{re.sub(r'[^A-Za-z0-9_]', '_', material.name)}-{thickness * 1e3:g}mm"
            materials[material.name, thickness] = bsdf_id
            if material.name in MATERIALS:
                bsdf = ET.SubElement(root, "bsdf", type="itu-radio-material", id=bsdf_id)
                _property(bsdf, "string", "type", material.name)
            else:
                bsdf = ET.SubElement(root, "bsdf", type="radio-material", id=bsdf_id)
                eps = material.bands[0]
                _property(bsdf, "float", "relative_permittivity", repr(eps.a))
                _property(bsdf, "float", "conductivity", repr(eps.c))
            _property(bsdf, "float", "thickness", repr(thickness))
        shape = ET.SubElement(root, "shape", type="ply", id=f"mesh-{ident}")
        _property(shape, "string", "filename", f"{MESH_FOLDER}/{ident}.ply")
        _property(shape, "boolean", "face_normals", "true")
        ET.SubElement(shape, "ref", id=bsdf_id, name="bsdf")
        files.append((ident, mesh))
    ET.indent(root)
    try:
        (folder / MESH_FOLDER).mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=".export-", dir=folder) as tmp:
            for ident, mesh in files:
                write_ply(mesh, Path(tmp) / f"{ident}.ply")
                os.replace(Path(tmp) / f"{ident}.ply", folder / MESH_FOLDER / f"{ident}.ply")
            ET.ElementTree(root).write(Path(tmp) / SCENE_FILE, encoding="utf-8", xml_declaration=True)
            os.replace(Path(tmp) / SCENE_FILE, folder / SCENE_FILE)
    except OSError as exc:
        raise RfsdfError(f"{folder}: cannot write the scene here ({exc.strerror or exc})") from None
    return folder / SCENE_FILE
