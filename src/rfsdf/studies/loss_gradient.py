"""The data loss's gradient in the network's parameters: autograd against finite differences.

The chain the fit differentiates, for surface samples p0 frozen between refreshes (their
anchors, frozen gradient g0 and area dA, ``recon/surface.py``):

    p*     = p0 - f_theta(p0) g0 / |g0|^2            (one Newton step onto f = 0)
    n      = grad f_theta(p0) / |grad f_theta(p0)|   (the normal, turning with theta)
    c_v    = Gamma_theta(p0) * lobe(p*, n; Tx_v, Rx_v) * dA       (``radar.scattering.scatter``)
    y_v    = A_v(p*) c_v                              (the sensing operator, its positions too)
    c^_v   = A_v^H y_v / ||A_v||^2 at data voxels    (the matched filter)
    L      = 1 - cos^2(|c^|, |c^_obs|)               (``amplitude_loss``, gain fitted)

so dL/dtheta = sum dL/dp* . dp*/dtheta + dL/dn . dn/dtheta + dL/dGamma . dGamma/dtheta with dp*/dtheta =
-g0/|g0|^2 df/dtheta (the normal velocity of the level set) and the operator's hand-written
position gradient inside dL/dp*. Measured: for every parameter tensor of a small RadarField
(float64) rendered by the coherent renderer on the tests' toy radar looking at a 2 cm
metal ball, the directional derivative along a random unit direction by autograd against
central finite differences, and their relative difference.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..field import RadarField
from ..geometry import Grid
from ..radar import Radar, simulate
from ..radar.system import RadarSpec
from ..recon import CoherentRenderer, amplitude_loss
from ..scene import load_scene
from ..viz.figures import plt, save_figure

NAME = "loss-gradient"
SUMMARY = "autograd's gradient of the data loss in every layer against central finite differences"

_TOY_RADAR = {"name": "toy", "waveform": {"kind": "ofdm", "carrier_hz": 79e9, "bandwidth_hz": 4e9, "subcarriers": 8},
              "array": {"kind": "boundary", "size_m": 0.04, "elements_per_edge": 3},
              "views": {"distance_m": 0.3, "azimuths_per_ring": [4, 1, 1], "elevations_rad": [0.0, 1.4, -1.4]},
              "noise": {"snr_db": 40.0}}


@dataclass(frozen=True)
class Settings:
    voxels: int = 10  # per edge of the 12 cm box
    width: int = 32
    depth: int = 4
    step: float = 1e-6  # finite-difference step along the unit direction [parameter units]
    seed: int = 0


QUICK = Settings(voxels=6, width=16)


@dataclass(frozen=True)
class Result:
    layers: list[str]
    autograd: list[float]  # directional derivatives
    finite_difference: list[float]
    relative_error: list[float]
    loss: float


def run(settings: Settings) -> Result:
    torch.manual_seed(settings.seed)
    scene = load_scene("sphere")
    radar = Radar.from_spec(RadarSpec.model_validate(_TOY_RADAR))
    data = simulate(scene, radar, seed=settings.seed, spacing_m=radar.acquisition().wavelength_m / 6)
    grid = Grid(scene.lower_m, scene.upper_m, (settings.voxels,) * 3)
    renderer = CoherentRenderer(data, grid, spacing_m=0.006, dtype=torch.float64)
    field = RadarField(scene.lower_m, scene.upper_m, levels=2, depth=settings.depth, width=settings.width,
                       init_radius_m=0.022).double()
    renderer.refresh(field.sdf, torch.Generator().manual_seed(settings.seed))
    views, voxels = torch.arange(renderer.num_views), torch.arange(renderer.voxels.shape[0])
    observed = renderer.observed.abs()

    def loss() -> torch.Tensor:
        return amplitude_loss(renderer(field, views, voxels), observed)

    value = loss()
    field.zero_grad()
    value.backward()
    names, analytic, numeric = [], [], []
    generator = torch.Generator().manual_seed(settings.seed)
    for name, parameter in field.named_parameters():
        direction = torch.randn(parameter.shape, generator=generator, dtype=parameter.dtype)
        direction /= direction.norm()
        with torch.no_grad():
            parameter += settings.step * direction
            up = float(loss())
            parameter -= 2 * settings.step * direction
            down = float(loss())
            parameter += settings.step * direction
        names.append(name)
        analytic.append(float((parameter.grad * direction).sum()))
        numeric.append((up - down) / (2 * settings.step))
    errors = [abs(a - n) / max(abs(a), abs(n), 1e-12) for a, n in zip(analytic, numeric)]
    return Result(names, analytic, numeric, errors, value.detach().item())


def plot(result: Result, path) -> None:
    fig, ax = plt.subplots(figsize=(max(6.0, 0.45 * len(result.layers) + 2), 4.2), layout="constrained")
    ax.semilogy(range(len(result.layers)), [max(e, 1e-16) for e in result.relative_error], "o")
    ax.set_xticks(range(len(result.layers)), result.layers, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("|autograd - finite difference| / |derivative| [1]")
    ax.set_title(f"directional derivative of the data loss ({result.loss:.3f}) per parameter tensor")
    save_figure(fig, path)
