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

How far a reading can be trusted is measured the same way: the split is repeated with each view
left out in turn, and the spread of those readings (the jackknife's standard error over views,
``SurfaceReadout.spread``) is what a segment's |Gamma| would move by had another set of views seen
it: a glint one view alone sees, a view whose wrong surface brightens a segment, noise.

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
    (None: only ratios are data), how many ``voxels`` were compared, and the ``spread`` (S,) of
    the reflectivity (of the brightness without a scale): the jackknife's standard error over the
    views, each left out in turn (NaN with one view, or where a view left out leaves the segment
    unlit or the reference unread)."""

    brightness: np.ndarray
    scale: float | None
    voxels: int
    spread: np.ndarray

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
    nothing of it. Each split is repeated with each view left out, for the readings' spread (the
    module docstring), from the same rendered images."""
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
    images = torch.stack([rendered[j] for j in which])  # one a mask, the labelings' segments one after another
    observed = renderer.observed[:, index].abs()  # the data's peak voxel is bright: X >= 1
    # (1 + V, segments of all labelings): the split with every view, then with each left out
    every = torch.ones_like(views, dtype=torch.bool)
    subsets = [every, *(views != v for v in views)] if len(views) > 1 else [every]
    splits = np.array([_split(images[:, keep], observed[keep], labelings) for keep in subsets])
    scales = np.full(len(splits), np.nan)  # each split's |Gamma| per unit brightness
    if reference is not None:
        segment, reflectivity = reference
        read = splits[:, segment]  # NaN where the reference renders nothing
        scales = np.divide(reflectivity, read, out=scales, where=read > 0)
    elif gain is not None:
        scales[:] = renderer.observed_peak / gain
    scale = float(scales[0]) if np.isfinite(scales[0]) else None
    spread = _jackknife(splits[1:] if scale is None else splits[1:] * scales[1:, None])
    readouts, start = [], 0
    for _, count in labelings:
        readouts.append(SurfaceReadout(splits[0, start:start + count], scale, len(index), spread[start:start + count]))
        start += count
    return readouts


def _jackknife(replicates: np.ndarray) -> np.ndarray:
    """(S,) the jackknife's standard error from the leave-one-out ``replicates`` (V, S):
    sqrt((V - 1) / V sum_v (x_v - mean)^2); NaN with fewer than two."""
    count = len(replicates)
    if count < 2:
        return np.full(replicates.shape[1:], np.nan)
    return np.sqrt((count - 1) / count * ((replicates - replicates.mean(0)) ** 2).sum(0))


def _split(images: torch.Tensor, observed: torch.Tensor, labelings) -> np.ndarray:
    """(sum of counts,) each labeling's segments' brightness split from ``images`` (S, V', X) and
    the data's amplitudes ``observed`` (V', X), one labeling at a time; NaN where a segment renders
    nothing."""
    out, start = [], 0
    for _, count in labelings:
        mine, start = list(images[start:start + count]), start + count
        lit = np.array([bool(image.abs().max() > 0) for image in mine])
        out.append(np.where(lit, split_powers(mine, observed), np.nan))
    return np.concatenate(out)


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
