"""The box a triangle mesh is, when it is one: a closed cuboid or a flat rectangle.

Rooms drawn for a ray tracer are mostly boxes: Sionna RT's ``box`` room is a closed
8-vertex cuboid, a wall in ``floor_wall`` one quad. Recognised, such a mesh can be written
as an analytic box whose lengths a primitive fit moves (:func:`rfsdf.scene_model.analytic_spec`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = ["Cuboid", "cuboid_of"]

_RTOL = 1e-5  # of the mesh's size (lengths) or area: float32 vertices of a 10 m room are good to 1e-6


@dataclass(frozen=True)
class Cuboid:
    """A box: ``center_m`` (3,) [m], ``axes`` (3, 3) unit rows, right-handed, and
    ``half_extents_m`` (3,) [m] along them; a rectangle has 0 along its normal (the last axis)."""

    center_m: np.ndarray
    axes: np.ndarray
    half_extents_m: np.ndarray

    @property
    def flat(self) -> bool:
        return bool(self.half_extents_m[2] == 0)


def _directions(vectors: np.ndarray, most: int) -> list[np.ndarray] | None:
    """The distinct lines (up to sign, to ``_RTOL``) among unit ``vectors`` (N, 3), in order of
    first use; None as soon as there are more than ``most`` (a curved mesh has as many as
    faces, and comparing each with all of them was quadratic: 17 s for a 5120-face ball)."""
    lines = vectors[:1]
    while len(lines) <= most:
        new = (np.abs(vectors @ lines.T) <= 1 - _RTOL).all(1)
        if not new.any():
            return list(lines)
        lines = np.vstack([lines, vectors[new.argmax()]])
    return None


def _box_in(mesh: trimesh.Trimesh, axes: np.ndarray, flat: bool) -> Cuboid | None:
    """The box of ``mesh``'s vertices in the frame ``axes`` (rows), when every face lies in
    one of the box's faces and the faces cover them (a rectangle, ``flat``: its two sides
    are one, its normal the last axis); None otherwise."""
    local = np.asarray(mesh.vertices, dtype=float) @ axes.T
    low, high = local.min(0), local.max(0)
    extents = high - low
    size = float(extents.max())
    if flat:
        if extents[2] > _RTOL * size:
            return None
        extents[2] = 0.0
        area = extents[0] * extents[1]
    else:
        area = 2 * (extents[0] * extents[1] + extents[1] * extents[2] + extents[2] * extents[0])
    if abs(mesh.area - area) > _RTOL * area:
        return None
    corners = local[np.asarray(mesh.faces)]  # (F, 3, 3): each face's vertices in the box frame
    on_a_face = (np.abs(corners - low).max(1) <= _RTOL * size) | (np.abs(corners - high).max(1) <= _RTOL * size)
    if not on_a_face.any(1).all():
        return None
    centre = (low + high) / 2 @ axes
    right_handed = axes if np.linalg.det(axes) > 0 else axes * np.array([[1.0], [1.0], [-1.0]])
    return Cuboid(centre, right_handed, extents / 2)


def cuboid_of(mesh: trimesh.Trimesh) -> Cuboid | None:
    """The cuboid a closed mesh bounds, or the rectangle an open flat mesh covers; None for
    any other mesh. Faces may be split any way; all must lie in the box's faces and cover
    them exactly (area to 1e-5)."""
    keep = mesh.area_faces > 0
    if not keep.any():
        return None
    mesh = trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[keep], process=False)
    lines = _directions(np.asarray(mesh.face_normals, dtype=float), most=3)
    if lines is None:
        return None
    if mesh.is_watertight and len(lines) == 3:
        axes = np.stack(lines)
        if np.abs(axes @ axes.T - np.eye(3)).max() > _RTOL:
            return None
        return _box_in(mesh, axes, flat=False)
    if not mesh.is_watertight and len(lines) == 1:
        normal = lines[0]
        rim = np.asarray(mesh.vertices)[mesh.edges[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]]
        directions = rim[:, 1] - rim[:, 0]
        sides = _directions(directions / np.linalg.norm(directions, axis=1, keepdims=True), most=2)
        for u in sides or []:  # a rectangle's outline runs along its two sides
            box = _box_in(mesh, np.stack([u, np.cross(normal, u), normal]), flat=True)
            if box is not None:
                return box
    return None
