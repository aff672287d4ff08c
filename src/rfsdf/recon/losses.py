"""Losses: data fidelity between predicted and observed MF images, and the Eikonal term."""

from __future__ import annotations

import torch
from torch.nn import functional as F

from ..geometry import gradient

__all__ = ["data_loss", "eikonal_loss"]

_AMPLITUDE_EPS = 1e-10  # keeps d sqrt(P)/dP finite where the predicted power is 0


def data_loss(predicted_power: torch.Tensor, observed_power: torch.Tensor, *, target: str = "amplitude",
              norm: str = "l2", huber_delta: float = 0.05, fit_scale: bool = True) -> torch.Tensor:
    """Mean misfit between MF power images (any equal shapes), on amplitude sqrt(P) or on P.

    With ``fit_scale`` the prediction is first multiplied by the least-squares scale
    <p, o> / <p, p> (held constant for the gradient): radar data have no absolute
    calibration, so the fit matches the image's shape, and shrinking every surface away
    never looks like progress.
    """
    if target == "amplitude":
        predicted, observed = torch.sqrt(predicted_power + _AMPLITUDE_EPS), torch.sqrt(observed_power)
    else:
        predicted, observed = predicted_power, observed_power
    if fit_scale:
        with torch.no_grad():
            scale = (predicted * observed).sum() / (predicted**2).sum().clamp(min=1e-20)
        predicted = predicted * scale
    if norm == "huber":
        return F.huber_loss(predicted, observed, delta=huber_delta)
    return F.mse_loss(predicted, observed)


def eikonal_loss(sdf, points: torch.Tensor) -> torch.Tensor:
    """mean((|grad f| - 1)^2) at ``points`` (N, 3), differentiable (create_graph=True)."""
    grad = gradient(sdf, points, create_graph=True)
    return ((grad.norm(dim=1) - 1.0) ** 2).mean()
