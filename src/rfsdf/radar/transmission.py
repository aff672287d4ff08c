"""Lines of sight through dielectric objects: what each crossing does to a return.

A ray from a surface sample to the array's phase centre that meets another object goes on
through it when the object is a dielectric: each crossing is a slab (:mod:`rfsdf.slab`)
whose thickness is the chord the ray cuts, d = chord x cos(theta_entry) (exact for a slab of
parallel faces, the first-order reading of a solid's), whose permittivity is the object's
material's, and which multiplies the one-way field by its T and stands the sample farther by
its excess electrical path (:func:`~rfsdf.slab.excess_path`). A metal object stops the ray,
as the opaque shadow does. The refracted ray's lateral offset inside a slab is left out
(a 3 mm sheet at 45 degrees moves it about 1 mm).

The line of sight's factor is T at the centre frequency; each slab it crossed is kept
(:class:`Slabs`), so that :func:`band_factor` gives T over the band, frequency by frequency
(a slab's internal reflections bend T off the excess path's linear delay: behind 6 mm of
glass by up to 17 % over 77-81 GHz), and :func:`sheet_reflection` a thin sheet's own R
(3 mm of glass: 0.49-0.79 of the half space's Gamma over the band).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import torch

from ..geometry import sphere_trace
from ..scene import Scene
from ..slab import excess_path, slab_coefficients, slab_over_band

__all__ = ["Slabs", "LineOfSight", "line_of_sight", "through_objects", "band_factor", "sheet_reflection",
           "thickness_along", "thin_slabs"]

_TRACE_EPS_M = 1e-7  # hit tolerance of the rays [m]: a slab's phase needs its thickness to a micrometre
_STEP_IN_M = 4e-5  # a ray restarts this far past a face it crossed [m]
MAX_CROSSINGS = 16  # faces a ray passes at most (a closed box with something behind it: 4)


@dataclass(frozen=True)
class Slabs:
    """The dielectric slabs each ray crossed, in the order it met them: ``object_index``
    (..., C) int64 (the scene's objects), ``cos_inc`` (..., C) float64 its incidence cosine,
    ``thickness_m`` (..., C) float64 [m]. A ray that crossed fewer than C (or crossed metal,
    which blocks it) is padded with slabs of no thickness, which pass it (T = 1)."""

    object_index: torch.Tensor
    cos_inc: torch.Tensor
    thickness_m: torch.Tensor

    def __getitem__(self, index) -> "Slabs":
        """The slabs of the rays ``index`` selects on the leading axes."""
        return Slabs(self.object_index[index], self.cos_inc[index], self.thickness_m[index])

    @staticmethod
    def clear(rays: int, width: int, device=None) -> "Slabs":
        """(rays, width) slabs of no thickness: rays that cross nothing."""
        return Slabs(torch.zeros(rays, width, dtype=torch.long, device=device),
                     torch.ones(rays, width, dtype=torch.float64, device=device),
                     torch.zeros(rays, width, dtype=torch.float64, device=device))

    @staticmethod
    def stack(parts: list["Slabs"]) -> "Slabs":
        """Slabs (Q, C_i) of several views as (V, Q, max C_i), the shorter padded."""
        width = max(part.thickness_m.shape[-1] for part in parts)

        def padded(tensors, value):
            return torch.stack([torch.nn.functional.pad(t, (0, width - t.shape[-1]), value=value) for t in tensors])

        return Slabs(padded([p.object_index for p in parts], 0), padded([p.cos_inc for p in parts], 1.0),
                     padded([p.thickness_m for p in parts], 0.0))

    def state(self) -> dict[str, torch.Tensor]:
        """The tensors, as a checkpoint keeps them (``Slabs(**state)`` again)."""
        return {"object_index": self.object_index, "cos_inc": self.cos_inc, "thickness_m": self.thickness_m}


@dataclass(frozen=True)
class LineOfSight:
    """Per sample: ``factor`` (Q,) complex128, the product of the slabs' T on the way at
    the centre frequency (0 through metal, 1 in the clear); ``excess_m`` (Q,) float64, their
    summed one-way excess path [m]; ``crossings`` (Q,) int64, the objects' faces the ray
    entered; ``slabs`` (Q, C) the dielectric slabs among them."""

    factor: torch.Tensor
    excess_m: torch.Tensor
    crossings: torch.Tensor
    slabs: Slabs


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
        columns = []  # per face crossed: (object, cos, thickness) of every ray, (Q,) each, T = 1 where none
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
            column = Slabs.clear(q, 1, origins.device)[:, 0]  # (Q,) each: this face, for every ray
            for values, found in zip(column.state().values(), (which, cos_inc, thickness)):
                values[active[dielectric]] = found[dielectric]
            columns.append(column.state().values())
            crossings[active] += 1
            advance = entry_t + chord + _STEP_IN_M
            origins[active] = origins[active] + advance[:, None] * direction[active]
            remaining[active] = remaining[active] - advance
            keep = dielectric & (remaining[active] > 0)
            active = active[keep]
        else:
            factor[active] = 0  # still crossing faces: as good as blocked
        slabs = (Slabs(*(torch.stack(parts, 1) for parts in zip(*columns))) if columns
                 else Slabs.clear(q, 0, origins.device))
        return LineOfSight(factor, excess, crossings, slabs)


def through_objects(scene: Scene, points: torch.Tensor, normals: torch.Tensor, centre_m: torch.Tensor,
                    frequency_hz: float, polarization: str = "mean") -> tuple[torch.Tensor, Slabs]:
    """Each surface sample's (Q, 3) [m], normals (Q, 3), two-way line of sight to
    ``centre_m`` (3,) [m] through the scene's objects (:func:`line_of_sight`): (Q,)
    complex128, T^2 of the slabs crossed at ``frequency_hz``, their excess path's phase
    there included (0 for samples facing away or behind metal), and the (Q, C) slabs
    crossed, whose T at every other frequency :func:`band_factor` gives."""
    points, normals = points.double(), normals.double()
    facing = (((centre_m.to(points) - points) * normals).sum(1) > 0).nonzero().squeeze(1)
    sight = line_of_sight(scene, points[facing], normals[facing], centre_m, frequency_hz, polarization=polarization)
    factor = torch.zeros(len(points), dtype=torch.complex128, device=points.device)
    factor[facing] = sight.factor**2
    slabs = Slabs.clear(len(points), sight.slabs.thickness_m.shape[1], points.device)
    for kept, found in zip(slabs.state().values(), sight.slabs.state().values()):
        kept[facing] = found
    return factor, slabs


def band_factor(scene: Scene, slabs: Slabs, frequencies_hz: torch.Tensor, centre_hz: float,
                polarization: str = "mean") -> torch.Tensor:
    """(K, Q) complex128: prod over each ray's ``slabs`` (Q, C) of (T(f) / T(f_c))^2, the
    two-way transmission at each frequency (K,) [Hz] over the centre frequency's, which
    :func:`through_objects`'s factor carries: the slabs' delay and their resonances across
    the band (:func:`~rfsdf.slab.slab_over_band`, each material's permittivity at each frequency)."""
    at_centre, *band = (t.prod(dim=-1) for _, t in _over_band(scene, slabs, [centre_hz, *frequencies_hz], centre_hz,
                                                              polarization))
    opaque = at_centre == 0  # a long lossy chord underflows: no return either way
    at_centre = torch.where(opaque, torch.ones_like(at_centre), at_centre)
    return torch.stack([torch.where(opaque, 0, t / at_centre) ** 2 for t in band])


def sheet_reflection(scene: Scene, sheets: Slabs, frequencies_hz: torch.Tensor, centre_hz: float,
                     polarization: str = "mean") -> torch.Tensor:
    """(K, Q) complex128: each sample's own thin sheet's slab R at each frequency (K,) [Hz]
    (``sheets`` (Q, 1), :func:`thin_slabs`), its internal reflections summed, so its
    resonances turn R across the band (3 mm of glass: 0.49-0.79 of the half space's Gamma
    over 77-81 GHz); 1 for a half space (its Fresnel coefficient is the reflectivity's)."""
    return torch.stack([torch.where(sheets.thickness_m > 0, r, 1)[:, 0]
                        for r, _ in _over_band(scene, sheets, frequencies_hz, centre_hz, polarization)])


def _over_band(scene: Scene, slabs: Slabs, frequencies_hz, centre_hz: float,
               polarization: str) -> Iterator[tuple[torch.Tensor, torch.Tensor]]:
    """(R, T) (Q, C) complex128 of the slabs at each of ``frequencies_hz`` in turn
    (:func:`~rfsdf.slab.slab_over_band`), computed where they have a thickness; the padding
    (slabs of none, of any object) passes: R = 0, T = 1."""
    some = (slabs.thickness_m > 0).nonzero(as_tuple=True)
    objects = slabs.object_index[some]

    def permittivity(frequency_hz: float) -> torch.Tensor:
        return scene.permittivities(frequency_hz, objects.device)[objects]

    for r_some, t_some in slab_over_band(slabs.cos_inc[some], permittivity, slabs.thickness_m[some], centre_hz,
                                         frequencies_hz, polarization):
        r = torch.zeros(slabs.thickness_m.shape, dtype=torch.complex128, device=slabs.thickness_m.device)
        t = torch.ones_like(r)
        r[some], t[some] = r_some, t_some
        yield r, t


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
               source_m: torch.Tensor, frequency_hz: float, resolution_m: float) -> Slabs:
    """(Q, 1) each sample's own object as a slab seen from ``source_m`` (3,) [m]: its
    :func:`thickness_along` that ray where the sample is a dielectric's and its round trip
    2 d sqrt(eps') at ``frequency_hz`` is under ``resolution_m`` (the range resolution: the
    back face's echo not apart from the front's, so the face reflects as the slab); of no
    thickness elsewhere (a half space)."""
    eps_real = scene.permittivities(frequency_hz, points.device)[object_index].real
    dielectric = ~torch.isinf(eps_real)
    thickness = torch.zeros(len(points), dtype=torch.float64, device=points.device)
    thickness[dielectric] = thickness_along(scene, points[dielectric], normals[dielectric], object_index[dielectric],
                                            source_m, limit_m=resolution_m)
    thin = dielectric & (thickness > 0) & (2 * thickness * eps_real.clamp(min=1).sqrt() < resolution_m)
    towards = torch.nn.functional.normalize(source_m.to(points).double() - points.double(), dim=1)
    cos_inc = (towards * normals.double()).sum(1).clamp(0, 1)
    return Slabs(object_index.long()[:, None], cos_inc[:, None],
                 torch.where(thin, thickness, torch.zeros_like(thickness))[:, None])


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
