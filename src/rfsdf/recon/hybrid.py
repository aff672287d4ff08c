"""The hybrid scene model: a primitive model plus a small neural residual of bounded amplitude.

f(x) = f_model(x; theta) + a tanh(r(x; w)): ``f_model`` is the scene model's analytic SDF
(:class:`~rfsdf.recon.primitive.PrimitiveField`, its free parameters theta), r a small MLP
on sinusoidal features of x with wavelengths from the box's size down to ``shortest_m``,
its last layer zero at the start, so the fit begins at the primitive model. The amplitude
a is a few range resolutions at most: the residual moves the model's surfaces by up to a
and can add a surface only within a of one (a board on a wall, a radiator, a bulge the
primitives lack), never structure far from them. Its slope is a |grad r| <= a 2 pi /
shortest_m times the network's gain, so f is no exact distance: sphere tracing takes
``TRACE_STEP`` of f per step (safe while |grad f| <= 1 / TRACE_STEP).
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch
import trimesh

from ..radar import Measurements
from ..radar.waveform import range_resolution_m
from ..scene_model import SceneModel
from .primitive import PrimitiveField, PrimitiveFit
from .range_profile import ProfileSettings, fit_profiles, read_materials

__all__ = ["HybridField", "TRACE_STEP", "RANGE_RESOLUTIONS", "residual_amplitude_m", "fit_hybrid_profiles",
           "project_mesh"]

TRACE_STEP = 0.5
RANGE_RESOLUTIONS = 2.0  # the residual's default amplitude, in range resolutions c / 2B
PRIOR_WEIGHT = 1.0  # of the residual's prior against the profile loss (fit_hybrid_profiles; docs/guide/rooms.md)


def residual_amplitude_m(bandwidth_hz: float, range_resolutions: float = RANGE_RESOLUTIONS) -> float:
    """The residual's amplitude [m]: ``range_resolutions`` times c / 2B."""
    return range_resolutions * range_resolution_m(bandwidth_hz)


class HybridField(PrimitiveField):
    """A scene model's SDF plus ``amplitude_m`` tanh(MLP(features(x))) (module docstring).

    ``lower_m``, ``upper_m`` (3,) the box the features are scaled to [m]; ``shortest_m`` the
    shortest feature wavelength [m]; ``width`` the MLP's hidden width (two hidden layers)."""

    def __init__(self, model: SceneModel, amplitude_m: float, lower_m, upper_m, *, shortest_m: float = 0.25,
                 width: int = 64, seed: int = 0):
        super().__init__(model)
        if not amplitude_m > 0:
            raise ValueError(f"the residual's amplitude must be positive, not {amplitude_m} m")
        self.amplitude_m = float(amplitude_m)
        lower, upper = np.asarray(lower_m, dtype=float), np.asarray(upper_m, dtype=float)
        longest = float((upper - lower).max())
        octaves = max(1, int(math.ceil(math.log2(longest / shortest_m))) + 1)
        self.register_buffer("centre", torch.tensor((lower + upper) / 2, dtype=torch.float64))
        # angular wavenumbers 2 pi / lambda, lambda = longest, longest / 2, ... down to shortest_m
        self.register_buffer("wavenumbers", 2 * math.pi / (longest / 2.0 ** torch.arange(octaves, dtype=torch.float64)))
        generator = torch.Generator().manual_seed(seed)
        layers, inputs = [], 3 * 2 * octaves
        for _ in range(2):
            layers += [torch.nn.Linear(inputs, width, dtype=torch.float64), torch.nn.Softplus(beta=10)]
            inputs = width
        last = torch.nn.Linear(width, 1, dtype=torch.float64)
        with torch.no_grad():
            for layer in layers[::2]:
                layer.weight.copy_(torch.randn(layer.weight.shape, generator=generator) / math.sqrt(layer.in_features))
                layer.bias.zero_()
            last.weight.zero_()
            last.bias.zero_()
        self.network = torch.nn.Sequential(*layers, last)
        self.residual_on = True  # off: the primitive model alone (its fit's first phase, at its cost)

    @property
    def trace_step(self) -> float:
        """The share of f sphere tracing steps by (module docstring)."""
        return TRACE_STEP if self.residual_on else 1.0

    def residual(self, points: torch.Tensor) -> torch.Tensor:
        """(N,) a tanh(r(x)) [m] at points (N, 3) [m]: |residual| < amplitude_m everywhere."""
        if not self.residual_on:
            return torch.zeros(len(points), dtype=points.dtype, device=points.device)
        phase = (points.double() - self.centre)[:, :, None] * self.wavenumbers  # (N, 3, octaves)
        features = torch.cat([phase.sin(), phase.cos()], dim=2).flatten(1)
        return (self.amplitude_m * torch.tanh(self.network(features)[:, 0])).to(points.dtype)

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        """f_model + residual (N,) [m] at points (N, 3), differentiable in both."""
        return super().sdf(points) + self.residual(points)

    def frozen_sdf(self):
        """The SDF at the current values (the model's detached; its callers use it without
        a graph or through :func:`~rfsdf.geometry.differential.gradient`, which detaches):
        points (N, 3) -> (N,) [m]."""
        model = super().frozen_sdf()
        return lambda points: model(points) + self.residual(points)

    def residual_parameters(self) -> list[torch.nn.Parameter]:
        """The network's weights (the primitive parameters are :attr:`values`)."""
        return list(self.network.parameters())


def fit_hybrid_profiles(measurements: Measurements, model: SceneModel, *, amplitude_m: float, lower_m, upper_m,
                        steps: int = 150, residual_steps: int = 100, joint: bool = False, lr: float = 0.01,
                        residual_lr: float = 3e-3, prior_weight: float = PRIOR_WEIGHT,
                        settings: ProfileSettings = ProfileSettings(), seed: int = 0,
                        progress: bool = False) -> PrimitiveFit:
    """Fit a :class:`HybridField` of ``model`` to the range profiles of ``measurements``:
    the primitive parameters for ``steps`` (coarse to fine over range), then the residual for
    ``residual_steps`` at full resolution with the primitives held (``joint``: both together
    for ``steps``, then the residual alone). The residual's prior, ``prior_weight`` times the
    mean of (residual / amplitude)^2 at 4096 random points of the box a step, keeps it at zero
    wherever the data do not ask for it (it is one smooth function of the whole room: without
    it, a change made for one view's peak moves surfaces no view sees)."""
    clock = time.perf_counter()
    field = HybridField(model, amplitude_m, lower_m, upper_m)
    primitives = {"params": list(field.values), "lr": lr}
    residual = {"params": field.residual_parameters(), "lr": residual_lr}
    generator = torch.Generator().manual_seed(seed)
    lower = torch.as_tensor(np.asarray(lower_m, dtype=float))
    size = torch.as_tensor(np.asarray(upper_m, dtype=float)) - lower

    def prior() -> torch.Tensor:
        points = lower + size * torch.rand(4096, 3, dtype=torch.float64, generator=generator)
        return prior_weight * (field.residual(points) / amplitude_m).pow(2).mean()

    field.residual_on = joint  # zero at the start anyway: the primitives alone, at their cost
    losses = fit_profiles(measurements, field, [primitives, residual] if joint else [primitives], steps=steps,
                          settings=settings, progress=progress, prior=prior if joint else None,
                          desc="hybrid fit: primitives")
    field.residual_on = True
    losses += fit_profiles(measurements, field, [residual], steps=residual_steps, settings=settings, blur=False,
                           progress=progress, prior=prior, desc="hybrid fit: residual")
    return read_materials(PrimitiveFit(field, losses, time.perf_counter() - clock,
                                       measurements.acquisition.center_frequency_hz), measurements, settings)


def project_mesh(sdf, mesh: trimesh.Trimesh, steps: int = 4, chunk: int = 1 << 16) -> trimesh.Trimesh:
    """``mesh`` (the fitted primitive scene's, watertight) with each vertex moved along its
    normal n onto the zero set of ``sdf`` (a hybrid field's: points (N, 3) -> (N,) [m]):
    s <- s - f(v + s n), which converges where the slope of f along n is near 1 (the
    primitives' exact distance, plus a residual of small slope). The faces stay as they were,
    so the mesh keeps the primitives' topology (a thin pane stays a pane, which a grid would
    lose), and the residual moves each surface by less than its amplitude."""
    vertices = torch.as_tensor(mesh.vertices, dtype=torch.float64)
    normals = torch.tensor(np.array(mesh.vertex_normals), dtype=torch.float64)
    moved = []
    with torch.no_grad():
        for v, n in zip(vertices.split(chunk), normals.split(chunk)):
            shift = torch.zeros(len(v), dtype=torch.float64)
            for _ in range(steps):
                shift = shift - sdf(v + shift[:, None] * n).double()
            moved.append(v + shift[:, None] * n)
    return trimesh.Trimesh(torch.cat(moved).numpy(), mesh.faces.copy(), process=False)
