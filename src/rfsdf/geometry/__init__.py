"""Analytic signed distance functions, CSG, transforms, mesh SDFs, sphere tracing, occupancy.

Every SDF is a callable ``f(points) -> (N,)`` on (N, 3) torch tensors [m] that works
with autograd; f < 0 inside, f > 0 outside.
"""

from .base import SDF, as_points
from .csg import (
    Complement, Intersection, SmoothIntersection, SmoothUnion, Union,
    complement, difference, intersection, smooth_intersection, smooth_union, union,
)
from .differential import eikonal_residual, gradient, gradient_and_curvature, normals
from .grid import Grid, interpolated_sdf, trilinear
from .mesh_sdf import MeshSDF, load_mesh, load_watertight_mesh, thicken
from .occupancy import occupancy
from .primitives import Box, CappedCylinder, Capsule, Cylinder, HalfSpace, Sphere, Torus
from .tracing import TraceResult, sphere_trace
from .transforms import Rotate, Scale, Translate, rotation_from_vector, rotation_matrix
from .zero_set import SLIVER_AREA, chord_gaps, facet_geometry, project_to_zero_set, refine_creases, vertex_normals

__all__ = [
    "SDF", "as_points", "Grid", "interpolated_sdf", "trilinear",
    "Sphere", "Box", "HalfSpace", "Cylinder", "CappedCylinder", "Torus", "Capsule", "MeshSDF",
    "load_mesh", "load_watertight_mesh", "thicken",
    "Union", "Intersection", "Complement", "SmoothUnion", "SmoothIntersection",
    "union", "intersection", "complement", "difference", "smooth_union", "smooth_intersection",
    "Translate", "Rotate", "Scale", "rotation_matrix", "rotation_from_vector",
    "gradient", "gradient_and_curvature", "normals", "eikonal_residual", "occupancy", "sphere_trace", "TraceResult",
    "project_to_zero_set", "vertex_normals", "chord_gaps", "refine_creases", "facet_geometry", "SLIVER_AREA",
]
