"""Where the fit starts: f pre-fitted to the signed distance of a thresholded image.

The coherent fit refines a surface that is roughly right (a few mm of smooth error); it
does not find objects from nothing. The image of the data (view-mean MF power, or its
CLEAN image) says roughly where things are. A voxel is taken as inside where the image
amplitude exceeds both ``local_threshold`` of the *local* peak (the maximum over a window
of about a PSF, like a CFAR detector: every object is cut at its own half-amplitude
contour, so strong objects are not bloated by their blur and weak ones are kept) and
``threshold`` of the global peak (which drops what is only noise and far sidelobes). The
signed Euclidean distance to that set's boundary is the target, and f is regressed onto
it (L1, clipped, plus the Eikonal term) at random points in the box, a quarter of them
within a voxel of the set's boundary (uniform points alone left the demo's metal ball with
half its surface after 300 steps: a 2.5 cm ball gets about 30 of 8192). The reflectivity is
regressed at the same time onto the local peak amplitude, so weak reflectors (wood,
drywall) start dim instead of being explained away by moving their surfaces.

On the demo scene the local rule is what makes the start useful: marching cubes on the
CLEAN image cut this way scores Chamfer-L1 5.91 mm (F 0.59), against 8.67 mm for the best
global threshold of the same image and 9.72 mm for the best global threshold of the MF
image (docs/results/demo-quality.md); ``benchmarks/detection_settings.py`` scores
the closed target itself for other local thresholds and closings.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import torch
from scipy import ndimage

from ..geometry import Grid, gradient, interpolated_sdf, trilinear
from ..progress import progress_bar
from ..radar.detection import amplitude_of, detection_mask, in_front_of_ridges, on_range_sidelobes, window_voxels
from ..radar.range_peaks import RangePeaks
from ..scene import Scene
from .losses import BENDING_STEP_M, eikonal_penalty, normal_variation
from .sampling import random_offsets

__all__ = ["detection_threshold", "excluded_voxels", "known_exclusion", "mask_signed_distance", "detection_target",
           "local_peak_amplitude", "fit_to_image", "warm_start"]

_CLIP_M = 0.03  # residuals beyond 3 cm count as 3 cm: far-field values need not be exact


def detection_threshold(setting: float | str, clean=None) -> float:
    """The global threshold [fraction of the peak amplitude] for a config value: a number as
    given, "auto" as the residual floor of ``clean`` (a :class:`~rfsdf.radar.clean.CleanResult`:
    what CLEAN left unexplained, so the threshold follows the radar and the scene)."""
    if setting != "auto":
        return float(setting)
    if clean is None:
        raise ValueError('threshold "auto" needs the CLEAN image (init method "clean")')
    return clean.residual_floor()


def excluded_voxels(init, per_view_power: np.ndarray, acquisition, grid: Grid, threshold: float, *,
                    matched_filter_power: np.ndarray | None = None) -> np.ndarray:
    """(nx, ny, nz) bool: the voxels the ``[init]`` settings ``init`` take out of the detection:
    in front of a view's range ridge (``carve_front``) and range sidelobes
    (``blank_range_sidelobes``, within ``sidelobe_reach`` range resolutions), from the
    per-view image power (V, nx, ny, nz) of the :class:`~rfsdf.radar.Acquisition`
    ``acquisition`` at the global ``threshold``. With ``matched_filter_power`` (V, nx, ny, nz),
    the per-view matched-filter power beside a CLEAN image's, what is a sidelobe in either
    image is blanked (``sidelobes_in_mf``)."""
    centres = acquisition.view_centres()[0].cpu().numpy()
    rule = {"threshold": threshold, "local_threshold": init.local_threshold, "window_m": init.window_m}
    exclude = np.zeros(grid.shape, bool)
    if init.carve_front:
        exclude |= in_front_of_ridges(per_view_power, centres, grid, **rule)
    if init.blank_range_sidelobes:
        frequencies = acquisition.frequencies_hz.cpu().numpy()
        images = [per_view_power] + ([matched_filter_power] if matched_filter_power is not None else [])
        for power in images:
            exclude |= on_range_sidelobes(power, centres, frequencies, grid, reach=init.sidelobe_reach,
                                          level=init.sidelobe_level, **rule)
    return exclude


def known_exclusion(grid: Grid, scene: Scene, margin_m: float) -> np.ndarray:
    """(nx, ny, nz) bool: the voxels a reconstruction seen through the known ``scene`` (a box
    the objects are packed in) leaves out: those whose centre lies in one of its objects or
    within ``margin_m`` [m] of one, and, where its objects close off a cavity (free voxels,
    half a voxel from any wall so that a thin wall parts them, that do not reach beyond the
    grid; a voxel nearer a wall goes with the free voxels nearest to it), every voxel
    outside it: the objects are in the box."""
    with torch.no_grad():
        distance = scene.sdf(grid.points().double()).reshape(grid.shape).numpy()
    walls = distance < max(margin_m, 0.5 * float(np.max(grid.voxel_m)))
    labels, _ = ndimage.label(np.pad(~walls, 1, constant_values=True))  # the world beyond the grid is free
    # a voxel by a wall is on the side of the free voxels nearest to it
    nearest = labels[tuple(ndimage.distance_transform_edt(labels == 0, return_distances=False, return_indices=True))]
    cavity = (distance > 0) & (nearest[1:-1, 1:-1, 1:-1] != labels[0, 0, 0])
    return (distance < margin_m) | (~cavity if cavity.any() else np.zeros_like(walls))


def mask_signed_distance(inside: np.ndarray, grid: Grid) -> np.ndarray:
    """(nx, ny, nz) float32 signed distance [m] to the boundary of a voxel set, negative inside.

    Distances run between voxel centres, so the boundary sits half a voxel outside the last
    inside voxel.
    """
    voxel = tuple(float(v) for v in grid.voxel_m)
    half = 0.5 * float(np.mean(voxel))
    outside_distance = ndimage.distance_transform_edt(~inside, sampling=voxel) - half
    inside_distance = ndimage.distance_transform_edt(inside, sampling=voxel) - half
    return np.where(inside, -inside_distance, outside_distance).astype(np.float32)


def local_peak_amplitude(power: np.ndarray, window_voxels: int) -> np.ndarray:
    """(nx, ny, nz) float32 max of sqrt(power) over a cube of ``window_voxels``, peak 1."""
    amplitude = amplitude_of(power)
    peak = ndimage.maximum_filter(amplitude, size=max(1, int(window_voxels)))
    return (peak / max(float(peak.max()), 1e-30)).astype(np.float32)


def fit_to_image(field, lower_m, upper_m, target_sdf: Callable, target_reflectivity: Callable | None, *,
                 steps: int, lr: float, batch: int, eikonal_weight: float, generator: torch.Generator,
                 near_m: torch.Tensor | None = None, near_share: float = 0.0, near_jitter_m: float = 0.0,
                 target_normal: Callable | None = None, normal_weight: float = 0.0,
                 surface_m: torch.Tensor | None = None, surface_weights: torch.Tensor | None = None,
                 surface_weight: float = 0.0, surface_normals: torch.Tensor | None = None,
                 surface_normal_weight: float = 0.0, bending_weight: float = 0.0, bending_step_m: float = BENDING_STEP_M,
                 decay: bool = False, progress: bool = False) -> float:
    """Regress ``field`` (a RadarField) onto target functions of points (N, 3) [m] by Adam.

    Each step draws ``batch`` points uniformly in the box (not only on a voxel grid, so the
    net is pinned between voxel centres too), ``near_share`` of them instead within
    ``near_jitter_m`` of random points of ``near_m`` (M, 3) [m] (points near the target's
    zero set, where small objects would otherwise get a few of the batch): f by clipped L1
    against ``target_sdf`` plus the Eikonal term (on a quarter of the batch), Gamma by L1
    against ``target_reflectivity`` (None: f only). With ``target_normal`` (points -> (N, 3)
    mean bisectors m, :func:`~rfsdf.radar.specular.specular_normals`) the same quarter adds
    ``normal_weight`` * |m| (1 - cos(grad f, m)) where the target's own normal faces m: the
    faces the views see turn towards where the views say they face, the others are left alone.
    With ``surface_m`` (M, 3) [m], points the surface is known to pass through, and their
    ``surface_weights`` (M,), the loss adds ``surface_weight`` * |f| at a quarter batch of them
    drawn in proportion to their weights, and with their ``surface_normals`` (M, 3), unit or
    zero where a point's orientation is not known, ``surface_normal_weight`` * |n| (1 - cos(grad
    f, n)) at the same points: Hermite data. ``bending_weight``: the bending energy
    (:func:`~rfsdf.recon.losses.normal_variation`) at the near points, each against a point
    ``bending_step_m`` [m] away in a random direction. ``decay``: the rate annealed to zero over
    the steps (cosine), so that the network does not stop wherever the last batches left it.
    The field's coarse displacement, where it has one, stays as it is (zero): it is what the fit
    moves afterwards. Returns the last clipped L1 residual of f [m].
    """
    device = next(field.parameters()).device
    lower = torch.as_tensor(lower_m, dtype=torch.float32)
    extent = torch.as_tensor(upper_m, dtype=torch.float32) - lower
    optimizer = torch.optim.Adam([p for name, p in field.named_parameters() if not name.startswith("displacement.")],
                                 lr=lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps) if decay else None
    residual = float("nan")
    near_count = 0 if near_m is None or len(near_m) == 0 else int(near_share * batch)
    for _ in progress_bar(range(steps), desc="warm start", enabled=progress):
        points = lower + extent * torch.rand(batch, 3, generator=generator)
        if near_count:
            pick = torch.randint(len(near_m), (near_count,), generator=generator)
            points[:near_count] = near_m[pick] + near_jitter_m * (2 * torch.rand(near_count, 3, generator=generator) - 1)
        points = points.to(device)
        f, gamma = field.sdf_and_reflectivity(points)
        with torch.no_grad():
            target = target_sdf(points)
        misfit = (f - target).abs().clamp(max=_CLIP_M).mean()
        shaped = points[: max(1, batch // 4)]
        grad = gradient(field.sdf, shaped, create_graph=True)
        loss = misfit + eikonal_weight * eikonal_penalty(grad)
        if target_normal is not None and normal_weight > 0:
            facing = gradient(target_sdf, shaped)
            loss = loss + normal_weight * _facing_misfit(grad, target_normal(shaped), facing)
        if surface_m is not None and len(surface_m) and surface_weight > 0:
            pick = torch.multinomial(surface_weights, max(1, batch // 4), replacement=True, generator=generator)
            on = surface_m[pick].to(device)
            oriented = surface_normals is not None and surface_normal_weight > 0
            f_on = field.sdf(on.requires_grad_(oriented))
            loss = loss + surface_weight * f_on.abs().mean()
            if oriented:
                (grad_on,) = torch.autograd.grad(f_on.sum(), on, create_graph=True)
                normals = surface_normals[pick].to(device)
                loss = loss + surface_normal_weight * _misalignment(grad_on, normals).mean()
        if bending_weight > 0 and near_count:
            offsets = random_offsets(near_count, bending_step_m, generator).to(device)
            loss = loss + bending_weight * normal_variation(field.sdf, points[:near_count], offsets)
        if target_reflectivity is not None:
            with torch.no_grad():
                target_gamma = target_reflectivity(points)
            loss = loss + (gamma - target_gamma).abs().mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        if schedule is not None:
            schedule.step()
        residual = float(misfit.detach())
    return residual


def _misalignment(grad: torch.Tensor, normals: torch.Tensor) -> torch.Tensor:
    """(N,) |n| (1 - cos(grad, n)) for gradients (N, 3) and normals n (N, 3), whose length is
    how sure each is: 0 aligned or where n is zero (unknown), 2 |n| opposed."""
    length = normals.norm(dim=1)
    return length * (1 - (grad * normals).sum(1) / (grad.norm(dim=1) * length).clamp(min=1e-12))


def _facing_misfit(grad: torch.Tensor, bisector: torch.Tensor, target_grad: torch.Tensor) -> torch.Tensor:
    """mean |m| (1 - cos(grad, m)) over the points (N,) where the target's own normal faces m
    (gated by the fixed target, not by f, so a face turning away cannot drag its neighbours)."""
    return (_misalignment(grad, bisector) * ((target_grad * bisector).sum(1) > 0)).mean()


def detection_target(power: np.ndarray, grid: Grid, *, threshold: float, local_threshold: float, window_m: float,
                     closing_m: float, exclude: np.ndarray | None = None) -> np.ndarray:
    """(nx, ny, nz) float32 signed distance [m] (negative inside) to the detection set of the
    image ``power``: :func:`detection_mask` with a local window of edge ``window_m`` [m],
    less the voxels of ``exclude`` (bool, grid.shape; e.g. ``in_front_of_ridges``), closed
    morphologically by a ball of radius ``closing_m`` [m]. What f is regressed onto."""
    inside = detection_mask(power, threshold=threshold, local_threshold=local_threshold,
                            window_voxels=window_voxels(window_m, grid))
    if exclude is not None:
        inside &= ~exclude
    radius = round(closing_m / float(np.max(grid.voxel_m)))
    if radius > 0:  # join the separate glints of one smooth object into one volume
        ball = np.linalg.norm(np.mgrid[-radius:radius + 1, -radius:radius + 1, -radius:radius + 1], axis=0) <= radius
        inside = ndimage.binary_closing(np.pad(inside, radius), structure=ball)
        inside = inside[radius:-radius, radius:-radius, radius:-radius]
    return mask_signed_distance(inside, grid)


def warm_start(field, power: np.ndarray, grid: Grid, *, threshold: float, local_threshold: float, window_m: float,
               closing_m: float, steps: int, lr: float, batch: int, eikonal_weight: float, generator: torch.Generator,
               near_share: float = 0.0, exclude: np.ndarray | None = None, normals: np.ndarray | None = None,
               normal_weight: float = 0.0, peaks: RangePeaks | None = None, peak_weight: float = 0.0,
               peak_normal_weight: float = 0.0, peak_apex_m: float = 0.0, bending_weight: float = 0.0,
               bending_step_m: float = BENDING_STEP_M, progress: bool = False) -> float:
    """Fit ``field`` to the image ``power`` (grid.shape, view-mean MF or CLEAN power): f to the
    signed distance of :func:`detection_target` (``exclude`` as there), Gamma to the local peak
    amplitude (both interpolated between voxel centres), and with ``normals`` ((3, *grid.shape)
    mean bisectors, :func:`~rfsdf.radar.specular.specular_normals`) the seen faces' normals to
    them (``normal_weight``, see :func:`fit_to_image`). With ``peaks``
    (:func:`~rfsdf.radar.range_peaks.range_peaks`), the zero set is pulled through those within
    a voxel of the target's boundary (``peak_weight``, weighted by their amplitude): the
    views' surface to a fraction of a voxel where the target has it to half of one; and with
    ``peak_normal_weight`` its normal towards the view at each glint's centre, the peaks that are
    the strongest of their view's within ``peak_apex_m`` [m] (:meth:`RangePeaks.apexes`; 0: at
    every peak): a glint is a specular return, the surface there faces its view.
    ``window_m`` [m] is the local window's edge. Returns the last clipped L1 residual of f [m]."""
    device = next(field.parameters()).device
    signed = detection_target(power, grid, threshold=threshold, local_threshold=local_threshold, window_m=window_m,
                              closing_m=closing_m, exclude=exclude)
    distance = torch.from_numpy(signed).to(device)
    peak = torch.from_numpy(local_peak_amplitude(power, window_voxels(window_m, grid))).to(device)
    voxel = float(np.max(grid.voxel_m))
    near = grid.points()[torch.from_numpy(np.abs(signed).ravel() < voxel)]  # voxel centres by the boundary
    target = interpolated_sdf(distance, grid)
    surface, weights, facing = None, None, None
    if peaks is not None and peak_weight > 0:
        surface = torch.from_numpy(peaks.points).float().to(device)
        on_boundary = target(surface).abs() <= voxel
        surface = surface[on_boundary]
        weights = torch.from_numpy(peaks.amplitude).float().to(device)[on_boundary]
        if peak_normal_weight > 0:
            apex = peaks.apexes(peak_apex_m) if peak_apex_m > 0 else np.ones(len(peaks.points), bool)
            facing = torch.from_numpy(peaks.towards * apex[:, None]).float().to(device)[on_boundary]
    target_normal = None
    if normals is not None:
        target_normal = trilinear(torch.from_numpy(np.ascontiguousarray(normals)).to(device), grid)
    return fit_to_image(field, grid.lower_m, grid.upper_m, target,
                        trilinear(peak, grid), steps=steps, lr=lr, batch=batch,
                        eikonal_weight=eikonal_weight, generator=generator, near_m=near, near_share=near_share,
                        near_jitter_m=voxel, target_normal=target_normal, normal_weight=normal_weight,
                        surface_m=surface, surface_weights=weights, surface_weight=peak_weight,
                        surface_normals=facing, surface_normal_weight=peak_normal_weight,
                        bending_weight=bending_weight, bending_step_m=bending_step_m, progress=progress)

