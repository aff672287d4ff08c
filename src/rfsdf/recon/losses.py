"""Losses: data fidelity between predicted and observed MF images, and the Eikonal term.

Data losses take the predicted complex per-view images (v, X) and the observed images (v, X)
at the same voxels (complex, or amplitudes where only amplitudes are compared), and are
registered by name in ``DATA_LOSSES``. Radar data carry no absolute calibration unless the
radar gain is known, so a data loss first scales the prediction by the least-squares gain
(held constant for the gradient, one gain for all views of the step: relative brightness
between views is physics, not calibration), and is normalised by the observed energy, so 0
is a perfect fit and 1 is a prediction orthogonal to the data. With a known gain
(``fit_gain=False``) the prediction is compared as it is; ``per_voxel=True``: each voxel's
share of the loss (X,), to say where the misfit lies. A loss that compares phases
(``uses_phase``) is compared voxel by voxel, never pooled over cells (``recon/sampling.py``).

Amplitude locates a glint to a fraction of the range resolution c / 2B (37.5 mm at 4 GHz);
the carrier phase locates it to a fraction of lambda / 2 (1.9 mm at 79 GHz) but repeats
every lambda / 2, so a fit reaches it by continuation (``LossConfig.stages``): amplitude
while the surface is more than about lambda / 4 off, then phase.
"""

from __future__ import annotations

import torch

from ..geometry import gradient
from ..registry import Registry

__all__ = ["DATA_LOSSES", "amplitude_loss", "power_loss", "complex_loss", "split_spectrum_loss", "bands_of",
           "uses_phase", "peak_offset", "peak_match_loss", "material_entropy",
           "material_cross_entropy", "eikonal_loss", "eikonal_penalty", "normal_variation", "BENDING_STEP_M"]

DATA_LOSSES: Registry = Registry("data loss")
BENDING_STEP_M = 0.003  # normal_variation's offset [m] unless told (LossConfig.bending_step_m)


def _relative(squared_residual: torch.Tensor, squared_observed: torch.Tensor, per_voxel: bool) -> torch.Tensor:
    """sum(residual^2) / sum(observed^2) over (v, X), or ``per_voxel`` each voxel's share (X,)
    of it (summed over the views), whose sum is the loss: where the misfit lies."""
    numerator = squared_residual.sum(0) if per_voxel else squared_residual.sum()
    return numerator / squared_observed.sum().clamp(min=torch.finfo(squared_observed.dtype).tiny)


def _misfit(predicted: torch.Tensor, observed: torch.Tensor, fit_gain: bool, per_voxel: bool) -> torch.Tensor:
    """sum((g p - o)^2) / sum(o^2) with the least-squares gain g = <p, o> / <p, p>, detached
    (``fit_gain``), or g = 1 where the prediction is already in the data's units."""
    gain = 1.0
    if fit_gain:
        with torch.no_grad():
            gain = (predicted * observed).sum() / (predicted * predicted).sum().clamp(min=torch.finfo(predicted.dtype).tiny)
    return _relative((gain * predicted - observed) ** 2, observed**2, per_voxel)


@DATA_LOSSES.register("amplitude")
def amplitude_loss(predicted: torch.Tensor, observed: torch.Tensor, *, fit_gain: bool = True,
                   per_voxel: bool = False) -> torch.Tensor:
    """Misfit of MF *amplitudes* |c_hat|: where the glints are and how bright, not the
    carrier phase of each (an absolute phase is not a geometric fact worth fitting).
    With the fitted gain it equals 1 - cos^2 between the amplitude images; ``fit_gain=False``
    when the radar gain is known (the prediction is in the data's units), so that absolute
    brightness, and with it each material's |Gamma|, is data too."""
    return _misfit(predicted.abs(), observed.abs(), fit_gain, per_voxel)


@DATA_LOSSES.register("power")
def power_loss(predicted: torch.Tensor, observed: torch.Tensor, *, fit_gain: bool = True,
               per_voxel: bool = False) -> torch.Tensor:
    """Misfit of MF power |c_hat|^2: weights the brightest glints more than ``amplitude``."""
    return _misfit(predicted.abs() ** 2, observed.abs() ** 2, fit_gain, per_voxel)


@DATA_LOSSES.register("complex")
def complex_loss(predicted: torch.Tensor, observed: torch.Tensor, *, fit_gain: bool = True,
                 per_voxel: bool = False) -> torch.Tensor:
    """Misfit of the complex MF images (v, X): sum |g e^{j phi_v} p - o|^2 / sum |o|^2, each
    view's prediction turned by the phase phi_v = arg <p_v, o_v> that best aligns it with the
    data (an unknown absolute phase per view, a range offset of the radar's: not a geometric
    fact to fit) and scaled by one gain g = sum_v |<p_v, o_v>| / sum |p|^2 for all views (1
    with ``fit_gain=False``), both in closed form and held for the gradient (at the optimum
    the loss does not change with them). It sees the carrier phase of every glint relative
    to the others: a smooth 0.25 mm error of the demo's surface raises it as much as a 1 mm
    error raises the amplitude loss; beyond about lambda / 4 its gradient points a cycle the
    wrong way (study ``basin``)."""
    with torch.no_grad():
        tiny = torch.finfo(predicted.real.dtype).tiny
        inner = (predicted.conj() * observed).sum(1)  # (v,)
        turn = inner / inner.abs().clamp(min=tiny)
        gain = inner.abs().sum() / (predicted.abs() ** 2).sum().clamp(min=tiny) if fit_gain else 1.0
    return _relative((gain * turn[:, None] * predicted - observed).abs() ** 2, observed.abs() ** 2, per_voxel)


complex_loss.uses_phase = True


@DATA_LOSSES.register("split")
def split_spectrum_loss(predicted: torch.Tensor, observed: torch.Tensor, *, fit_gain: bool = True,
                        per_voxel: bool = False) -> torch.Tensor:
    """Misfit of the split-spectrum interferograms of (v, 2, X) complex images of the lower and
    upper half of the band: I_lo conj(I_hi) at each voxel, whose phase is the synthetic
    wavenumber 2 (k_hi - k_lo) times the glints' range from the voxel (the carrier's own
    phase cancels), so it sees position linearly, where the amplitude is flat at its peak,
    with no cycle to skip within c / (4 Delta f_c) (18.7 mm for the demo's two 2 GHz halves;
    the carrier's lambda / 4 is 0.95 mm). Compared as sum |g p - o|^2 / sum |o|^2 with one
    real gain g >= 0 for all views in closed form (held for the gradient; 1 with
    ``fit_gain=False``): a phase fitted per view would absorb a range offset, the very thing
    this loss is for. An interferogram scales as power, so bright glints weigh more."""
    p, o = predicted[:, 0] * predicted[:, 1].conj(), observed[:, 0] * observed[:, 1].conj()
    tiny = torch.finfo(p.real.dtype).tiny
    gain = 1.0
    if fit_gain:
        with torch.no_grad():
            gain = (p.conj() * o).sum().real.clamp(min=0) / (p.abs() ** 2).sum().clamp(min=tiny)
    return _relative((gain * p - o).abs() ** 2, o.abs() ** 2, per_voxel)


split_spectrum_loss.uses_phase = True
split_spectrum_loss.bands = 2


def bands_of(loss) -> int:
    """How many sub-band images a data loss compares (1: the full band's image)."""
    return getattr(loss, "bands", 1)


def uses_phase(loss) -> bool:
    """Whether a data loss compares phases (complex images voxel by voxel, never pooled)."""
    return getattr(loss, "uses_phase", False)


def peak_offset(power: torch.Tensor, offsets_m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Where each line's range peak lies: the vertex of the least-squares parabola through
    ``power`` (N, S), |image|^2 sampled at ``offsets_m`` (S,) [m] along the line, each line
    scaled to its largest sample first (so the estimate does not see brightness). Returns
    the vertices (N,) [m], clamped to the samples' span, and whether each line has a peak
    there (N,) bool: a parabola opening downwards whose vertex lies within the span.
    Differentiable in ``power``; linear in a shift of a peak that is wide against the span
    (a range peak, c / 2B, against a few millimetres)."""
    t = offsets_m.to(power.dtype) - offsets_m.mean()
    g = power / power.detach().amax(1, keepdim=True).clamp(min=torch.finfo(power.dtype).tiny)
    basis = torch.stack([torch.ones_like(t), t, t * t], dim=1)  # (S, 3)
    a, b, c = (torch.linalg.pinv(basis) @ g.T).unbind(0)  # each (N,)
    span = float(t.abs().max())
    concave = c < 0
    vertex = -b / (2 * torch.where(concave, c, -torch.ones_like(c)))
    valid = concave & (vertex.detach().abs() < span)
    return vertex.clamp(-span, span) + offsets_m.mean(), valid


def peak_match_loss(predicted: torch.Tensor, observed: torch.Tensor, offsets_m: torch.Tensor,
                    weights: torch.Tensor, scale_m: float) -> torch.Tensor:
    """How far the predicted images' range peaks lie from the data's along the same lines:
    the weighted mean of sqrt(1 + (d / scale_m)^2) - 1 over lines (N,) where both peak
    (``peak_offset``), d the difference of their vertices [m], from the complex images
    ``predicted`` and ``observed`` (N, S) at ``offsets_m`` (S,) along each line.

    Traveltime against waveform, as full-waveform inversion reaches for it: a peak's shift
    is linear in the surface's range error over a range cell, with no carrier cycle to skip,
    and whatever moves a peak off the surface (a glint's lateral sidelobes, a face's tilt)
    moves the predicted peak as it moves the observed one, so the difference is 0 at the
    truth, where holding the zero set through the data's peaks (``LossConfig.peak_weight``)
    keeps their bias (about +1 mm outward on the demo)."""
    p, p_valid = peak_offset(predicted.abs() ** 2, offsets_m)
    o, o_valid = peak_offset(observed.abs() ** 2, offsets_m)
    w = weights * (p_valid & o_valid).to(weights.dtype)
    residual = torch.sqrt(1 + ((p - o.detach()) / scale_m) ** 2) - 1
    return (w * residual).sum() / w.sum().clamp(min=torch.finfo(w.dtype).tiny)


def material_entropy(probabilities: torch.Tensor, weights: torch.Tensor | None = None) -> torch.Tensor:
    """Weighted mean over points of -sum_k p_k log p_k [nats] of (Q, K) class probabilities
    (``weights`` (Q,), e.g. sample areas; None: equal): 0 when every point is decided,
    log K when every class is equally likely. Minimising it favours decisive classes."""
    entropy = -(probabilities * torch.log(probabilities.clamp(min=1e-12))).sum(1)
    return entropy.mean() if weights is None else (weights * entropy).sum() / weights.sum().clamp(min=1e-30)


def material_cross_entropy(probabilities: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """Mean -log p_label over the points (Q, K) whose label (Q,) int64 is a class index;
    points labelled -1 (unknown) are left out (0 when none is labelled)."""
    known = labels >= 0
    if not bool(known.any()):
        return probabilities.sum() * 0.0
    return -torch.log(probabilities[known].gather(1, labels[known, None]).clamp(min=1e-12)).mean()


def eikonal_loss(sdf, points: torch.Tensor) -> torch.Tensor:
    """mean((|grad f| - 1)^2) at ``points`` (N, 3), differentiable (create_graph=True)."""
    return eikonal_penalty(gradient(sdf, points, create_graph=True))


def eikonal_penalty(grad: torch.Tensor) -> torch.Tensor:
    """mean((|grad| - 1)^2) of gradients (N, 3) already taken (for a caller that uses them twice)."""
    return ((grad.norm(dim=1) - 1.0) ** 2).mean()


def normal_variation(sdf, points: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """mean |n(p + o) - n(p)|^2 of the unit normals n = grad f / |grad f| at ``points`` p (N, 3)
    [m] and at them moved by ``offsets`` o (N, 3) [m], differentiable: 0 where the level sets
    are planes over |o|, about (|o| kappa)^2 where they bend by kappa along o. Squared, so a
    ripple of curvature kappa_r costs (kappa_r / kappa)^2 times what a smooth curve of kappa
    does (a sphere's 1 / R): a bending energy, the prior that fits a surface through noisy
    points by smoothing rather than interpolating them."""
    normals = torch.nn.functional.normalize(gradient(sdf, torch.cat([points, points + offsets]), create_graph=True),
                                            dim=1)
    here, there = normals.chunk(2)
    return ((there - here) ** 2).sum(1).mean()
