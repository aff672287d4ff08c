"""The neural model at room scale: the GeRaF geometry network fitted to each view's range profile.

At room scale the network cannot start where GeRaF's does. A few-centimetre array's image
of a room resolves range, not cross-range (lambda R / D is about 1 m at 3 m for room-60g's
1.3 cm aperture), so there is no image to warm start from, and the image-domain fit would
need the room on a grid of the radar's resolution. So the neural model starts where the
primitive and hybrid models start and is fitted to what they are fitted to:

1. **Distillation**: the SDF network (:class:`~rfsdf.field.RadarField`'s, no geometric
   initialisation: a room is inside out, its air outside every surface) regresses the start
   scene model's SDF by L1 on points within ``near_m`` of its surface (most of each batch:
   a room is mostly empty) and across the box, and its gradient by ``gradient_weight`` times
   |grad f - grad f_start| on a quarter of the batch near the surface (Sobolev training):
   the renderer's votes read normals, and on values alone a short distillation's normals
   err (a wall's, 40 deg at the median after 400 steps; 4 deg with the term; 2 deg after
   2000 steps without it). Off by default: on l-room, at 2000 steps, it lowered the start's
   profile loss but the fit ended worse and two minutes later (docs/guide/rooms.md).
2. **Profile fit**: the network's weights by Adam through the same ray-vote renderer and
   coarse-to-fine profile loss as the scene models (:func:`~rfsdf.recon.range_profile.fit_profiles`),
   with an Eikonal term at points within ``near_m`` of the start surface (the network is
   no exact distance: sphere tracing steps by ``TRACE_STEP`` of f).

The positional encoding's finest half-period is the radar's range resolution c / 2B
(:func:`~rfsdf.field.encoding.levels_for`): finer detail than that the profiles cannot ask
for. The materials are the start model's, held, by the nearest start object: the renderer's
votes weigh each hit by them, and each view's profile is normalised, so only their ratios
matter.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import torch
import trimesh

from ..field import RadarField
from ..field.encoding import levels_for
from ..geometry.differential import gradient
from ..mesh import extract_mesh_near_surface
from ..progress import progress_bar
from ..radar import Measurements
from ..radar.waveform import range_resolution_m
from ..scene import Scene
from ..scene_model import SceneModel
from .losses import eikonal_loss
from .primitive import PrimitiveField
from .range_profile import ProfileSettings, fit_profiles
from .schedules import exponential_decay

__all__ = ["TRACE_STEP", "NeuralProfileSettings", "NeuralProfileField", "NeuralProfileFit", "NeuralModel",
           "distil_start", "fit_neural_profiles", "fit_neural_model"]

TRACE_STEP = 0.5  # sphere tracing's share of f per step: the network's |grad f| is only near 1
NEAR_POINTS = 200_000  # points of the start's surface the samples near it are drawn about


@dataclass(frozen=True)
class NeuralProfileSettings:
    """The network (``width``, ``depth``), its distillation (``distil_steps`` of ``batch``
    points at ``distil_lr``, ``near_share`` of them within ``near_m`` of the start surface,
    the gradient's misfit weighted by ``gradient_weight``)
    and its profile fit (``steps`` at ``lr``, decaying to a tenth; ``eikonal_weight`` on
    ``batch`` / 4 points within ``near_m`` of the start surface each step)."""

    width: int = 64
    depth: int = 4
    distil_steps: int = 2000
    gradient_weight: float = 0.0
    distil_lr: float = 3e-3
    batch: int = 8192
    near_share: float = 0.7
    near_m: float = 0.1
    steps: int = 150
    lr: float = 5e-5
    eikonal_weight: float = 0.1


class NeuralProfileField(torch.nn.Module):
    """The geometry network as the profile renderer sees a scene model: ``sdf`` (float64 in
    and out [m]), ``frozen_sdf``, ``trace_step``, ``materials`` and ``material`` (the start
    model's, held) and a ``clamp_`` that has no bounds to keep."""

    trace_step = TRACE_STEP

    def __init__(self, start: SceneModel, lower_m, upper_m, bandwidth_hz: float, *, width: int = 64, depth: int = 4,
                 seed: int = 0):
        super().__init__()
        longest = max(float(u) - float(lo) for lo, u in zip(lower_m, upper_m))
        with torch.random.fork_rng(devices=[]):  # initial weights from ``seed``; the caller's stream untouched
            torch.manual_seed(seed)
            self.network = RadarField(lower_m, upper_m, levels=levels_for(longest, range_resolution_m(bandwidth_hz)),
                                      depth=depth, width=width, geometric_init=False)
        self.start = PrimitiveField(start)
        self.materials = self.start.materials
        self.near_points = _near_points(start, NEAR_POINTS, seed)  # (NEAR_POINTS, 3) on the start's surface [m]
        self.distil_residual_m = float("nan")  # the distillation's last L1 [m] (distil_start)

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        """f (N,) [m] at points (N, 3) [m], differentiable in the network's weights."""
        return self.network.sdf(points.float()).to(points.dtype)

    def frozen_sdf(self):
        """The SDF without a graph to the weights (sphere tracing runs it under no_grad;
        :func:`~rfsdf.geometry.differential.gradient` detaches): points (N, 3) -> (N,) [m]."""
        return self.sdf

    def material(self, points: torch.Tensor) -> torch.Tensor:
        """(N, K) the start model's class probabilities of the object nearest each point."""
        return self.start.material(points)

    def clamp_(self) -> None:
        """No bounds: every weight is free."""

    def geometry_parameters(self) -> list[torch.nn.Parameter]:
        """The SDF network's weights (the field's reflectivity network is not used here)."""
        return list(self.network.geometry.parameters())


@dataclass(frozen=True)
class NeuralProfileFit:
    """A :class:`NeuralProfileField` fitted to range profiles: the data loss per step and
    the fit's seconds."""

    field: NeuralProfileField
    losses: list[float]
    seconds: float


def _near_points(start: SceneModel, count: int, seed: int) -> torch.Tensor:
    """(count, 3) float32 points on the start model's surface [m] (area-uniform, seeded)."""
    mesh = Scene(start.spec, start.base_dir).ground_truth_mesh()
    return torch.as_tensor(trimesh.sample.sample_surface(mesh, count, seed=seed)[0], dtype=torch.float32)


def _sampler(near: torch.Tensor, lower_m, upper_m, near_m: float, generator: torch.Generator):
    """points(count, share) -> (count, 3): ``share`` of them within ``near_m`` (per axis) of
    random points of ``near``, the rest uniform in the box."""
    lower = torch.tensor([float(v) for v in lower_m])
    extent = torch.tensor([float(v) for v in upper_m]) - lower

    def points(count: int, share: float) -> torch.Tensor:
        out = lower + extent * torch.rand(count, 3, generator=generator)
        k = int(share * count)
        pick = torch.randint(len(near), (k,), generator=generator)
        out[:k] = near[pick] + near_m * (2 * torch.rand(k, 3, generator=generator) - 1)
        return out

    return points


def distil_start(start: SceneModel, lower_m, upper_m, bandwidth_hz: float, *,
                 settings: NeuralProfileSettings = NeuralProfileSettings(), seed: int = 0,
                 progress: bool = False) -> NeuralProfileField:
    """A :class:`NeuralProfileField` over the box ``lower_m``..``upper_m`` [m] for a radar of
    ``bandwidth_hz``, its network regressed onto ``start``'s SDF by L1 (module docstring);
    its ``distil_residual_m`` is the last step's L1 [m]."""
    field = NeuralProfileField(start, lower_m, upper_m, bandwidth_hz, width=settings.width, depth=settings.depth,
                               seed=seed)
    target = field.start.frozen_sdf()
    points = _sampler(field.near_points, lower_m, upper_m, settings.near_m, torch.Generator().manual_seed(seed))
    optimizer = torch.optim.Adam(field.geometry_parameters(), lr=settings.distil_lr)
    steps = settings.distil_steps
    schedule = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda step: exponential_decay(step, steps - 1, 1.0, 0.1))
    for _ in progress_bar(range(steps), desc="neural model: distil the start", enabled=progress):
        batch = points(settings.batch, settings.near_share)
        with torch.no_grad():
            wanted = target(batch.double()).float()
        misfit = (field.network.sdf(batch) - wanted).abs().mean()
        loss = misfit
        if settings.gradient_weight > 0:
            near = batch[: settings.batch // 4]  # within near_m of the start's surface (near_share >= 1/4)
            slope = gradient(field.network.sdf, near, create_graph=True)
            wanted_slope = gradient(target, near.double()).float()
            loss = loss + settings.gradient_weight * (slope - wanted_slope).norm(dim=1).mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        schedule.step()
        field.distil_residual_m = float(misfit.detach())
    return field


def fit_neural_profiles(measurements: Measurements, field: NeuralProfileField, *,
                        settings: NeuralProfileSettings = NeuralProfileSettings(),
                        profile: ProfileSettings = ProfileSettings(), seed: int = 0,
                        progress: bool = False) -> NeuralProfileFit:
    """Fit ``field`` (:func:`distil_start`'s) to the range profiles of ``measurements`` in
    place: ``settings.steps`` of Adam on its network, with the Eikonal term (module docstring)."""
    clock = time.perf_counter()
    network = field.network
    points = _sampler(field.near_points, network.lower_m, network.upper_m, settings.near_m,
                      torch.Generator().manual_seed(seed))

    def eikonal() -> torch.Tensor:
        return settings.eikonal_weight * eikonal_loss(network.sdf, points(settings.batch // 4, 1.0))

    losses = fit_profiles(measurements, field, [{"params": field.geometry_parameters(), "lr": settings.lr}],
                          steps=settings.steps, settings=profile, progress=progress, prior=eikonal,
                          desc="neural model: profile fit")
    return NeuralProfileFit(field, losses, time.perf_counter() - clock)


@dataclass(frozen=True)
class NeuralModel:
    """The neural model of a room as a run reports it: its field after the profile fit, the
    fit, its mesh near the zero set (a voxel of one range resolution) and the seconds of the
    whole (distillation, fit, mesh)."""

    field: NeuralProfileField
    fit: NeuralProfileFit
    mesh: trimesh.Trimesh
    seconds: float

    def as_dict(self) -> dict:
        return {"parameters": sum(p.numel() for p in self.field.geometry_parameters()),
                "fit_s": round(self.seconds, 2), "profile_fit_s": round(self.fit.seconds, 2),
                "steps": len(self.fit.losses), "loss_first": self.fit.losses[0], "loss_last": self.fit.losses[-1],
                "levels": self.field.network.encoding.levels,
                "distil_residual_mm": self.field.distil_residual_m * 1e3}

    def summary(self) -> str:
        row = self.as_dict()
        return (f"{row['parameters']} weights, {row['levels']} encoding levels, distilled to "
                f"{row['distil_residual_mm']:.1f} mm (L1), profile loss {row['loss_first']:.3f} -> "
                f"{row['loss_last']:.3f} in {row['steps']} steps, {row['fit_s']:.0f} s")


def fit_neural_model(measurements: Measurements, start: SceneModel, *,
                     settings: NeuralProfileSettings = NeuralProfileSettings(),
                     profile: ProfileSettings = ProfileSettings(), seed: int = 0, progress: bool = False,
                     distilled: Callable[[NeuralProfileField], None] | None = None) -> NeuralModel:
    """The neural model of ``measurements`` from ``start`` over the start's box: distilled
    (:func:`distil_start`), fitted to the range profiles (:func:`fit_neural_profiles`) and
    meshed. ``distilled`` is called with the field between the two (to score the start)."""
    clock = time.perf_counter()
    bandwidth_hz = measurements.acquisition.bandwidth_hz
    field = distil_start(start, start.spec.bounds.lower_m, start.spec.bounds.upper_m, bandwidth_hz,
                         settings=settings, seed=seed, progress=progress)
    if distilled is not None:
        distilled(field)
    fit = fit_neural_profiles(measurements, field, settings=settings, profile=profile, seed=seed, progress=progress)
    network = field.network
    mesh = extract_mesh_near_surface(field.frozen_sdf(), network.lower_m, network.upper_m,
                                     range_resolution_m(bandwidth_hz), progress=progress)
    return NeuralModel(field, fit, mesh, time.perf_counter() - clock)
