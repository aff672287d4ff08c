"""Lines of sight through dielectric objects: what each crossing does to a return.

A ray from a surface sample to the array's phase centre that meets another object goes on
through it when the object is a dielectric: each crossing is a slab (:mod:`rfsdf.slab`)
whose thickness is the chord the ray cuts, d = chord x cos(theta_entry) (exact for a slab of
parallel faces, the first-order reading of a solid's), whose permittivity is the object's
material's, and which multiplies the one-way field by its T and stands the sample farther by
its excess electrical path (:func:`~rfsdf.slab.excess_path`). A metal object stops the ray,
as the opaque shadow does. The refracted ray's lateral offset inside a slab is left out
(a 3 mm sheet at 45 degrees moves it about 1 mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..geometry import sphere_trace
from ..scene import Scene
from ..slab import excess_path, slab_coefficients
from .acquisition import SPEED_OF_LIGHT

__all__ = ["LineOfSight", "line_of_sight", "through_objects", "excess_delay", "thickness_along", "thin_slabs"]

_TRACE_EPS_M = 1e-7  # hit tolerance of the rays [m]: a slab's phase needs its thickness to a micrometre
_STEP_IN_M = 4e-5  # a ray restarts this far past a face it crossed [m]
MAX_CROSSINGS = 16  # faces a ray passes at most (a closed box with something behind it: 4)


@dataclass(frozen=True)
class LineOfSight:
    """Per sample: ``factor`` (Q,) complex128, the product of the slabs' T on the way
    (0 through metal, 1 in the clear); ``excess_m`` (Q,) float64, their summed one-way
    excess path [m]; ``crossings`` (Q,) int64, the objects' faces the ray entered."""

    factor: torch.Tensor
    excess_m: torch.Tensor
    crossings: torch.Tensor


def line_of_sight(scene: Scene, points: torch.Tensor, normals: torch.Tensor, centre_m: torch.Tensor,
                  frequency_hz: float, *, polarization: str = "mean", shadow_offset_m: float = _STEP_IN_M,
                  max_crossings: int = MAX_CROSSINGS) -> LineOfSight:
    """The one-way :class:`LineOfSight` of rays from ``points`` (Q, 3) [m] (started
    ``shadow_offset_m`` along their ``normals``) to ``centre_m`` (3,) [m], at ``frequency_hz``.
    A ray still inside objects after ``max_crossings`` faces is taken as blocked."""
    with torch.no_grad():
        origins = (points + shadow_offset_m * normals).double()
        to_centre = centre_m.to(origins) - origins
        remaining = to_centre.norm(dim=1)
        direction = to_centre / remaining[:, None]
        q = len(origins)
        factor = torch.ones(q, dtype=torch.complex128, device=origins.device)
        excess = torch.zeros(q, dtype=torch.float64, device=origins.device)
        crossings = torch.zeros(q, dtype=torch.long, device=origins.device)
        eps = scene.permittivities(frequency_hz, origins.device)
        active = torch.arange(q, device=origins.device)
        for _ in range(max_crossings):
            entry = sphere_trace(scene.sdf, origins[active], direction[active], eps=_TRACE_EPS_M, max_steps=256,
                                 t_max=remaining[active])
            met = entry.hit & (entry.t < remaining[active])
            active, entry_t, entry_points, entry_normals = (
                active[met], entry.t[met], entry.points[met], entry.normals[met])
            if not len(active):
                break
            which = scene.object_index(entry_points)
            cos_inc = (-(entry_normals * direction[active]).sum(1)).clamp(0, 1)
            chord = _chords(scene, which, entry_points + _STEP_IN_M * direction[active], direction[active],
                            remaining[active] - entry_t) + _STEP_IN_M
            lost = torch.isinf(chord)  # its way out not found (along a thin wall): as good as blocked
            chord = torch.where(lost, torch.zeros_like(chord), chord)
            thickness = chord * cos_inc
            transmission = slab_coefficients(cos_inc, eps[which], thickness, frequency_hz, polarization)[1]
            factor[active] *= torch.where(lost, torch.zeros_like(transmission), transmission)
            dielectric = ~torch.isinf(eps[which].real) & ~lost
            excess[active[dielectric]] += excess_path(cos_inc[dielectric], eps[which][dielectric].real,
                                                      thickness[dielectric])
            crossings[active] += 1
            advance = entry_t + chord + _STEP_IN_M
            origins[active] = origins[active] + advance[:, None] * direction[active]
            remaining[active] = remaining[active] - advance
            keep = dielectric & (remaining[active] > 0)
            active = active[keep]
        else:
            factor[active] = 0  # still crossing faces: as good as blocked
        return LineOfSight(factor, excess, crossings)


def through_objects(scene: Scene, points: torch.Tensor, normals: torch.Tensor, centre_m: torch.Tensor,
                    frequency_hz: float, polarization: str = "mean") -> tuple[torch.Tensor, torch.Tensor]:
    """Each surface sample's (Q, 3) [m], normals (Q, 3), two-way line of sight to
    ``centre_m`` (3,) [m] through the scene's objects (:func:`line_of_sight`): (Q,)
    complex128, T^2 of the slabs crossed at ``frequency_hz``, their excess path's phase
    there included (0 for samples facing away or behind metal), and (Q,) float64 the
    two-way excess path [m], whose delay relative to ``frequency_hz`` goes in at every
    frequency (:func:`excess_delay`; the rest of T is taken as flat over the band)."""
    points, normals = points.double(), normals.double()
    facing = (((centre_m.to(points) - points) * normals).sum(1) > 0).nonzero().squeeze(1)
    sight = line_of_sight(scene, points[facing], normals[facing], centre_m, frequency_hz, polarization=polarization)
    factor = torch.zeros(len(points), dtype=torch.complex128, device=points.device)
    factor[facing] = sight.factor**2
    excess = torch.zeros(len(points), dtype=torch.float64, device=points.device)
    excess[facing] = 2 * sight.excess_m
    return factor, excess


def excess_delay(frequencies_hz: torch.Tensor, centre_hz: float, excess_m: torch.Tensor) -> torch.Tensor:
    """(K, Q) complex128: exp(-j (k - k_c) x), the delay of each sample's two-way excess path
    x (Q,) [m] at each frequency (K,) [Hz] over its phase at the centre frequency, which
    :func:`through_objects`'s factor carries (in T's own phase)."""
    k = (2 * np.pi / SPEED_OF_LIGHT) * (frequencies_hz.to(excess_m.device, torch.float64) - centre_hz)
    return torch.exp(-1j * k[:, None] * excess_m.double()[None])


def thickness_along(scene: Scene, points: torch.Tensor, normals: torch.Tensor, object_index: torch.Tensor,
                    source_m: torch.Tensor, *, limit_m: float = 1.0) -> torch.Tensor:
    """(Q,) float64 [m]: the thickness of each sample's own object along the ray from
    ``source_m`` (3,) [m] that lights it, as a slab: the chord from the sample (Q, 3) [m]
    on through the object, times cos(theta_inc) (0 where the sample faces away, inf where
    the way out is not found). A chord longer than ``limit_m`` is cut there."""
    with torch.no_grad():
        points, normals = points.double(), normals.double()
        incident = torch.nn.functional.normalize(points - source_m.to(points), dim=1)
        cos_inc = -(incident * normals).sum(1)
        lit = (cos_inc > 0).nonzero().squeeze(1)
        thickness = torch.zeros(len(points), dtype=torch.float64, device=points.device)
        starts = points[lit] - _STEP_IN_M * normals[lit]
        limit = torch.full((len(lit),), limit_m, dtype=torch.float64, device=points.device)
        chord = _chords(scene, object_index[lit], starts, incident[lit], limit)
        thickness[lit] = torch.where(torch.isinf(chord), chord,  # way out not found: no slab
                                     (chord + _STEP_IN_M / cos_inc[lit]).clamp(max=limit_m) * cos_inc[lit])
        return thickness


def thin_slabs(scene: Scene, points: torch.Tensor, normals: torch.Tensor, object_index: torch.Tensor,
               source_m: torch.Tensor, frequency_hz: float, resolution_m: float) -> torch.Tensor:
    """(Q,) float64 [m]: each dielectric sample's :func:`thickness_along` the ray from
    ``source_m`` (3,) [m] where its round trip 2 d sqrt(eps') at ``frequency_hz`` is under
    ``resolution_m`` (the range resolution: the back face's echo not apart from the
    front's, so the face reflects as the slab); 0 elsewhere (a half space)."""
    eps_real = scene.permittivities(frequency_hz, points.device)[object_index].real
    dielectric = ~torch.isinf(eps_real)
    thickness = torch.zeros(len(points), dtype=torch.float64, device=points.device)
    thickness[dielectric] = thickness_along(scene, points[dielectric], normals[dielectric], object_index[dielectric],
                                            source_m, limit_m=resolution_m)
    thin = dielectric & (thickness > 0) & (2 * thickness * eps_real.clamp(min=1).sqrt() < resolution_m)
    return torch.where(thin, thickness, torch.zeros_like(thickness))


def _chords(scene: Scene, which: torch.Tensor, starts: torch.Tensor, direction: torch.Tensor,
            limit: torch.Tensor) -> torch.Tensor:
    """(R,) the distance [m] from ``starts`` (just inside object ``which[i]``) along
    ``direction`` to where the ray leaves that object: ``limit`` when it does not before,
    inf when the trace ends inside without finding the way out."""
    chord = limit.clone()
    for index in which.unique().tolist():
        rays = (which == index).nonzero().squeeze(1)
        sdf = scene.objects[index].sdf
        leave = sphere_trace(lambda p: -sdf(p), starts[rays], direction[rays], eps=_TRACE_EPS_M, max_steps=256,
                             t_max=limit[rays])
        beyond = leave.t >= limit[rays]
        chord[rays] = torch.where(leave.hit, leave.t.clamp(max=limit[rays]),
                                  torch.where(beyond, limit[rays], torch.full_like(leave.t, torch.inf)))
    return chord
