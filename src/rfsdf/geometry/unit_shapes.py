"""Mitsuba 3's built-in shapes as triangle meshes in their own frame, before ``to_world``.

rectangle: the square [-1, 1]^2 at z = 0, normal +z (open); cube: [-1, 1]^3 (closed);
disk: the unit disk at z = 0, normal +z (open); sphere: the unit sphere (closed);
cylinder: the open tube of radius 1 from z = 0 to z = 1 (Mitsuba's has no caps).
Curved ones are polygons fine enough that their area is within 0.1 % of the exact one.
"""

from __future__ import annotations

import numpy as np
import trimesh

__all__ = ["UNIT_SHAPES", "unit_shape"]

_SEGMENTS = 128  # around a disk or a tube: area within 0.04 % of the circle's
_SPHERE_SUBDIVISIONS = 5  # icosphere levels: area within 0.1 % of the sphere's


def _rectangle() -> trimesh.Trimesh:
    return trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False)


def _disk() -> trimesh.Trimesh:
    angle = np.linspace(0, 2 * np.pi, _SEGMENTS, endpoint=False)
    rim = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(_SEGMENTS)])
    ring = np.arange(_SEGMENTS)
    faces = np.column_stack([np.zeros(_SEGMENTS, dtype=int), 1 + ring, 1 + (ring + 1) % _SEGMENTS])
    return trimesh.Trimesh(np.vstack([[0, 0, 0], rim]), faces, process=False)


def _cylinder() -> trimesh.Trimesh:
    angle = np.linspace(0, 2 * np.pi, _SEGMENTS, endpoint=False)
    circle = np.column_stack([np.cos(angle), np.sin(angle)])
    vertices = np.vstack([np.column_stack([circle, np.zeros(_SEGMENTS)]), np.column_stack([circle, np.ones(_SEGMENTS)])])
    i = np.arange(_SEGMENTS)
    j = (i + 1) % _SEGMENTS
    faces = np.vstack([np.column_stack([i, j, j + _SEGMENTS]), np.column_stack([i, j + _SEGMENTS, i + _SEGMENTS])])
    return trimesh.Trimesh(vertices, faces, process=False)


UNIT_SHAPES = {
    "rectangle": _rectangle,
    "cube": lambda: trimesh.creation.box(extents=(2.0, 2.0, 2.0)),
    "disk": _disk,
    "sphere": lambda: trimesh.creation.icosphere(subdivisions=_SPHERE_SUBDIVISIONS, radius=1.0),
    "cylinder": _cylinder,
}


def unit_shape(name: str) -> trimesh.Trimesh:
    """A fresh mesh of the built-in shape ``name`` (a key of ``UNIT_SHAPES``)."""
    mesh = UNIT_SHAPES[name]()
    mesh.metadata["name"] = f"built-in {name}"
    return mesh
