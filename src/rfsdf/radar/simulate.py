"""Radar measurements of a scene: surface scattering through the Born model, with shadows and noise.

Each surface sample p (area dA, normal n, material eps) scatters, in view v, with
c = Gamma(theta_inc, eps(f_c)) * L * dA * visible, where theta_inc is the angle between n
and the direction to the view's Tx phase centre and the lobe L is
(1 - w_d) max(0, m.o)^n_s + w_d cos(theta_inc) (m: mirror of the incident ray, o: direction
to the Rx phase centre). Visibility is sphere-traced from p to the array's phase centre
(one ray per sample and view; the array is small next to the range).
"""

from __future__ import annotations

import numpy as np
import torch
from tqdm.auto import tqdm

from ..geometry import sphere_trace
from ..materials import fresnel
from ..scene import Scene, SurfaceSamples
from .acquisition import Acquisition, Measurements
from .operator import SensingOperator
from .system import Radar

__all__ = ["simulate", "surface_reflectivity", "view_reflectivities", "add_noise"]

_SHADOW_OFFSET = 4.0  # start shadow rays this many trace tolerances off the surface
_TRACE_EPS_M = 1e-5


def surface_reflectivity(
    scene: Scene, points: torch.Tensor, normals: torch.Tensor, area_m2: torch.Tensor, object_index: torch.Tensor,
    tx_centre: torch.Tensor, rx_centre: torch.Tensor, frequency_hz: float, *,
    specular_exponent: float = 8.0, diffuse_weight: float = 0.5, polarization: str = "mean", shadows: bool = True,
) -> torch.Tensor:
    """Complex reflectivity (Q,) of surface samples seen from one view's Tx/Rx phase centres [m]."""
    p, n = points.double(), normals.double()
    to_tx, to_rx = tx_centre.double() - p, rx_centre.double() - p
    dist_tx = to_tx.norm(dim=1)
    cos_inc = (to_tx * n).sum(1) / dist_tx
    incident = -to_tx / dist_tx[:, None]
    mirror = incident - 2 * (incident * n).sum(1, keepdim=True) * n
    cos_spec = (mirror * torch.nn.functional.normalize(to_rx, dim=1)).sum(1)
    lobe = (1 - diffuse_weight) * cos_spec.clamp(min=0) ** specular_exponent + diffuse_weight * cos_inc.clamp(min=0)
    front = (cos_inc > 0) & ((to_rx * n).sum(1) > 0)
    eps = torch.tensor([complex(o.material.permittivity(frequency_hz)) for o in scene.objects], dtype=torch.complex128)
    gamma = fresnel(torch.arccos(cos_inc.clamp(0, 1)), eps[object_index], polarization)
    visible = front.clone()
    if shadows and front.any():
        centre = 0.5 * (tx_centre + rx_centre).double()
        idx = front.nonzero().squeeze(1)
        origins = p[idx] + _SHADOW_OFFSET * _TRACE_EPS_M * n[idx]
        direction = centre - origins
        distance = direction.norm(dim=1)
        trace = sphere_trace(scene.sdf, origins, direction, eps=_TRACE_EPS_M, max_steps=256, t_max=float(distance.max()))
        visible[idx] = ~(trace.hit & (trace.t < distance))
    return (gamma * lobe * area_m2.double() * visible).to(torch.complex64)


def view_reflectivities(scene: Scene, samples: SurfaceSamples, acquisition: Acquisition, *,
                        progress: bool = False, **scattering) -> torch.Tensor:
    """(V, Q) complex64: :func:`surface_reflectivity` of the samples in each view, at the
    centre frequency, from that view's Tx and Rx phase centres; ``scattering`` as there."""
    acq = acquisition
    return torch.stack([
        surface_reflectivity(scene, samples.points, samples.normals, samples.area_m2, samples.object_index,
                             acq.tx_m[v].mean(0), acq.rx_m[v].mean(0), acq.center_frequency_hz, **scattering)
        for v in tqdm(range(acq.shape[0]), desc="scattering", disable=not progress, leave=False)
    ])


def add_noise(y: torch.Tensor, snr_db: float, generator: torch.Generator) -> tuple[torch.Tensor, float]:
    """y + circular complex Gaussian noise with mean|y|^2 / sigma^2 = 10^(snr/10); returns (y, sigma)."""
    sigma = float(torch.sqrt((y.abs() ** 2).mean() / 10 ** (snr_db / 10)))
    noise = torch.complex(torch.randn(y.shape, generator=generator), torch.randn(y.shape, generator=generator))
    return y + (sigma / np.sqrt(2)) * noise.to(y.dtype), sigma


def simulate(
    scene: Scene, radar: Radar, *, seed: int = 0, spacing_m: float | None = None, max_samples: int = 150_000,
    specular_exponent: float = 8.0, diffuse_weight: float = 0.5, polarization: str = "mean",
    shadows: bool = True, progress: bool = False,
) -> Measurements:
    """Simulated measurements of ``scene`` by ``radar`` (reproducible for a given ``seed``).

    The surface is sampled about lambda/3 apart (``spacing_m`` overrides; at most
    ``max_samples`` samples). Noise is added at ``radar.snr_db`` (None: noise-free).
    """
    acq = radar.acquisition()
    spacing = spacing_m or acq.wavelength_m / 3
    samples = scene.sample_surface(spacing, seed=seed, max_samples=max_samples)
    c = view_reflectivities(scene, samples, acq, progress=progress, specular_exponent=specular_exponent,
                            diffuse_weight=diffuse_weight, polarization=polarization, shadows=shadows)
    y = SensingOperator(acq).forward(samples.points, c, progress=progress)
    noise_std = None
    if radar.snr_db is not None:
        y, noise_std = add_noise(y, radar.snr_db, torch.Generator().manual_seed(seed + 1))
    return Measurements(acq, y, noise_std, {"scene": scene.name, "radar": radar.name,
                                            "surface_samples": str(len(samples.points))})
