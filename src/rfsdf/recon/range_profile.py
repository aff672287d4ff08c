"""The primitive fit at room scale: each view's range profile instead of an image.

A room seen by a 60 GHz module is metres across, and the image-domain fit would need its
box on a grid of the radar's resolution (about 96 M voxels for ``l-room``); what the data
of a few-centimetre array resolve is range. So the room's model is fitted to each view's
**range profile**, the power of its channels' data transformed over frequency to
round-trip path length p (Hann window, Tx-Rx pairs averaged incoherently):
P_v(p) = mean_ch |sum_k w_k y_k exp(+j 2 pi f_k p / c)|^2, peaked where a surface's
specular return comes from (the data model is exp(-j k (d_tx + d_rx)), design.md).

The model's profile comes from rays: from each view's array centre, a grid of directions
over its beam is sphere-traced against the model's analytic SDF. A ray that hits at range t
with incidence cosine cos votes for the specular return of the surface's tangent plane
there: the image source of that plane, at the plane's foot point (distance R = t cos,
normal incidence), with the power of a flat wall's return (|Gamma(0)| g(-n)^2 / 2R)^2
(the hit object's Fresnel coefficient, the two-way antenna pattern towards the foot)
times the ray's share of the simulator's specular lobe, cos^(2 n_s) dOmega (2 n_s + 1) /
2 pi, which sums to 1 over a wall. A hit whose foot point is off the surface (a face seen
edge-on, beyond its edge) does not vote. Voting 2 t instead put an oblique ray's vote
behind the wall and biased every wall outwards; voting every hit's plane put strong peaks
where faces seen edge-on have none. Each vote is spread by a Gaussian of the data's own
point-spread width. Only distances carry gradients: by implicit differentiation of
f(o + t d) = 0 the plane's distance moves by df/dtheta (as IDR moves its surface); the
weights are held per step.

The votes' weights are right in shape, not in scale: a face that subtends less than the
lobe gets only part of it, and each view's profile is normalised. So a free material is
not fitted through them (measured: a 30 cm concrete wall read 0.29 for 0.39) but read after
the fit (:func:`image_source_reflectivities`): each seen face's data peak over the image
source's.

The loss compares amplitude profiles (square roots, normalised per view: the gain is
unknown) by least squares, both blurred by a Gaussian whose width shrinks from
``blur_start_m`` to 0 over the fit: a coarse-to-fine schedule over range, so a wall 15 cm
off still overlaps its own peak at the start. The data's noise is part of the model's
profile (:func:`noise_floor`, added to the model's scaled to the data), so a wall a few dB
over the noise still has the loss's minimum at it. What this model leaves out: multipath (a
wall's image of another wall, the corner's double bounce) and range ambiguity (returns
beyond c / (2 delta f) fold back); both would enter as extra terms of the model's profile.

With ``transmission`` (``ProfileSettings``), as the simulator's (:mod:`rfsdf.radar.transmission`),
a ray that hits a dielectric goes on through it: the crossing is a slab of the chord's
thickness times the incidence cosine, its own vote is the slab's reflection where the slab
is thin (its round trip under the range resolution), and every hit behind it votes with
|T|^4 of its power (T out and back) from farther by twice the slab's delay over the band
(:func:`~rfsdf.slab.band_delay`: where the simulator's T over the band puts it). Metal
stops the ray. The slabs' factors are held per step (their gradients left out), the hits'
distances behind them carry theirs as any hit's.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Callable

import torch

from ..geometry import sphere_trace
from ..geometry.differential import gradient
from ..materials import class_permittivities, class_reflectivities, mixture_fresnel
from ..progress import progress_bar
from ..radar import SPEED_OF_LIGHT, Measurements
from ..radar.scattering import SPECULAR_EXPONENT
from ..radar.waveform import range_resolution_m
from ..slab import band_delay, slab_coefficients
from ..scene_model import SceneModel
from .primitive import RELATIVE_GAIN, PrimitiveField, PrimitiveFit
from .schedules import exponential_decay

__all__ = ["ProfileSettings", "path_axis", "view_beams", "data_profiles", "model_profiles", "noise_floor", "profile_loss",
           "fit_primitive_profiles", "fit_profiles", "image_source_reflectivities"]

_HANN_FWHM = 1.44  # Hann window's main-lobe width at half power, in units of c / B (path)
# a hit votes only when its tangent plane's foot point lies on the surface (within this share
# of its distance): a face seen edge-on has its foot beyond its edge and no specular return
FOOT_TOLERANCE = 0.02
_NEGLIGIBLE = 1e-6  # votes below this share of the strongest are dropped (most hits are far off specular)
MAX_CROSSINGS = 4  # with transmission: dielectric objects a ray goes on through at most
_STEP_IN_M = 4e-5  # a ray restarts this far past a face it crossed [m]
DELAY_FREQUENCIES = 17  # a slab's delay over the band from its T at these many frequencies (rfsdf.slab.band_delay)


def path_axis(measurements: Measurements, step_m: float, near_m: float) -> torch.Tensor:
    """(P,) round-trip path lengths [m] from 2 ``near_m`` to 2 ``near_m`` short of the
    unambiguous path c / delta f, ``step_m`` apart: a profile repeats every c / delta f, so a
    return nearer than ``near_m`` (a sheet the array stands by) shows again at the top of the
    period, where no model's return falls (on ``box_knife`` the knife 4 cm from the diagonal
    views stood there 28 dB over their strongest wall)."""
    f = measurements.acquisition.frequencies_hz
    if len(f) < 2:
        return torch.arange(2 * near_m, 2 * near_m + step_m, step_m, dtype=torch.float64)
    unambiguous = SPEED_OF_LIGHT / float(f[1] - f[0])
    return torch.arange(2 * near_m, max(unambiguous - 2 * near_m, 2 * near_m + step_m), step_m, dtype=torch.float64)


def _window(count: int) -> torch.Tensor:
    """(count,) float64 the profiles' window over frequency: Hann, or flat for two or fewer."""
    if count <= 2:
        return torch.ones(count, dtype=torch.float64)
    return torch.hann_window(count, periodic=False, dtype=torch.float64)


def data_profiles(measurements: Measurements, path_m: torch.Tensor, beams: torch.Tensor | None = None) -> torch.Tensor:
    """(V, P) power of each view's range profile at ``path_m`` (P,) [m], mean over its Tx-Rx
    pairs; with ``beams`` (V, B, T R) (:func:`view_beams`) (V, B, P), each beam's coherent
    sum over the pairs (a return at boresight stands T R times higher over the same noise)."""
    y = measurements.data.to(torch.complex128)
    f = measurements.acquisition.frequencies_hz.double()
    window = _window(len(f))
    steer = torch.exp(1j * 2 * math.pi * f[:, None] * path_m[None, :] / SPEED_OF_LIGHT)  # (K, P)
    profiles = (y * window).reshape(-1, len(f)) @ steer  # (V T R, P)
    if beams is None:  # reduced over (T, R) as ever: the fits' rounding, and so their chaotic paths, as measured
        return (profiles.abs() ** 2).reshape(*y.shape[:3], -1).mean((1, 2))
    return (beams.conj() @ profiles.reshape(y.shape[0], -1, len(path_m))).abs() ** 2


def _blur(profiles: torch.Tensor, sigma_m: float, step_m: float, *, fft: bool = False) -> torch.Tensor:
    """profiles (..., P) convolved along P with a unit-sum Gaussian of ``sigma_m`` [m path],
    zero outside the axis; with ``fft`` by FFT, the same values within 2e-15 (a beamformed
    fit's B rows a view under a wide blur made the direct convolution 5 s of a 7 s step; the
    channels' mean keeps the direct one, its fits bit for bit as measured)."""
    if sigma_m <= step_m / 4:
        return profiles
    half = int(math.ceil(4 * sigma_m / step_m))
    offsets = torch.arange(-half, half + 1, dtype=profiles.dtype) * step_m
    kernel = torch.exp(-0.5 * (offsets / sigma_m) ** 2)
    kernel = (kernel / kernel.sum()).to(profiles.device)
    if fft:
        size = 1 << (profiles.shape[-1] + 2 * half).bit_length()  # zero-padded: the circular convolution is the linear one
        spectrum = torch.fft.rfft(profiles, n=size) * torch.fft.rfft(kernel, n=size)
        return torch.fft.irfft(spectrum, n=size)[..., half:half + profiles.shape[-1]]
    rows = profiles.reshape(-1, 1, profiles.shape[-1])
    return torch.nn.functional.conv1d(rows, kernel[None, None], padding=half).reshape(profiles.shape)


def _view_frame(boresight: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(b, u, w) float64 (3,) each: the unit ``boresight`` and two unit axes across it."""
    b = torch.nn.functional.normalize(boresight.double(), dim=0)
    helper = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    if abs(float(b @ helper)) > 0.9:
        helper = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    u = torch.nn.functional.normalize(torch.linalg.cross(b, helper), dim=0)
    return b, u, torch.linalg.cross(b, u)


def _beam_directions(boresight: torch.Tensor, per_side: int, half_angle_rad: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Unit directions (per_side^2, 3) on a grid of tangent-plane angles about ``boresight``
    (3,), and each one's solid angle [sr] (the grid is uniform in tan, so dOmega ~ cos^3)."""
    b, u, w = _view_frame(boresight)
    edge = math.tan(half_angle_rad)
    s = torch.linspace(-edge, edge, per_side, dtype=torch.float64)
    a, c = torch.meshgrid(s, s, indexing="ij")
    raw = b + a.reshape(-1, 1) * u + c.reshape(-1, 1) * w
    norm = raw.norm(dim=1)
    cell = float(s[1] - s[0]) ** 2 if per_side > 1 else 1.0
    return raw / norm[:, None], cell / norm ** 3


def _virtual_positions(acq) -> torch.Tensor:
    """(V, T R, 3) float64 [m]: each channel's p_tx + p_rx less twice its view's array
    centre, the data's channel order. A far return from direction u (unit, from the centre)
    reaches channel c with the phase exp(+j k u . v_c) over the centre's (design.md's
    exp(-j k (d_tx + d_rx)); for a wall's specular return u is towards its foot point)."""
    tx, rx = acq.tx_m.double(), acq.rx_m.double()
    centre = torch.cat([tx, rx], dim=1).mean(1)
    return (tx[:, :, None] + rx[:, None]).reshape(len(tx), -1, 3) - 2 * centre[:, None]


def view_beams(acq, half_angle_rad: float) -> torch.Tensor:
    """(V, B, T R) complex128 unit-norm steering vectors of each view's beams at the centre
    frequency: directions u_b = a u + c w + sqrt(1 - a^2 - c^2) b in the view's frame,
    a and c on a grid of the virtual aperture's Rayleigh spacing lambda / extent along each
    axis (one beam across an axis the array does not extend along), up to
    sin(``half_angle_rad``) off boresight. The views' arrays must give one count of beams."""
    wavenumber = 2 * math.pi * acq.center_frequency_hz / SPEED_OF_LIGHT
    virtual = _virtual_positions(acq)
    reach = math.sin(half_angle_rad)
    beams = []
    for v in range(len(virtual)):
        b, u, w = _view_frame(acq.boresight[v])
        grids = []
        for axis in (u, w):
            extent = float((virtual[v] @ axis).max() - (virtual[v] @ axis).min())
            spacing = 2 * math.pi / (wavenumber * extent) if extent > 1e-9 else math.inf
            half = int(reach / spacing) if math.isfinite(spacing) else 0
            grids.append(torch.arange(-half, half + 1, dtype=torch.float64) * (spacing if half else 0.0))
        a, c = (g.reshape(-1) for g in torch.meshgrid(*grids, indexing="ij"))
        inside = a**2 + c**2 <= reach**2
        a, c = a[inside], c[inside]
        directions = a[:, None] * u + c[:, None] * w + torch.sqrt(1 - a**2 - c**2)[:, None] * b
        beams.append(torch.exp(1j * wavenumber * (directions @ virtual[v].T)) / math.sqrt(virtual.shape[1]))
    if len({len(beam) for beam in beams}) > 1:
        raise ValueError(f"beams: the views' arrays give {sorted({len(beam) for beam in beams})} beams; "
                         "a beamformed profile needs one count")
    return torch.stack(beams)


@dataclass(frozen=True)
class _Hits:
    """The ray grid's hits on a model (Q of them): each one's ``view``, range ``t`` [m]
    along its ray, incidence cosine ``cos``, outward ``normal`` (Q, 3), ``points`` (Q, 3)
    [m], whether its tangent plane's foot lies ``on_surface``, the two-way antenna amplitude
    ``pattern`` toward the foot (per element, squared in a channel), the share of the
    specular ``lobe`` its ray stands for, its ``reflectivity`` |Gamma(0)| (the material's,
    or a thin slab's |R|), and with transmission the ``power`` |T|^4 of the slabs its ray
    crossed before it (1 in the clear) and their two-way delay ``delay_m`` [m]."""

    view: torch.Tensor
    t: torch.Tensor
    cos: torch.Tensor
    normal: torch.Tensor
    points: torch.Tensor
    on_surface: torch.Tensor
    pattern: torch.Tensor
    lobe: torch.Tensor
    reflectivity: torch.Tensor
    power: torch.Tensor
    delay_m: torch.Tensor


def _hits(field: PrimitiveField, acq, *, rays_per_side: int, half_angle_rad: float, t_max: float,
          transmission: bool = False) -> _Hits:
    """Trace each view's ray grid (module docstring) against ``field``'s frozen SDF, on
    through dielectrics with ``transmission``."""
    views = acq.tx_m.shape[0]
    beams = [_beam_directions(acq.boresight[v], rays_per_side, half_angle_rad) for v in range(views)]
    directions = torch.cat([d for d, _ in beams])
    solid_angle = torch.cat([w for _, w in beams])
    ray_view = torch.arange(views).repeat_interleave(rays_per_side ** 2)
    origins = torch.cat([acq.tx_m, acq.rx_m], dim=1).double().mean(1)[ray_view]
    frozen = field.frozen_sdf()
    step = field.trace_step  # below 1 where f is no exact distance (the hybrid's residual)
    eps = class_permittivities(field.materials, acq.center_frequency_hz)
    resolution = range_resolution_m(acq.bandwidth_hz)  # a slab thinner (round trip) reflects as one
    frequencies = acq.frequencies_hz.double()
    band = torch.linspace(float(frequencies.min()), float(frequencies.max()), DELAY_FREQUENCIES, dtype=torch.float64)
    band_window = _window(DELAY_FREQUENCIES)
    rays = torch.arange(len(directions))
    travelled = torch.zeros(len(directions), dtype=torch.float64)  # along each ray, to where its trace starts
    factor = torch.ones(len(directions), dtype=torch.complex128)  # T of the slabs crossed so far
    delays = torch.zeros(len(directions), dtype=torch.float64)
    found: list[tuple] = []  # (rays, t, |T|, delay, reflectivity) of each round's hits
    for _ in range(MAX_CROSSINGS + 1 if transmission else 1):
        trace = sphere_trace(lambda p: step * frozen(p), origins[rays] + travelled[rays, None] * directions[rays],
                             directions[rays], eps=1e-5 * step, max_steps=int(256 / step),
                             t_max=t_max - travelled[rays])
        rays, t = rays[trace.hit], travelled[rays[trace.hit]] + trace.t[trace.hit]
        points = origins[rays] + t[:, None] * directions[rays]
        with torch.no_grad():
            probabilities = field.material(points)
            reflectivity = mixture_fresnel(torch.ones_like(t), probabilities, eps, "mean").abs()
        found.append([rays, t, factor[rays].abs(), delays[rays].clone(), reflectivity])
        if not transmission:
            break
        with torch.no_grad():
            classes = probabilities.argmax(1)
            slab = eps[classes]
            inside = torch.isfinite(slab.real).nonzero().squeeze(1)  # metal stops the ray
            if not len(inside):
                break
            d, entry = directions[rays[inside]], points[inside]
            cos = (-(torch.nn.functional.normalize(gradient(frozen, entry), dim=1) * d).sum(1)).clamp(1e-3, 1)
            leave = sphere_trace(lambda p: -step * frozen(p), entry + _STEP_IN_M * d, d, eps=1e-5 * step,
                                 max_steps=int(256 / step), t_max=t_max - t[inside])
            thickness = (leave.t + _STEP_IN_M) * cos
            r, tr = slab_coefficients(cos, slab[inside], thickness, acq.center_frequency_hz, "mean")
            thin = leave.hit & (2 * thickness * slab[inside].real.clamp(min=1).sqrt() < resolution)
            found[-1][4][inside[thin]] = r[thin].abs()  # a thin sheet reflects as its slab
            crossing = rays[inside[leave.hit]]
            factor[crossing] *= tr[leave.hit]
            crossed = classes[inside][leave.hit]
            delays[crossing] += band_delay(cos[leave.hit], lambda f: class_permittivities(field.materials, f)[crossed],
                                           thickness[leave.hit], acq.center_frequency_hz, band, band_window)
            travelled[crossing] = t[inside[leave.hit]] + leave.t[leave.hit] + 2 * _STEP_IN_M
            rays = crossing
        if not len(rays):
            break
    ray, t, transmitted, delay, reflectivity = (torch.cat(column) for column in zip(*found))
    d, view = directions[ray], ray_view[ray]
    points = origins[ray] + t[:, None] * d
    normal = torch.nn.functional.normalize(gradient(frozen, points), dim=1)
    cos = (-(normal * d).sum(1)).clamp(1e-3, 1)  # grad f . d < 0 coming from outside
    with torch.no_grad():
        foot = origins[ray] - (t * cos)[:, None] * normal  # the plane's point nearest the array
        on_surface = frozen(foot).abs() < FOOT_TOLERANCE * t * cos
        pattern = (-normal * acq.boresight.double()[view]).sum(1).clamp(min=0) ** acq.pattern_exponent
        lobe = cos ** (2 * SPECULAR_EXPONENT) * solid_angle[ray] * (2 * SPECULAR_EXPONENT + 1) / (2 * math.pi)
    return _Hits(view, t, cos.detach(), normal.detach(), points, on_surface, pattern, lobe, reflectivity,
                 transmitted ** 4, 2 * delay)


def model_profiles(field: PrimitiveField, measurements: Measurements, path_m: torch.Tensor, *, rays_per_side: int,
                   half_angle_rad: float, sigma_m: float, transmission: bool = False,
                   beams: torch.Tensor | None = None) -> torch.Tensor:
    """(V, P) the model's range-profile power at ``path_m`` (module docstring), differentiable
    in the field's free parameters through the hits' tangent-plane distances; with
    ``transmission`` rays go on through dielectrics; with ``beams`` (V, B, T R)
    (:func:`view_beams`) (V, B, P), each hit's power times |a_b^H s(u)|^2, the beam's gain
    towards its foot point (s(u) its plane wave's channel phases, :func:`_virtual_positions`)."""
    acq = measurements.acquisition
    hits = _hits(field, acq, rays_per_side=rays_per_side, half_angle_rad=half_angle_rad, t_max=float(path_m[-1]) / 2,
                 transmission=transmission)
    value = field.sdf(hits.points)  # ~0, but it moves with the parameters
    # the tangent plane's distance t cos moves by df/dtheta (implicit differentiation of f(o + t d) = 0)
    distance = hits.t * hits.cos + (value - value.detach())
    with torch.no_grad():
        weight = ((hits.reflectivity * hits.pattern ** 2 / (2 * hits.t * hits.cos)) ** 2 * hits.lobe * hits.on_surface
                  * hits.power)
    keep = weight > _NEGLIGIBLE * weight.max() if len(weight) else weight > 0
    centres, weight, view = 2 * distance[keep] + hits.delay_m[keep], weight[keep], hits.view[keep]
    views = acq.tx_m.shape[0]
    if beams is None:
        return _splat(centres, weight, view, path_m, math.hypot(sigma_m, _psf_sigma_m(measurements)), views)
    with torch.no_grad():  # the foot point lies along -normal from the array: that plane wave's phases
        wavenumber = 2 * math.pi * acq.center_frequency_hz / SPEED_OF_LIGHT
        waves = torch.exp(-1j * wavenumber * torch.einsum("qi,qci->qc", hits.normal[keep],
                                                          _virtual_positions(acq)[view]))
        gain = torch.einsum("qc,qbc->qb", waves, beams[view].conj()).abs() ** 2  # (Q, B)
        beamed = weight.detach()[:, None] * gain
        hit, beam = (beamed > _NEGLIGIBLE * beamed.max()).nonzero(as_tuple=True)  # a beam's far sidelobes dropped
    count = beams.shape[1]  # B times the rows: splatted at the point spread, then blurred
    profiles = _splat(centres[hit], weight[hit] * gain[hit, beam], view[hit] * count + beam, path_m,
                      _psf_sigma_m(measurements), views * count)
    return _blur(profiles.reshape(views, count, -1), sigma_m, float(path_m[1] - path_m[0]), fft=True)


def image_source_reflectivities(measurements: Measurements, field: PrimitiveField, *,
                                settings: ProfileSettings | None = None) -> tuple[list[float | None], str]:
    """Each free material's |Gamma(0)|, read from the data at the fitted model: for each
    view and object, the hit nearest normal incidence whose tangent plane's foot lies on the
    object is its specular point, and the data's profile peak within a range resolution of
    its path 2R, over the peak a wall of |Gamma| = 1 gives there (the image source:
    sum(Hann) g^2 / 2R, g the two-way pattern), is the object's reflectivity times the radar's
    gain; the median over the views that see it. The gain is the held objects' (their
    catalogue |Gamma(0)|) where some view sees one, else 1 for rfsdf's simulated data, else
    unknown: the reflectivities are then relative to the brightest. Returns one value per
    free material (None where no view sees it) and how the gain was set."""
    settings = settings or ProfileSettings()
    acq = measurements.acquisition
    path = path_axis(measurements, settings.step_m, settings.near_m)
    data = data_profiles(measurements, path).sqrt()
    window = _window(len(acq.frequencies_hz)).sum()  # the data profile's peak over one channel's amplitude
    resolution = SPEED_OF_LIGHT / acq.bandwidth_hz  # in path
    hits = _hits(field, acq, rays_per_side=settings.rays_per_side,
                 half_angle_rad=math.radians(settings.half_angle_deg), t_max=float(path[-1]) / 2,
                 transmission=settings.transmission)
    with torch.no_grad():
        owner = torch.stack([sdf(hits.points) for sdf in field.object_sdfs(detach=True)]).abs().argmin(0)
    ratios: dict[int, list[float]] = {}
    for v in range(acq.tx_m.shape[0]):
        for index in range(len(field.model.spec.objects)):
            mine = ((hits.view == v) & (owner == index) & hits.on_surface).nonzero().flatten()
            if not len(mine):
                continue
            best = mine[hits.cos[mine].argmax()]
            distance = float(hits.t[best] * hits.cos[best])
            gate = (path - 2 * distance - hits.delay_m[best]).abs() <= resolution
            if not gate.any():
                continue
            # the image source's peak, dimmed by the slabs on its way (|T|^2 in amplitude)
            unit = float(window * hits.pattern[best] ** 2 / (2 * distance) * hits.power[best].sqrt())
            ratios.setdefault(index, []).append(float(data[v, gate].max()) / unit)
    seen = {index: float(torch.tensor(values).median()) for index, values in ratios.items()}
    free = {m.index for m in field.model.materials}
    held = [seen[i] / float(class_reflectivities((field.model.spec.objects[i].material,),
                                                 acq.center_frequency_hz)[0])
            for i in seen if i not in free]
    if held:
        gain, how = float(torch.tensor(held).median()), "the held materials' returns"
    elif "surface_sampling" in measurements.metadata:
        gain, how = 1.0, "1 (rfsdf's simulated data are calibrated)"
    else:
        brightest = max([seen[m.index] for m in field.model.materials if m.index in seen], default=1.0)
        gain, how = brightest, RELATIVE_GAIN
    return [seen[m.index] / gain if m.index in seen else None for m in field.model.materials], how


def _splat(centres_m: torch.Tensor, weights: torch.Tensor, view: torch.Tensor, path_m: torch.Tensor, spread_m: float,
           views: int) -> torch.Tensor:
    """(views, P) sum of Gaussians of ``spread_m`` centred at ``centres_m`` (Q,) [m path] with
    ``weights`` (Q,) into the profile of ``view`` (Q,), each over +-4 spreads of the uniform
    axis ``path_m`` only (the dense (Q, P) kernel took most of a step's time)."""
    step = float(path_m[1] - path_m[0])
    half = int(math.ceil(4 * spread_m / step))
    nearest = torch.round((centres_m.detach() - float(path_m[0])) / step).long()
    index = nearest[:, None] + torch.arange(-half, half + 1)  # (Q, W)
    valid = (index >= 0) & (index < len(path_m))
    index = index.clamp(0, len(path_m) - 1)
    kernel = torch.exp(-0.5 * ((path_m[index] - centres_m[:, None]) / spread_m) ** 2) * valid
    flat = (view[:, None] * len(path_m) + index).reshape(-1)
    out = torch.zeros(views * len(path_m), dtype=torch.float64)
    return out.index_add(0, flat, (weights[:, None] * kernel).reshape(-1)).reshape(views, len(path_m))


def _psf_sigma_m(measurements: Measurements) -> float:
    """The Gaussian sigma [m path] of the Hann-windowed profile's main lobe, c / B x 1.44 / 2.355."""
    return _HANN_FWHM * SPEED_OF_LIGHT / measurements.acquisition.bandwidth_hz / (2 * math.sqrt(2 * math.log(2)))


def _amplitudes(profiles: torch.Tensor) -> torch.Tensor:
    """sqrt of (V, P) powers, each view scaled to unit norm (a floor of 1e-12 of the
    peak power keeps the square root's gradient finite where a profile is empty)."""
    floor = 1e-12 * profiles.detach().amax(dim=1, keepdim=True).clamp(min=1e-30)
    amplitude = (profiles.clamp(min=0) + floor).sqrt()
    return amplitude / amplitude.norm(dim=1, keepdim=True).clamp(min=1e-30)


def noise_floor(measurements: Measurements, profiles: torch.Tensor) -> torch.Tensor:
    """(V, 1) the noise power per bin of the data's (V, P) or (V, B, P) range ``profiles`` (a
    unit-norm beam's as a channel's): sigma^2 sum w_k^2
    where the data's noise is known (a simulation's), else each view's median bin (most of a
    profile's path is empty: on ``box_knife`` at 20 dB the median is 0.95-1.01 of the known floor)."""
    if measurements.noise_std is None or not math.isfinite(measurements.noise_std):
        return profiles.flatten(1).median(dim=1, keepdim=True).values
    window = _window(len(measurements.acquisition.frequencies_hz))
    return torch.full((len(profiles), 1), measurements.noise_std ** 2 * float((window ** 2).sum()), dtype=profiles.dtype)


def profile_loss(predicted: torch.Tensor, target: torch.Tensor, floor: torch.Tensor | None = None) -> torch.Tensor:
    """Mean over views of the squared distance between the (V, P) power profiles'
    amplitudes, each view normalised (the gain is unknown; a view's (B, P) beams as one
    profile). With the data's noise ``floor``
    (V, 1) the model's profile is g_v P_v + floor, g_v >= 0 by least squares on power (held
    for the gradient): where a view's walls stand a few dB over its noise (behind
    ``box_knife``'s glass at 20 dB), the noise fills most of the data's normalised profile and,
    left out of the model, flattened the loss (its minimum 6 and 63 cm off those walls, with
    the floor 1 cm)."""
    predicted, target = predicted.flatten(1), target.flatten(1)
    if floor is not None:
        with torch.no_grad():
            gain = ((predicted * (target - floor)).sum(1, keepdim=True).clamp(min=0)
                    / (predicted ** 2).sum(1, keepdim=True).clamp(min=torch.finfo(predicted.dtype).tiny))
        predicted = gain * predicted + floor
    return ((_amplitudes(predicted) - _amplitudes(target)) ** 2).sum(1).mean()


@dataclass(frozen=True)
class ProfileSettings:
    """How the profile fit samples: ``rays_per_side`` squared rays a view over a square of
    tangent-plane angles up to ``half_angle_deg`` off boresight, profiles ``step_m`` apart in
    path from 2 ``near_m``; the blur shrinks from ``blur_start_m`` [m path] to 0;
    ``transmission``: rays go on through dielectrics (module docstring); ``beams``: each
    view's profiles per beam of its array (:func:`view_beams`, up to ``half_angle_deg``),
    coherent over its channels, instead of their mean."""

    rays_per_side: int = 48
    half_angle_deg: float = 70.0
    step_m: float = 0.005
    near_m: float = 0.5
    blur_start_m: float = 0.4
    transmission: bool = False
    beams: bool = False


def fit_primitive_profiles(measurements: Measurements, model: SceneModel, *, steps: int = 150, lr: float = 0.01,
                           settings: ProfileSettings = ProfileSettings(), progress: bool = False) -> PrimitiveFit:
    """Fit ``model``'s free parameters to the range profiles of ``measurements`` (module
    docstring): Adam at ``lr`` [m per step, about], decaying to a tenth, for ``steps``."""
    clock = time.perf_counter()
    field = PrimitiveField(model)
    losses = fit_profiles(measurements, field, [{"params": list(field.values), "lr": lr}], steps=steps,
                          settings=settings, progress=progress) if len(field.values) else []
    return read_materials(PrimitiveFit(field, losses, time.perf_counter() - clock,
                                       measurements.acquisition.center_frequency_hz), measurements, settings)


def read_materials(fit: PrimitiveFit, measurements: Measurements, settings: ProfileSettings) -> PrimitiveFit:
    """``fit`` with its free materials read at the fitted model (:func:`image_source_reflectivities`)."""
    if not fit.field.model.materials:
        return fit
    reflectivities, calibration = image_source_reflectivities(measurements, fit.field, settings=settings)
    return dataclasses.replace(fit, reflectivities=reflectivities, calibration=calibration)


def fit_profiles(measurements: Measurements, field: PrimitiveField, groups: list[dict], *, steps: int,
                 settings: ProfileSettings = ProfileSettings(), blur: bool = True, progress: bool = False,
                 prior: Callable[[], torch.Tensor] | None = None, desc: str = "profile fit") -> list[float]:
    """Fit ``field`` (a primitive or hybrid field) to the range profiles of ``measurements``:
    Adam over the parameter ``groups`` (torch's param groups, each its ``lr``), each rate
    decaying to a tenth over ``steps``, the blur shrinking from ``settings.blur_start_m`` to 0
    (``blur``) or none; ``prior()`` is added to each step's loss. Returns the data loss per step."""
    path = path_axis(measurements, settings.step_m, settings.near_m)
    beams = view_beams(measurements.acquisition, math.radians(settings.half_angle_deg)) if settings.beams else None
    data = data_profiles(measurements, path, beams)
    floor = noise_floor(measurements, data)  # the blur's unit-sum kernel keeps it
    optimizer = torch.optim.Adam(groups)
    schedule = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda step: exponential_decay(step, steps - 1, 1.0, 0.1))
    losses = []
    for step in progress_bar(range(steps), desc=desc, enabled=progress):
        width = settings.blur_start_m * (1 - step / max(steps - 1, 1)) if blur else 0.0
        predicted = model_profiles(field, measurements, path, rays_per_side=settings.rays_per_side,
                                   half_angle_rad=math.radians(settings.half_angle_deg), sigma_m=width,
                                   transmission=settings.transmission, beams=beams)
        loss = profile_loss(predicted, _blur(data, width, settings.step_m, fft=beams is not None), floor)
        optimizer.zero_grad(set_to_none=True)
        (loss if prior is None else loss + prior()).backward()
        optimizer.step()
        schedule.step()
        field.clamp_()
        losses.append(float(loss.detach()))
    return losses
