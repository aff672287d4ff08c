"""The primitive fit: a scene model's free parameters fitted by gradient descent through the
coherent renderer and the data loss of the neural fit.

A :class:`PrimitiveField` stands where the neural field stands in the renderer: its ``sdf``
is the scene model's analytic SDF built from the current parameter values
(``scene.build_shape`` with the free ones as tensors, so f is differentiable in them), and
each surface sample reflects by the Fresnel coefficient of its object's material (the
renderer's material path with certain classes). The analytic SDFs are exact, so there is
no Eikonal term; the samples move with the parameters through the renderer's projection
onto f = 0 (``recon/surface.py``), as the neural surface moves with its weights.

The loss compares RMS amplitudes over cubes of voxels (``sampling.pooled_amplitude``), and
the cubes shrink from ``cell_voxels_start`` to ``cell_voxels`` over the fit: a coarse to
fine schedule over the image grid, since a surface more than lambda/4 off sees the phase of
its own glint wrap (the tiny neural fit's 22 mm ripple minimum, docs/guide/reproducibility.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from ..materials import get_material, point_reflectivity, reflectivity_class
from ..progress import progress_bar
from ..scene import build_shape
from ..scene_model import FreeMaterial, SceneModel
from .losses import amplitude_loss
from .render import CoherentRenderer
from .sampling import data_batch, data_voxel_probabilities, pooled_amplitude
from .trainer import Problem

__all__ = ["PrimitiveField", "PrimitiveFit", "fit_primitive", "material_text", "MATERIAL_LR", "RELATIVE_GAIN"]

MATERIAL_LR = 0.05  # Adam's rate for a free material's logits [nats per step, about]
START_LOGIT = 2.0  # a free material's start class, over the others' 0: p 0.65 of five classes
# a PrimitiveFit's calibration when its materials were read with no gain to read them by
RELATIVE_GAIN = "unknown: relative to the brightest free material"


class PrimitiveField(torch.nn.Module):
    """A scene model with its free parameters as torch parameters (float64)."""

    trace_step = 1.0  # the SDF is exact: sphere tracing steps by f

    def __init__(self, model: SceneModel):
        super().__init__()
        self.model = model
        self.values = torch.nn.ParameterList(
            [torch.nn.Parameter(torch.tensor(p.start[0] if p.scalar else p.start, dtype=torch.float64))
             for p in model.free])
        self.lower = [torch.tensor(p.lower, dtype=torch.float64).reshape(v.shape) for p, v in zip(model.free, self.values)]
        self.upper = [torch.tensor(p.upper, dtype=torch.float64).reshape(v.shape) for p, v in zip(model.free, self.values)]
        names = [get_material(o.material).name for o in model.spec.objects]  # catalogue materials only
        free = {m.index: m for m in model.materials}
        held = [name for index, name in enumerate(names) if index not in free]
        # the classes, as a material head's: the held materials', then the free ones'
        self.materials = tuple(dict.fromkeys(held + [c for m in model.materials for c in m.classes]))
        certain = torch.zeros(len(names), len(self.materials), dtype=torch.float64)
        for index, name in enumerate(names):
            certain[index, self.materials.index(name)] = float(index not in free)
        self.register_buffer("_certain", certain)  # (objects, classes): one-hot for a held material
        self.logits = torch.nn.ParameterList(
            [torch.nn.Parameter(_start_logits(m)) for m in model.materials])  # one (classes,) per free material
        self._columns = [torch.tensor([self.materials.index(c) for c in m.classes]) for m in model.materials]
        # a shell's outer box follows its inner one (SceneModel.shell_ties): outer = inner + their start's difference
        self._ties = [(outer, inner, (self.values[outer] - self.values[inner]).detach().clone())
                      for outer, inner in model.shell_ties()]

    def _current(self) -> list[torch.Tensor]:
        """The free parameters' values, a tied one its leader's plus its offset (differentiable in the leader)."""
        values = list(self.values)
        for outer, inner, offset in self._ties:
            values[outer] = self.values[inner] + offset.to(self.values[inner].device)
        return values

    def object_sdfs(self, *, detach: bool = False) -> list:
        """Each object's SDF at the current parameter values (held constant with ``detach``)."""
        overrides = {}
        for parameter, value in zip(self.model.free, self._current()):
            node, field = self.model.node(parameter.path)
            overrides[(id(node), field)] = value.detach().clone() if detach else value
        return [build_shape(o.shape, self.model.base_dir, overrides) for o in self.model.spec.objects]

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        """The model's SDF (N,) [m] at points (N, 3), differentiable in the free parameters."""
        return torch.stack([sdf(points) for sdf in self.object_sdfs()]).min(0).values

    def frozen_sdf(self):
        """The SDF at the current values, detached and built once (for sphere tracing,
        which calls it a few hundred times a step): points (N, 3) -> (N,) [m]."""
        sdfs = self.object_sdfs(detach=True)
        return lambda points: torch.stack([sdf(points) for sdf in sdfs]).min(0).values

    def object_probabilities(self) -> torch.Tensor:
        """(objects, K) each object's class probabilities: certain of a held material, the
        softmax of its logits for a free one (differentiable in them)."""
        rows = self._certain.clone()
        for free, logits, columns in zip(self.model.materials, self.logits, self._columns):
            rows[free.index, columns.to(rows.device)] = torch.softmax(logits, dim=0)
        return rows

    def material(self, points: torch.Tensor) -> torch.Tensor:
        """(N, K) class probabilities of the nearest object's material at ``points`` (N, 3)."""
        with torch.no_grad():
            nearest = torch.stack([sdf(points) for sdf in self.object_sdfs()]).argmin(0)
        return self.object_probabilities()[nearest].to(points.dtype)

    def parameter_groups(self, lr: float) -> list[dict]:
        """Adam's groups: the free parameters at ``lr``, the free materials' logits at
        ``MATERIAL_LR`` (each only when there are any)."""
        groups = [{"params": list(self.values), "lr": lr}, {"params": list(self.logits), "lr": MATERIAL_LR}]
        return [group for group in groups if group["params"]]

    @torch.no_grad()
    def clamp_(self) -> None:
        """Every free parameter back inside its bounds, a tied one at its leader plus its offset."""
        for value, lower, upper in zip(self.values, self.lower, self.upper):
            value.copy_(torch.maximum(torch.minimum(value, upper.to(value.device)), lower.to(value.device)))
        for outer, inner, offset in self._ties:
            self.values[outer].copy_(self.values[inner] + offset.to(self.values[inner].device))

    def fitted(self) -> list[list[float]]:
        """The free parameters' current values, as lists of floats."""
        return [np.atleast_1d(v.detach().cpu().numpy()).tolist() for v in self.values]

    def fitted_materials(self) -> list[dict[str, float]]:
        """Each free material's class probabilities, {class: p}."""
        return [dict(zip(m.classes, torch.softmax(logits.detach(), 0).tolist()))
                for m, logits in zip(self.model.materials, self.logits)]


def material_text(row: dict) -> str:
    """One line for a :meth:`PrimitiveFit.material_table` row: 'east concrete (|Gamma| 0.36,
    truth concrete)'."""
    reflectivity = "unseen" if row["reflectivity"] is None else f"|Gamma| {row['reflectivity']:.2f}"
    truth = "" if row["truth"] is None else f", truth {row['truth']}"
    return f"{row['name']} {row['fitted'] or '?'} ({reflectivity}{truth})"


def _start_logits(material: FreeMaterial) -> torch.Tensor:
    """(classes,) float64: zeros (every class alike), ``START_LOGIT`` on the start class."""
    logits = torch.zeros(len(material.classes), dtype=torch.float64)
    if material.start is not None:
        logits[material.classes.index(material.start)] = START_LOGIT
    return logits


@dataclass(frozen=True)
class PrimitiveFit:
    """The fitted field, the data loss per step, the wall time [s], the data's centre
    frequency [Hz] (where a free material's |Gamma| is read) and, where the free materials
    were read from the data after the fit instead of fitted (range profiles), their
    ``reflectivities`` (one |Gamma(0)| or None each) and how the gain was set."""

    field: PrimitiveField
    losses: list[float]
    seconds: float
    frequency_hz: float
    reflectivities: list[float | None] | None = None
    calibration: str | None = None

    def free_table(self, truth=None) -> list[dict]:
        """One row per free parameter: name, unit, start, fitted and (given the true scene
        spec ``truth`` of the same structure) truth, each a list of floats."""
        model = self.field.model
        truths = None if truth is None else model.values_in(truth)
        return [{"name": p.name, "unit": "m", "start": p.start, "fitted": fitted,
                 "truth": None if truths is None else truths[i]}
                for i, (p, fitted) in enumerate(zip(model.free, self.field.fitted()))]

    def material_table(self, truth=None) -> list[dict]:
        """One row per free material: the object's name, start (None: undecided), its
        ``reflectivity`` |Gamma(0)| (fitted: |sum_k p_k Gamma_k| of the class probabilities;
        or read from the data), the ``fitted`` class (the one nearest that reflectivity, as
        the material head's readout; None where it is relative or unseen), the class
        ``probabilities`` {class: p} (fitted ones only), how the gain was set and (given the
        true scene spec ``truth``) the truth."""
        model = self.field.model
        truths = None if truth is None else model.materials_in(truth)
        rows = []
        for i, (m, p) in enumerate(zip(model.materials, self.field.fitted_materials())):
            if self.reflectivities is None:
                reflectivity = float(point_reflectivity(torch.tensor([list(p.values())]), m.classes,
                                                        self.frequency_hz)[0])
            else:
                reflectivity, p = self.reflectivities[i], None
            absolute = reflectivity is not None and self.calibration != RELATIVE_GAIN
            rows.append({"name": m.name, "start": m.start, "reflectivity": reflectivity,
                         "fitted": str(reflectivity_class(reflectivity, m.classes, self.frequency_hz))
                         if absolute else None, "probabilities": p, "calibration": self.calibration or "fitted",
                         "truth": None if truths is None else truths[i]})
        return rows

    def fitted_spec(self):
        """The fitted scene's spec: the free parameters at their fit, each free material its
        fitted class (:meth:`material_table`)."""
        model = self.field.model
        names = [row["fitted"] or model.spec.objects[m.index].material  # unseen or relative: its start
                 for m, row in zip(model.materials, self.material_table())]
        return model.fitted_spec(self.field.fitted(), names)

    def as_dict(self, truth=None) -> dict:
        return {"free": self.free_table(truth), "materials": self.material_table(truth),
                "fit_s": round(self.seconds, 2), "steps": len(self.losses),
                "loss_first": self.losses[0] if self.losses else None,
                "loss_last": self.losses[-1] if self.losses else None}


def fit_primitive(problem: Problem, model: SceneModel, *, steps: int = 150, lr: float = 5e-4,
                  cell_voxels_start: int = 4, cell_voxels_end: int = 1, voxels_per_step: int = 4096,
                  views_per_step: int = 6, refresh_every: int = 1, data_focus: float = 0.5, seed: int = 0,
                  device="cpu", progress: bool = False) -> PrimitiveFit:
    """Fit ``model``'s free parameters to ``problem``'s data (module docstring): Adam at
    ``lr`` [m per step, about] for ``steps``, each on ``views_per_step`` random views and
    about ``voxels_per_step`` voxels in cubes shrinking from ``cell_voxels_start`` to
    ``cell_voxels_end`` voxels per edge; new surface samples every ``refresh_every`` steps."""
    clock = time.perf_counter()
    generator = torch.Generator().manual_seed(seed)
    field = PrimitiveField(model).to(device)
    renderer = CoherentRenderer(problem.measurements, problem.grid, device=device)
    observed = renderer.observed.abs()
    probabilities = data_voxel_probabilities(observed, data_focus)
    optimizer = torch.optim.Adam(field.parameter_groups(lr))
    losses = []
    for step in progress_bar(range(steps), desc="primitive fit", enabled=progress):
        if step % refresh_every == 0:
            renderer.refresh(field.sdf, generator)
        fraction = step / max(steps - 1, 1)
        size = round(cell_voxels_start + fraction * (cell_voxels_end - cell_voxels_start))
        views, cells, voxels = data_batch(renderer.num_views, views_per_step, probabilities, voxels_per_step,
                                          problem.grid.shape, size, generator, device)
        predicted = renderer(field, views, voxels, probabilities=field.material(renderer.candidates.anchors))
        target = observed[views][:, voxels]
        if size > 1:
            predicted, target = pooled_amplitude(predicted, cells), pooled_amplitude(target, cells)
        loss = amplitude_loss(predicted, target)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        field.clamp_()
        losses.append(float(loss.detach()))
    frequency_hz = problem.measurements.acquisition.center_frequency_hz
    return PrimitiveFit(field, losses, time.perf_counter() - clock, frequency_hz)
