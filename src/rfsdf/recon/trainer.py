"""Fitting a RadarField to matched-filter images: the GeRaF training loop.

A fresh run first warm-starts f from the thresholded MF image (see ``warm_start``). Each
step: evaluate f and Gamma on the band of voxels near the current zero level set, render
c = Gamma delta_sigma(f) into predicted MF power for a few random views, compare with the
observed MF power on a batch of voxels, add lambda * Eikonal, take an AdamW step.
Checkpoints are atomic and hold everything needed to continue bit for bit (network,
optimiser, schedule, random generator, band, log), so ``resume=True`` after a kill gives
the same result as an uninterrupted run. A NaN/Inf loss stops the run with a clear error
and leaves the last good checkpoint in place.
"""

from __future__ import annotations

import csv
import math
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import tomli_w
import torch
from tqdm.auto import tqdm

from ..atomic import atomic_path
from ..errors import RfsdfError
from ..field import RadarField, levels_for
from ..geometry import Grid
from ..radar import Acquisition, Image
from .config import ReconConfig
from .losses import data_loss, eikonal_loss
from .render import delta_sigma, facing_weights, make_renderer
from .sampling import band_mask, data_voxel_probabilities, eikonal_points, sample_data_voxels
from .schedules import exponential_decay, sigma_at
from .warm_start import fit_to_image, image_signed_distance, local_peak_amplitude

__all__ = ["Problem", "Trainer", "load_field", "read_checkpoint", "CHECKPOINT_NAME", "CONFIG_NAME", "LOG_NAME"]

CHECKPOINT_NAME = "checkpoint.pt"
CONFIG_NAME = "config.toml"
LOG_NAME = "log.csv"
LOG_FIELDS = ("step", "loss", "data", "eikonal", "sigma_mm", "lr", "band_voxels")


@dataclass(frozen=True)
class Problem:
    """What the fit sees: per-view MF power on a grid, and where each view's radar sits.

    observed : (V, nx, ny, nz) float32 MF power, scaled so the largest value is 1.
    view_centres_m : (V, 3) mean Tx/Rx position of each view [m].
    """

    grid: Grid
    observed: torch.Tensor
    view_centres_m: torch.Tensor
    acquisition: Acquisition

    @classmethod
    def from_image(cls, image: Image, acquisition: Acquisition) -> "Problem":
        if image.per_view.shape[0] != acquisition.shape[0]:
            raise RfsdfError(f"the image has {image.per_view.shape[0]} views, the measurements {acquisition.shape[0]}")
        power = image.per_view.abs() ** 2
        peak = float(power.max())
        if not math.isfinite(peak) or peak <= 0:
            raise RfsdfError("the matched-filter image is empty or not finite; nothing to fit")
        centres = 0.5 * (acquisition.tx_m.mean(1) + acquisition.rx_m.mean(1)).float()
        return cls(image.grid, (power / peak).float(), centres, acquisition)


def _field_kwargs(problem: Problem, config: ReconConfig) -> dict:
    fc, grid = config.field, problem.grid
    extent = float(np.max(np.asarray(grid.upper_m) - np.asarray(grid.lower_m)))
    levels = fc.levels if fc.levels is not None else levels_for(extent, float(grid.voxel_m.max()))
    radius = fc.init_radius_m if fc.init_radius_m is not None else extent / 6
    return dict(lower_m=grid.lower_m, upper_m=grid.upper_m, levels=levels, depth=fc.depth, width=fc.width,
                init_radius_m=radius, geometric_init=fc.geometric_init,
                reflectivity_width=fc.reflectivity_width, reflectivity_floor=fc.reflectivity_floor)


def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


class Trainer:
    """Fits a :class:`RadarField` to a :class:`Problem`; checkpoints go to ``run_dir``."""

    def __init__(self, problem: Problem, config: ReconConfig, run_dir, *, progress: bool = False):
        self.problem, self.config, self.run_dir = problem, config, Path(run_dir)
        self.progress = progress
        self.device = _device(config.train.device)
        self.field_kwargs = _field_kwargs(problem, config)
        with torch.random.fork_rng():
            torch.manual_seed(config.train.seed)
            self.field = RadarField(**self.field_kwargs).to(self.device)
        tc = config.train
        groups = [{"params": self.field.geometry.parameters(), "lr": tc.lr},
                  {"params": self.field.reflectance.parameters(), "lr": tc.lr * tc.reflectivity_lr_scale}]
        self.optimizer = torch.optim.AdamW(groups, lr=tc.lr, weight_decay=tc.weight_decay)
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(
            self.optimizer, lambda step: exponential_decay(step, tc.steps, 1.0, tc.lr_end / tc.lr))
        self.generator = torch.Generator().manual_seed(tc.seed)
        self.renderer = make_renderer(config.render.renderer, problem.acquisition, problem.grid,
                                      config.render.psf_radius_m, self.device)
        self.points = problem.grid.points()
        self.voxel_m = float(problem.grid.voxel_m.max())
        self.probabilities = data_voxel_probabilities(problem.observed, config.sampling.data_focus)
        # Moved to the device once, not on every step.
        self.observed = problem.observed.flatten(1).to(self.device)  # (V, N)
        self.view_centres_m = problem.view_centres_m.to(self.device)
        self.step = 0
        self.log: list[dict] = []
        self.band: torch.Tensor | None = None  # (N,) bool, voxels where c is evaluated
        self.near: torch.Tensor | None = None  # (N,) bool, voxels next to the zero level set

    # Checkpoints -------------------------------------------------------------------------
    @property
    def checkpoint_path(self) -> Path:
        return self.run_dir / CHECKPOINT_NAME

    def save(self) -> None:
        state = {
            "step": self.step, "field": self.field.state_dict(), "field_kwargs": self.field_kwargs,
            "optimizer": self.optimizer.state_dict(), "scheduler": self.scheduler.state_dict(),
            "generator": self.generator.get_state(), "band": self.band, "near": self.near, "log": self.log,
            "config": self.config.model_dump(),
        }
        with atomic_path(self.checkpoint_path) as tmp:
            torch.save(state, tmp)
        with atomic_path(self.run_dir / LOG_NAME) as tmp, open(tmp, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=LOG_FIELDS)
            writer.writeheader()
            writer.writerows(self.log)

    def write_config(self) -> Path:
        """Write the resolved config as ``run_dir/config.toml`` (atomically); returns its path."""
        path = self.run_dir / CONFIG_NAME
        with atomic_path(path) as tmp:
            tmp.write_text(tomli_w.dumps(self.config.model_dump(exclude_none=True)))
        return path

    def load(self) -> None:
        state = read_checkpoint(self.checkpoint_path, self.device)
        if state["config"] != self.config.model_dump():
            raise RfsdfError(f"{self.checkpoint_path}: the checkpoint was made with another config; "
                             "resume with the run's own config.toml")
        if state["field_kwargs"] != self.field_kwargs:
            raise RfsdfError(f"{self.checkpoint_path}: the checkpoint was made for another image grid; "
                             "resume with the same data and image")
        self.field.load_state_dict(state["field"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.scheduler.load_state_dict(state["scheduler"])
        self.generator.set_state(state["generator"])
        self.step, self.band, self.near, self.log = state["step"], state["band"], state["near"], state["log"]

    # Training ----------------------------------------------------------------------------
    def warm_start(self) -> None:
        """Pre-fit f to the signed distance of the thresholded view-mean MF image, and Gamma
        to its local peak amplitude (see ``warm_start``)."""
        ic = self.config.init
        if ic.method != "image" or ic.steps == 0:
            return
        mean_power = self.problem.observed.mean(0).numpy()
        distance = image_signed_distance(mean_power, self.problem.grid, ic.threshold)
        window = round(self.config.render.psf_radius_m / 2 / self.voxel_m)
        peak = local_peak_amplitude(mean_power, window)
        fit_to_image(self.field, self.points.to(self.device), torch.from_numpy(distance).flatten().to(self.device),
                     torch.from_numpy(peak).flatten().to(self.device), steps=ic.steps, lr=ic.lr, batch=ic.batch,
                     eikonal_weight=self.config.loss.eikonal_weight, generator=self.generator,
                     progress=self.progress)

    def sigma_m(self, step: int) -> float:
        sc = self.config.sigma
        return sigma_at(step, self.config.train.steps, sc.start_voxels * self.voxel_m,
                        sc.end_voxels * self.voxel_m, sc.schedule)

    @torch.no_grad()
    def refresh_band(self, sigma_m: float) -> None:
        """Evaluate f on every voxel and keep those where c can be non-negligible."""
        values = torch.cat([self.field.sdf(chunk.to(self.device)).cpu() for chunk in self.points.split(1 << 16)])
        half_width = self.config.render.band_sigmas * sigma_m + self.voxel_m
        self.band = band_mask(values, half_width)
        self.near = band_mask(values, max(sigma_m, self.voxel_m))

    def loss_terms(self, sigma_m: float) -> dict[str, torch.Tensor]:
        """Data and Eikonal losses for one step (draws from the generator)."""
        cfg, problem = self.config, self.problem
        index = self.band.nonzero()[:, 0]
        points = self.points[index].to(self.device).requires_grad_(True)
        f, gamma = self.field.sdf_and_reflectivity(points)
        (grad,) = torch.autograd.grad(f.sum(), points, retain_graph=True, create_graph=cfg.render.train_normals)
        normals = torch.nn.functional.normalize(grad, dim=1)
        views = torch.randperm(len(self.view_centres_m), generator=self.generator)[:cfg.sampling.views_per_step]
        views = views.sort().values.to(self.device)
        weights = facing_weights(points.detach(), normals, self.view_centres_m[views],
                                 cfg.render.facing_exponent)
        c = gamma * delta_sigma(f, sigma_m)
        intensity = torch.zeros(len(views), problem.grid.size, device=self.device)
        intensity = intensity.index_copy(1, index.to(self.device), weights * c**2)
        predicted = self.renderer(intensity.reshape(len(views), *problem.grid.shape), views)
        voxels = sample_data_voxels(self.probabilities, cfg.sampling.data_batch, self.generator).to(self.device)
        observed = self.observed[views][:, voxels]
        data = data_loss(predicted.flatten(1)[:, voxels], observed, target=cfg.loss.target,
                         norm=cfg.loss.norm, huber_delta=cfg.loss.huber_delta)
        near = self.points[self.near] if self.near.any() else self.points[index]
        eik_points = eikonal_points(problem.grid.lower_m, problem.grid.upper_m, near, cfg.sampling.eikonal_batch,
                                    cfg.sampling.eikonal_near, sigma_m, self.generator)
        eikonal = eikonal_loss(self.field.sdf, eik_points.to(self.device))
        return {"data": data, "eikonal": eikonal, "loss": data + cfg.loss.eikonal_weight * eikonal}

    def fit(self, *, resume: bool = False, on_step: Callable[[int], None] | None = None) -> RadarField:
        """Train to ``config.train.steps``; returns the field. See the module docstring."""
        tc, rc = self.config.train, self.config.render
        if resume and self.checkpoint_path.exists():
            self.load()
        elif self.checkpoint_path.exists():
            raise RfsdfError(f"{self.run_dir}: already holds a run; pass --resume to continue it or choose another --out")
        else:
            self.write_config()
            self.warm_start()
            self.save()  # a run killed from here on resumes after the warm start
        bar = tqdm(total=tc.steps, initial=self.step, desc="fit", disable=not self.progress)
        while self.step < tc.steps:
            sigma = self.sigma_m(self.step)
            if self.band is None or self.step % rc.band_refresh_every == 0:
                self.refresh_band(sigma)
            terms = self.loss_terms(sigma)
            if not all(torch.isfinite(v) for v in terms.values()):
                bad = ", ".join(f"{k}={float(v.detach())}" for k, v in terms.items())
                kept = f"last good checkpoint kept at {self.checkpoint_path}" if self.checkpoint_path.exists() \
                    else "no checkpoint was written yet"
                raise RfsdfError(f"step {self.step}: loss is not finite ({bad}); stopped, {kept}")
            self.optimizer.zero_grad(set_to_none=True)
            terms["loss"].backward()
            self.optimizer.step()
            self.scheduler.step()
            self.step += 1
            self.log.append({"step": self.step, **{k: float(v.detach()) for k, v in terms.items()},
                             "sigma_mm": sigma * 1e3, "lr": self.scheduler.get_last_lr()[0],
                             "band_voxels": int(self.band.sum())})
            bar.update(1)
            bar.set_postfix(data=f"{float(terms['data'].detach()):.3g}", eik=f"{float(terms['eikonal'].detach()):.3g}",
                            sigma=f"{sigma * 1e3:.1f}mm")
            if self.step % tc.checkpoint_every == 0 or self.step == tc.steps:
                self.save()
            if on_step is not None:
                on_step(self.step)
        bar.close()
        return self.field


def load_field(run_dir) -> RadarField:
    """The trained field of a run folder (from its checkpoint), on the CPU, in eval mode."""
    path = Path(run_dir) / CHECKPOINT_NAME
    if not path.exists():
        raise RfsdfError(f"{run_dir}: no {CHECKPOINT_NAME}; is this a run folder from `rfsdf reconstruct`?")
    state = read_checkpoint(path, "cpu")
    try:
        field = RadarField(**state["field_kwargs"])
        field.load_state_dict(state["field"])
    except (RuntimeError, KeyError, TypeError) as exc:
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint ({exc})") from None
    return field.eval()


def read_checkpoint(path, device) -> dict:
    """The state dict of a checkpoint file, loaded as data only.

    ``weights_only=True``: the unpickler accepts tensors, numbers, strings and containers
    and refuses everything else, so a crafted checkpoint cannot run code (a plain
    ``torch.load`` would execute whatever a pickle in the file asks for).
    """
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except pickle.UnpicklingError:
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint (it holds objects other than tensors, "
                         "numbers and strings; refused without running them)") from None
    except Exception as exc:  # noqa: BLE001 - any other failure to read it means "not a checkpoint"
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint ({reason})") from None
    if not isinstance(state, dict):
        raise RfsdfError(f"{path}: not a readable rfsdf checkpoint (holds a {type(state).__name__}, not a dict)")
    return state
