"""Seeded random scenes for datasets: the preset scenes' kinds of object (balls, blocks,
jars, rings, capsules of 1-5 cm) in the catalogue's materials, placed without overlap
inside the bounds.

Each object gets a bounding sphere in closed form (for a box, its half-diagonal; for a
torus, major + minor radius; ...), and a centre drawn uniformly where that sphere lies
at least ``gap_m`` inside the bounds and from every sphere placed before it (rejection
sampling). The result is a plain scene dict (the TOML layout) that passes the same
validation as a file.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import RfsdfError

__all__ = ["SHAPE_KINDS", "MATERIALS", "random_scene_spec"]

SHAPE_KINDS = ("sphere", "box", "capped_cylinder", "torus", "capsule")
MATERIALS = ("metal", "wood", "glass", "concrete", "plasterboard")  # in band at 1-100 GHz (ITU-R P.2040)
_SIZE_M = (0.012, 0.04)  # range of the main dimension (radius or half-extent) [m]


def _unit(rng: np.random.Generator) -> list[float]:
    v = rng.normal(size=3)
    return (v / np.linalg.norm(v)).round(4).tolist()


def _shape(kind: str, rng: np.random.Generator) -> tuple[dict, float]:
    """(shape table centred at the origin, bounding radius [m])."""
    size = lambda scale=1.0: round(float(rng.uniform(*_SIZE_M)) * scale, 4)  # noqa: E731
    if kind == "sphere":
        r = size()
        return {"type": "sphere", "radius_m": r}, r
    if kind == "box":
        half = [size(0.8) for _ in range(3)]
        return {"type": "box", "half_extents_m": half,
                "transform": {"rotate_axis": _unit(rng), "rotate_rad": round(float(rng.uniform(0, math.pi)), 4)}}, \
            float(np.linalg.norm(half))
    if kind == "capped_cylinder":
        r, h = size(0.7), size(2.0)
        return {"type": "capped_cylinder", "radius_m": r, "height_m": h, "axis": _unit(rng)}, math.hypot(r, h / 2)
    if kind == "torus":
        major = size()
        minor = round(major * float(rng.uniform(0.25, 0.5)), 4)
        return {"type": "torus", "major_radius_m": major, "minor_radius_m": minor, "axis": _unit(rng)}, major + minor
    r, half_length = size(0.5), size()
    axis = np.array(_unit(rng))
    return {"type": "capsule", "start_m": (-half_length * axis).round(4).tolist(), "end_m": (half_length * axis).round(4).tolist(),
            "radius_m": r}, half_length + r


def _translated(shape: dict, centre: np.ndarray) -> dict:
    """The shape moved by ``centre`` (its transform's translation; rotation stays about the origin first)."""
    transform = dict(shape.get("transform", {}))
    transform["translate_m"] = centre.round(4).tolist()
    return {**shape, "transform": transform}


def random_scene_spec(seed: int, *, objects: tuple[int, int] = (2, 5), lower_m=(-0.15, -0.15, -0.15),
                      upper_m=(0.15, 0.15, 0.15), gap_m: float = 0.01, attempts: int = 2000) -> dict:
    """A random scene (TOML layout) of objects[0] to objects[1] objects, reproducible by ``seed``."""
    rng = np.random.default_rng(seed)
    lower, upper = np.asarray(lower_m, float), np.asarray(upper_m, float)
    placed: list[tuple[np.ndarray, float]] = []
    table = []
    for index in range(int(rng.integers(objects[0], objects[1] + 1))):
        kind = SHAPE_KINDS[int(rng.integers(len(SHAPE_KINDS)))]
        shape, radius = _shape(kind, rng)
        for _ in range(attempts):
            centre = rng.uniform(lower + radius + gap_m, upper - radius - gap_m)
            if all(np.linalg.norm(centre - c) >= radius + r + gap_m for c, r in placed):
                break
        else:
            raise RfsdfError(f"random scene {seed}: no room for object {index} ({kind}, {radius * 1e3:.0f} mm) "
                             f"after {attempts} tries; use larger bounds or fewer objects")
        placed.append((centre, radius))
        table.append({"name": f"{kind}_{index}", "material": MATERIALS[int(rng.integers(len(MATERIALS)))],
                      "shape": _translated(shape, centre)})
    return {"name": f"random-{seed}", "bounds": {"lower_m": lower.tolist(), "upper_m": upper.tolist()}, "objects": table}
