"""Each surface's |Gamma| read from the data in closed form, once the geometry is fitted.

The material head learns a class per point by gradient steps from a uniform start, and with a
known gain it learns the scene's mean level before the objects' differences
(docs/results/materials.md). What the data hold of a surface's material is its brightness, and
the renderer is linear in the reflection: so each segment of the surface (an object, a component
of the reconstruction) is rendered alone with a reflection of 1 at every angle, at the bright
voxels of every view, and the data's powers there are split over the segments by non-negative
least squares, |o|^2 ~ sum_i a_i^2 |p_i|^2 (powers add where the segments' phases are unrelated,
as in the calibration's split, :mod:`~rfsdf.recon.calibration`). a_i, segment i's
**brightness**, is how much brighter than a perfect reflector the data want it. It is |Gamma_i|
at normal incidence, the glints' own angle, where the scale is known: by a reference segment of
known material, |Gamma_i| = |Gamma_ref| a_i / a_ref, or by a known radar gain g (the renderer's
units to the data's), |Gamma_i| = a_i x the data's peak / g. Without either, only the ratios
are data.

Assumptions: the surface is right to a fraction of a millimetre over each glint's Fresnel zone
(a glint's brightness turns with it: the fitted network's ripples move it up to 15 %, a
primitive of the right shape reads within a few per cent; :func:`with_primitives`), each
glint is seen near normal incidence (a dielectric's |Gamma| falls off normal, which the unit
reflection does not model), and the segments' returns add in power, not coherently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .calibration import BRIGHT, split_powers

__all__ = ["PRIMITIVE_BAND_M", "SurfaceReadout", "primitive_union", "read_brightness", "read_surface",
           "with_primitives"]

PRIMITIVE_BAND_M = 3e-3  # within this of an explaining primitive the surface read is the primitive's [m]


@dataclass(frozen=True)
class SurfaceReadout:
    """Per segment its ``brightness`` a_i (S,) over a unit reflector's (NaN: the segment renders
    nothing where the data are bright), the ``scale`` that makes it |Gamma| at normal incidence
    (None: only ratios are data) and how many ``voxels`` were compared."""

    brightness: np.ndarray
    scale: float | None
    voxels: int

    @property
    def reflectivity(self) -> np.ndarray | None:
        """(S,) |Gamma_i| at normal incidence, or None without a scale."""
        return None if self.scale is None else self.brightness * self.scale


class _Unit:
    """A field that reflects 1 at every angle on every surface candidate: what the renderer needs
    of a field whose f it holds fixed (which candidates render is its ``only`` mask)."""

    material_head = None

    @staticmethod
    def reflectivity(anchors: torch.Tensor) -> torch.Tensor:
        return torch.ones(len(anchors), device=anchors.device)


@torch.no_grad()
def read_brightness(renderer, labelings: list[tuple[torch.Tensor, int]], *, gain: float | None = None,
                    reference: tuple[int, float] | None = None) -> list[SurfaceReadout]:
    """The module docstring's split on ``renderer`` (a CoherentRenderer refreshed on the surface
    to read), once per labeling of its candidates (labels (Q,) int64, each candidate's segment
    in [0, count), -1: none; e.g. by true object and by component of the mesh), all scaled as the
    first: by a ``reference`` (its segment, its |Gamma| at normal incidence) or, without one, a
    known ``gain``. The segments are rendered together, each distinct one once. A segment that
    renders nothing at the bright voxels (no surface there, or none lit) reads NaN: the data say
    nothing of it."""
    index = (renderer.observed.abs().max(0).values >= BRIGHT).nonzero().squeeze(1)
    views = torch.arange(renderer.num_views, device=renderer.device)
    masks = [labels.to(renderer.device) == i for labels, count in labelings for i in range(count)]
    distinct: list[torch.Tensor] = []  # a component that is an object is rendered once
    which = []
    for mask in masks:
        j = next((j for j, seen in enumerate(distinct) if torch.equal(seen, mask)), len(distinct))
        if j == len(distinct):
            distinct.append(mask)
        which.append(j)
    rendered = renderer.segment_images(_Unit, views, index, torch.stack(distinct))  # (S, V, X)
    images = [rendered[j] for j in which]  # one a mask, the labelings' segments one after another
    observed = renderer.observed[:, index].abs()  # the data's peak voxel is bright: X >= 1
    readouts, start = [], 0
    for _, count in labelings:
        mine, start = images[start:start + count], start + count
        lit = np.array([bool(image.abs().max() > 0) for image in mine])
        readouts.append(np.where(lit, split_powers(mine, observed), np.nan))
    scale = None
    if reference is not None:
        segment, reflectivity = reference
        scale = reflectivity / readouts[0][segment] if readouts[0][segment] > 0 else None  # NaN > 0 is False
    elif gain is not None:
        scale = renderer.observed_peak / gain
    return [SurfaceReadout(brightness, scale, len(index)) for brightness in readouts]


def read_surface(renderer, sdf, segmenters: list[tuple], *, gain: float | None = None,
                 reference: tuple[int, float] | None = None, seed: int = 0) -> list[SurfaceReadout]:
    """:func:`read_brightness` of the surface ``sdf`` ((N, 3) -> (N,) [m]): ``renderer`` refreshed on
    it (its samples drawn with ``seed``), each labeling of its candidates by a (segment_of, count)
    of ``segmenters``, segment_of their anchors (Q, 3) float64 [m] -> (Q,) int64."""
    renderer.refresh(sdf, torch.Generator().manual_seed(seed))
    anchors = renderer.candidates.anchors.double().cpu()
    return read_brightness(renderer, [(segment_of(anchors), count) for segment_of, count in segmenters],
                           gain=gain, reference=reference)


def primitive_union(points: torch.Tensor, primitives) -> torch.Tensor:
    """(N,) [m] the SDF of the union of ``primitives`` (at least one) at ``points`` (N, 3) [m], in
    float64 on the CPU, where the primitives' parameters live: the read surface is theirs where
    its magnitude is under ``PRIMITIVE_BAND_M`` (:func:`with_primitives`)."""
    held = points.double().cpu()
    return torch.stack([primitive(held) for primitive in primitives]).min(0).values


def with_primitives(sdf, primitives):
    """(N, 3) -> (N,) [m]: the ``primitives``' SDF (their union) within ``PRIMITIVE_BAND_M`` of them,
    ``sdf``'s (float32 points) elsewhere: the fitted surface with the shapes the primitives fitted
    to their range peaks where they stand, before the network's ripples."""
    def surface(points: torch.Tensor) -> torch.Tensor:
        network = sdf(points.float()).to(points.dtype)
        if not primitives:
            return network
        nearest = primitive_union(points, primitives).to(network)
        return torch.where(nearest.abs() < PRIMITIVE_BAND_M, nearest, network)
    return surface
