"""Losses: data fidelity between predicted and observed MF images, and the Eikonal term.

Data losses take the predicted complex per-view images (v, X) and the observed amplitudes
(v, X) at the same voxels, and are registered by name in ``DATA_LOSSES``. Radar data carry
no absolute calibration, so every data loss first scales the prediction by the least-squares
gain (held constant for the gradient, one gain for all views of the step: relative
brightness between views is physics, not calibration), and is normalised by the observed
energy, so 0 is a perfect fit and 1 is a prediction orthogonal to the data.
"""

from __future__ import annotations

import torch

from ..geometry import gradient
from ..registry import Registry

__all__ = ["DATA_LOSSES", "amplitude_loss", "power_loss", "eikonal_loss", "eikonal_penalty"]

DATA_LOSSES: Registry = Registry("data loss")


def _gain_fitted_misfit(predicted: torch.Tensor, observed: torch.Tensor) -> torch.Tensor:
    """sum((g p - o)^2) / sum(o^2) with the least-squares gain g = <p, o> / <p, p>, detached."""
    with torch.no_grad():
        gain = (predicted * observed).sum() / (predicted * predicted).sum().clamp(min=torch.finfo(predicted.dtype).tiny)
    return ((gain * predicted - observed) ** 2).sum() / (observed**2).sum().clamp(min=torch.finfo(observed.dtype).tiny)


@DATA_LOSSES.register("amplitude")
def amplitude_loss(predicted: torch.Tensor, observed_amplitude: torch.Tensor) -> torch.Tensor:
    """Misfit of MF *amplitudes* |c_hat|: where the glints are and how bright, not the
    carrier phase of each (an absolute phase is not a geometric fact worth fitting).
    Equals 1 - cos^2 between the amplitude images."""
    return _gain_fitted_misfit(predicted.abs(), observed_amplitude)


@DATA_LOSSES.register("power")
def power_loss(predicted: torch.Tensor, observed_amplitude: torch.Tensor) -> torch.Tensor:
    """Misfit of MF power |c_hat|^2: weights the brightest glints more than ``amplitude``."""
    return _gain_fitted_misfit(predicted.abs() ** 2, observed_amplitude**2)


def eikonal_loss(sdf, points: torch.Tensor) -> torch.Tensor:
    """mean((|grad f| - 1)^2) at ``points`` (N, 3), differentiable (create_graph=True)."""
    return eikonal_penalty(gradient(sdf, points, create_graph=True))


def eikonal_penalty(grad: torch.Tensor) -> torch.Tensor:
    """mean((|grad| - 1)^2) of gradients (N, 3) already taken (for a caller that uses them twice)."""
    return ((grad.norm(dim=1) - 1.0) ** 2).mean()
