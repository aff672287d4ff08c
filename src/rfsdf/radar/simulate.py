"""Radar measurements of a scene: surface scattering through the Born model, with shadows and noise.

Each surface sample p (area dA, normal n, material eps) scatters, in view v, as
:func:`~rfsdf.radar.scattering.scatter` says: c = Gamma(theta_inc, eps(f_c)) * L * dA * lit,
with the Fresnel coefficient of its material at the centre frequency, the specular/diffuse
lobe L, and shadows sphere-traced against the scene from p to the array's phase centre
(one ray per sample and view; the array is small next to the range). The reconstruction's
coherent renderer calls the same function on samples of the neural surface.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
import torch

from ..atomic import atomic_path
from ..errors import RfsdfError
from ..materials import fresnel
from ..progress import progress_bar
from ..scene import Scene, SurfaceSamples
from .acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from .operator import SensingOperator
from .scattering import DIFFUSE_WEIGHT, SPECULAR_EXPONENT, po_spectrum, scatter, unblocked
from .facets import facet_weight
from .surface_plan import surface_samples
from .system import Radar
from .waveform import range_resolution_m
from .transmission import Slabs, band_factor, sheet_reflection, thin_slabs, through_objects

__all__ = ["simulate", "surface_reflectivity", "view_reflectivities", "add_noise", "noise_draw", "SAMPLES_PER_WAVELENGTH",
           "SIMULATED_GAIN"]

SIMULATED_GAIN = 1.0
"""The radar gain of data this module simulates: their amplitudes are the scattering model's
own (Fresnel x lobe x area through A, no antenna or receiver gain), so a renderer of the
same physics predicts them in their units."""

# Points summed as a quadrature leave a speckle that no other sampling reproduces: two
# samplings of the 2 cm ball (6 views) differ by 21 % of the MF amplitude energy at lambda/3,
# 5 % at lambda/6 and 1.2 % at lambda/12 (error ~ spacing^2), and two lambda/3 stratified
# samplings of the demo scene correlate only 0.78-0.93 per view, a floor above the signal of a
# millimetre's error. So the surface is summed as flat facets of its zero set, whose phase is
# integrated in closed form (rfsdf.geometry.zero_set): on lambda/3 cells two meshes of the demo
# scene agree to 0.9996 per view (benchmarks/forward_convergence.py). A diffuse return that
# does not depend on the sampling comes from stated roughness (rfsdf.roughness).
# ``surface="points"`` keeps the points (``stratified=False`` the earlier random ones).
SAMPLES_PER_WAVELENGTH = 3
_REFLECTIVITY_BYTES = 1 << 27  # a scan's frames' reflectivities (F, Q) at once

def surface_reflectivity(
    scene: Scene, points: torch.Tensor, normals: torch.Tensor, area_m2: torch.Tensor, object_index: torch.Tensor,
    tx_centre: torch.Tensor, rx_centre: torch.Tensor, frequency_hz: float, *,
    specular_exponent: float = SPECULAR_EXPONENT, diffuse_weight: float = DIFFUSE_WEIGHT, polarization: str = "mean",
    shadows: bool = True, slab_m: torch.Tensor | None = None,
) -> torch.Tensor:
    """Complex reflectivity (Q,) complex64 of surface samples seen from one view's Tx/Rx phase
    centres [m]: :func:`~rfsdf.radar.scattering.scatter` with the Fresnel coefficient of each
    sample's material at ``frequency_hz`` and the scene itself as the occluder. ``slab_m``
    (Q,) [m] each sample's thickness as a thin slab along its lighting ray, 0 for a half
    space (:func:`~rfsdf.radar.transmission.thin_slabs`): a sample with one reflects as that
    slab, whose R (internal reflections summed) turns over the band, so its reflectivity here
    is without it, and R goes in at every frequency (:func:`~rfsdf.radar.transmission.sheet_reflection`)."""
    sample_eps = scene.permittivities(frequency_hz, points.device)[object_index]
    reflection = lambda cos_inc: fresnel(torch.arccos(cos_inc), sample_eps, polarization)  # noqa: E731
    if slab_m is not None:
        sheet, half_space = slab_m.to(points.device) > 0, reflection
        reflection = lambda cos_inc: torch.where(sheet, 1, half_space(cos_inc))  # noqa: E731
    c = scatter(points.double(), normals.double(), area_m2.double(), reflection,
                tx_centre.double(), rx_centre.double(), 2 * np.pi * frequency_hz / SPEED_OF_LIGHT,
                specular_exponent=specular_exponent, diffuse_weight=diffuse_weight,
                occluder=scene.sdf if shadows else None)
    return c.to(torch.complex64)


def view_reflectivities(scene: Scene, samples: SurfaceSamples, acquisition: Acquisition, *,
                        sight: torch.Tensor | None = None, progress: bool = False, **scattering) -> torch.Tensor:
    """(V, Q) complex64: :func:`surface_reflectivity` of the samples in each frame, at the
    centre frequency, from that frame's Tx and Rx phase centres; ``scattering`` as there.
    ``sight`` (Q,) each sample's line of sight found once for all these frames (a scan's,
    from its centre), so that no frame traces its own: bool (unshadowed) or complex (through
    objects, :func:`~rfsdf.radar.transmission.through_objects`)."""
    acq, device = acquisition, samples.points.device
    if sight is not None:
        scattering = {**scattering, "shadows": False}
    tx, rx = acq.tx_m.mean(1).to(device), acq.rx_m.mean(1).to(device)
    c = torch.stack([
        surface_reflectivity(scene, samples.points, samples.normals, samples.area_m2, samples.object_index,
                             tx[v], rx[v], acq.center_frequency_hz, **scattering)
        for v in progress_bar(range(acq.shape[0]), desc="scattering", enabled=progress)
    ])
    return c if sight is None else c * sight.to(device=device, dtype=c.dtype)


def _through(weight, scene: Scene, acquisition: Acquisition, slabs: Slabs, sheets: Slabs, polarization: str,
             views: slice, points: slice) -> torch.Tensor:
    """A chunk's per-frequency weight (v, K, q) (:meth:`SensingOperator.forward_weighted`):
    ``weight``'s (None: 1) times each point's slabs' two-way T at each frequency over the
    centre frequency's (:func:`band_factor`) and its own thin sheet's R at each frequency
    (:func:`sheet_reflection`)."""
    band = (band_factor(scene, slabs[points], acquisition.frequencies_hz, acquisition.center_frequency_hz,
                        polarization)
            * sheet_reflection(scene, sheets[points], acquisition.frequencies_hz, acquisition.center_frequency_hz,
                               polarization))  # (K, q)
    if weight is None:
        return band[None].expand(len(acquisition.tx_m[views]), -1, -1)
    facets = weight(views, points)
    return facets * band[None].to(facets.dtype)


def noise_draw(shape, generator: torch.Generator) -> torch.Tensor:
    """(shape) complex64 randn + j randn from ``generator``: the draw :func:`add_noise` scales
    by sigma / sqrt(2) (a benchmark regenerates it to take a run's noise out)."""
    return torch.complex(torch.randn(shape, generator=generator), torch.randn(shape, generator=generator))


def add_noise(y: torch.Tensor, snr_db: float, generator: torch.Generator) -> tuple[torch.Tensor, float]:
    """y + circular complex Gaussian noise with mean|y|^2 / sigma^2 = 10^(snr/10); returns (y, sigma)."""
    sigma = float(torch.sqrt((y.abs() ** 2).mean() / 10 ** (snr_db / 10)))
    return y + (sigma / np.sqrt(2)) * noise_draw(y.shape, generator).to(y.dtype), sigma


def _require_resolved_roughness(scene: Scene, spacing_m: float) -> None:
    """ValueError naming the object when a rough surface's heights vary faster than samples
    ``spacing_m`` [m] apart resolve (more than half its correlation length)."""
    for obj in scene.objects:
        if obj.roughness is not None and spacing_m > obj.roughness.correlation_m / 2:
            raise ValueError(f"scene {scene.name!r}: object {obj.name!r}: roughness correlation_m "
                             f"{obj.roughness.correlation_m * 1e3:.3g} mm needs surface samples at most "
                             f"{obj.roughness.correlation_m * 500:.3g} mm apart; the simulator samples "
                             f"{spacing_m * 1e3:.3g} mm apart (a longer correlation, or a finer spacing_m "
                             "with more max_samples)")


def _views_done(checkpoint: Path | None, shape: tuple, num_samples: int) -> tuple[torch.Tensor, int]:
    """(y (F, T, R, K) with the views a checkpoint holds, how many it holds): zeros and 0
    without one; RfsdfError for one of another simulation."""
    if checkpoint is None or not Path(checkpoint).is_file():
        return torch.zeros(shape, dtype=torch.complex64), 0
    held = torch.load(checkpoint, weights_only=True)
    if tuple(held["y"].shape) != tuple(shape) or held["surface_samples"] != num_samples:
        raise RfsdfError(f"{checkpoint}: a checkpoint of another simulation ({held['surface_samples']} surface "
                         f"samples, data {tuple(held['y'].shape)}; this one {num_samples}, {tuple(shape)}); "
                         "delete it to start again")
    return held["y"], int(held["views_done"])


def simulate(
    scene: Scene, radar: Radar, *, seed: int = 0, spacing_m: float | None = None, max_samples: int = 150_000,
    samples_per_wavelength: float = SAMPLES_PER_WAVELENGTH,
    specular_exponent: float = SPECULAR_EXPONENT, diffuse_weight: float = DIFFUSE_WEIGHT, polarization: str = "mean",
    shadows: bool = True, stratified: bool = True, surface: str = "facets", transmission: bool = False,
    device=None, progress: bool = False, checkpoint: Path | None = None,
) -> Measurements:
    """Simulated measurements of ``scene`` by ``radar`` (reproducible for a given ``seed``).

    The surface is covered on cells ``lambda / samples_per_wavelength`` (``spacing_m``
    overrides) when points that far apart would number at most ``max_samples``: by flat
    facets of its zero set (``surface="facets"``, the default, the converged quadrature;
    ``seed`` offsets their grid) or by points (``"points"``; ``stratified`` places them one
    per stratum of equal area, :meth:`~rfsdf.scene.Scene.sample_surface`, which cuts their
    random error, study ``roughness``); else as flat facets over the surface some view sees,
    no coarser than the physics allows, or ValueError (:mod:`~rfsdf.radar.surface_plan`; its
    summary is the metadata's "surface_sampling"). Rough objects need samples at most half
    their correlation length apart, else ValueError. With ``transmission`` a line of sight
    goes on through dielectric objects instead of stopping at them (each crossing a slab of
    the chord's thickness: its T out and back at every frequency, whose phase delays the
    sample, :mod:`~rfsdf.radar.transmission`); metal still blocks. Noise is added
    at ``radar.snr_db`` (None: noise-free). Scattering and A c run on ``device`` (None: CPU); the surface samples are
    drawn and the noise added on the CPU, so the data do not depend on the device beyond
    float rounding. Where views are traced one by one (scans, transmission: a room through
    glass takes hours), ``checkpoint`` names a file that keeps the views done, written after
    each; a rerun with the same arguments continues from it, and the same data result.
    """
    acq = radar.acquisition()
    samples, plan = surface_samples(scene, acq, spacing_m or acq.wavelength_m / samples_per_wavelength, max_samples,
                                    seed=seed, stratified=stratified, surface=surface)
    _require_resolved_roughness(scene, plan.facet_edge_m if plan.facets else plan.spacing_m)
    samples = samples.to(device or "cpu")
    scattering = {"specular_exponent": specular_exponent, "diffuse_weight": diffuse_weight,
                  "polarization": polarization, "shadows": shadows}
    points = scene.rough_points(samples)

    def measure(part: Acquisition, sight: torch.Tensor | None = None, slabs: Slabs | None = None,
                sheets: Slabs | None = None, show: bool = progress) -> torch.Tensor:
        """y = A c of the frames of ``part``, (F, T, R, K) on the CPU; with ``sight`` (Q,)
        (bool or complex: each sample's line of sight, found once for these frames) summed
        over the samples some frame sees (a scan: about half), each through its ``slabs``
        (Q, C) and reflecting as its own thin sheet ``sheets`` (Q, 1) at every frequency."""
        slab_m = None if sheets is None else sheets.thickness_m[:, 0]
        c = view_reflectivities(scene, samples, part, sight=sight, progress=show, slab_m=slab_m, **scattering)
        seen = (c != 0).any(0) if sight is not None else torch.ones(c.shape[1], dtype=torch.bool, device=c.device)
        operator, c = SensingOperator(part), c[:, seen]
        weight = None if samples.corners_m is None else facet_weight(part, samples.points[seen],
                                                                      samples.corners_m[seen])
        if slabs is not None:
            kept = seen.to(slabs.thickness_m.device)
            weight = partial(_through, weight, scene, part, slabs[kept], sheets[kept], polarization)
        if weight is None:
            return operator.forward(points[seen], c, progress=show).cpu()
        return operator.forward_weighted(points[seen], c, weight, progress=show).cpu()

    if acq.scans is None and not transmission:
        y = measure(acq)
    else:
        # A scan's frames trace one set of lines of sight, from its centre: its frames see a
        # hand-sized object within some 15 degrees of it (sar-77g), and a ray per sample and
        # frame would cost thousands of traces a sample. Through objects, each view traces its own.
        y, done = _views_done(checkpoint, acq.shape, len(samples.points))
        chunk = max(1, _REFLECTIVITY_BYTES // (8 * len(samples.points)))
        centres = 0.5 * sum(acq.view_centres())  # (S, 3) each view's phase centre
        for view in progress_bar(range(done, acq.num_views), desc="views", enabled=progress,
                                 initial=done, total=acq.num_views):
            centre, slabs, sheets = centres[view].to(samples.points), None, None
            if transmission:  # a sheet's front face returns its back face's echo too, within a range cell
                sight, slabs = through_objects(scene, samples.points, samples.normals, centre,
                                                acq.center_frequency_hz, polarization)
                sheets = thin_slabs(scene, samples.points, samples.normals, samples.object_index, centre,
                                  acq.center_frequency_hz, range_resolution_m(acq.bandwidth_hz))
            else:
                sight = (unblocked(samples.points, samples.normals, centre, scene.sdf)
                         if shadows else torch.ones(len(samples.points), dtype=torch.bool))
            for part in acq.frames(view).split(chunk):
                y[part] = measure(acq.view(part), sight, slabs, sheets, show=False)
            if checkpoint is not None:
                with atomic_path(checkpoint) as tmp:
                    torch.save({"views_done": view + 1, "surface_samples": len(samples.points), "y": y}, tmp)
    y = y * po_spectrum(acq.frequencies_hz).to(y.dtype)
    noise_std = None
    if radar.snr_db is not None:
        y, noise_std = add_noise(y, radar.snr_db, torch.Generator().manual_seed(seed + 1))
    bounds = ",".join(f"{v:.9g}" for v in (*scene.lower_m, *scene.upper_m))
    metadata = {"scene": scene.name, "radar": radar.name, "bounds_m": bounds, "surface_samples": str(len(samples.points)),
                "surface_sampling": plan.summary(len(samples.points))}
    if transmission:
        metadata["lines_of_sight"] = "through dielectric objects (ITU-R P.2040 slabs), blocked by metal"
    return Measurements(acq, y, noise_std, metadata)
