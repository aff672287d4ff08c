"""The Eikonal term in one dimension: one surface point and |f'| = 1 give a distance.

A small network f: R -> R (Softplus(beta=100), as the SDF network) is fitted on [-1, 1] to
a single surface point x0 (data term f(x0)^2) plus the Eikonal term E[(|f'(x)| - 1)^2] at
random x. Every zero of f other than x0 and every kink costs Eikonal loss (a smooth
network cannot turn sharply), so the fit is driven to the kink-free solutions
f = +-(x - x0): the signed distance to x0, its sign set by the initial slope. Measured: the
learned function against |x - x0|, both loss terms against the step, and the rate at
which each term falls (slope of log10(loss) against step, from 10 % to 50 % of the steps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..viz.figures import plt, save_figure

NAME = "eikonal-1d"
SUMMARY = "a 1-D network fitted to one surface point with the Eikonal term becomes +-(x - x0)"


@dataclass(frozen=True)
class Settings:
    x0: float = 0.3
    width: int = 64
    steps: int = 2000
    batch: int = 256
    eikonal_weight: float = 1.0  # at 0.1 the seed-0 fit stalls in a two-zero local minimum
    lr: float = 3e-3
    seed: int = 0
    away_m: float = 0.1  # the tolerance is checked where |x - x0| exceeds this


QUICK = Settings(steps=800)


@dataclass(frozen=True)
class Result:
    x: list[float]
    f: list[float]
    data_loss: list[float]
    eikonal_loss: list[float]
    max_error_away: float  # max | |f(x)| - |x - x0| | where |x - x0| > away_m
    sign: int  # +1: f = x - x0, -1: f = x0 - x
    zeros: int  # sign changes of f on the evaluation grid
    data_rate_per_1000_steps: float  # change of log10(loss) per 1000 steps, steps 10 % to 50 %
    eikonal_rate_per_1000_steps: float


def _network(width: int) -> torch.nn.Module:
    return torch.nn.Sequential(torch.nn.Linear(1, width), torch.nn.Softplus(beta=100),
                               torch.nn.Linear(width, width), torch.nn.Softplus(beta=100), torch.nn.Linear(width, 1))


def _rate(losses: list[float]) -> float:
    """Slope of log10(loss) per 1000 steps over steps 10 % to 50 %: the descent, before the floor."""
    lo, hi = len(losses) // 10, len(losses) // 2
    return float(np.polyfit(np.arange(lo, hi), np.log10(np.maximum(losses[lo:hi], 1e-30)), 1)[0] * 1000)


def run(settings: Settings) -> Result:
    torch.manual_seed(settings.seed)
    net = _network(settings.width).double()
    optimizer = torch.optim.Adam(net.parameters(), lr=settings.lr)
    x0 = torch.tensor([[settings.x0]], dtype=torch.float64)
    data_losses, eikonal_losses = [], []
    for _ in range(settings.steps):
        x = (2 * torch.rand(settings.batch, 1, dtype=torch.float64) - 1).requires_grad_(True)
        (slope,) = torch.autograd.grad(net(x).sum(), x, create_graph=True)
        eikonal = ((slope.abs() - 1) ** 2).mean()
        data = net(x0).pow(2).sum()
        optimizer.zero_grad()
        (data + settings.eikonal_weight * eikonal).backward()
        optimizer.step()
        data_losses.append(data.item())
        eikonal_losses.append(eikonal.item())
    grid = torch.linspace(-1, 1, 401, dtype=torch.float64)[:, None]
    with torch.no_grad():
        f = net(grid)[:, 0].numpy()
    x = grid[:, 0].numpy()
    away = np.abs(x - settings.x0) > settings.away_m
    sign = int(np.sign(np.median(np.sign(f[away]) * np.sign(x[away] - settings.x0))))
    return Result(x.tolist(), f.tolist(), data_losses, eikonal_losses,
                  float(np.abs(np.abs(f[away]) - np.abs(x[away] - settings.x0)).max()), sign,
                  int(np.count_nonzero(np.diff(np.sign(f)) != 0)), _rate(data_losses), _rate(eikonal_losses))


def plot(result: Result, path) -> None:
    fig, (ax, losses) = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
    x = np.asarray(result.x)
    x0 = x[int(np.argmin(np.abs(result.f)))]
    ax.plot(x, result.f, "k-", label="learned f")
    ax.plot(x, result.sign * (x - x0), "--", color="tab:orange", label=f"{'+' if result.sign > 0 else '-'}(x - x0)")
    ax.axhline(0, color="grey", lw=0.5)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("f [m]")
    ax.set_title(f"max | |f| - |x - x0| | away from x0: {result.max_error_away:.1e} m")
    ax.legend()
    steps = np.arange(1, len(result.data_loss) + 1)
    losses.semilogy(steps, result.data_loss, label="data f(x0)^2 [m^2]")
    losses.semilogy(steps, result.eikonal_loss, label="Eikonal (|f'| - 1)^2 [1]")
    losses.set_xlabel("step")
    losses.set_ylabel("loss")
    losses.legend()
    save_figure(fig, path)
