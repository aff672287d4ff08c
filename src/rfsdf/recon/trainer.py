"""Fitting a RadarField to radar measurements: the GeRaF training loop.

A fresh run first warm-starts f (and Gamma) from a thresholded image of the data (see
``warm_start``). Each step then renders predicted MF images of the neural surface for a
few random views through the simulator's physics (see ``render``), compares them with the
observed MF images on a batch of voxels (see ``losses``), adds lambda * Eikonal, and takes
an Adam step; the surface samples and their facing/shadow masks are refreshed every
``render.refresh_every`` steps. Checkpoints (``checkpoint``) hold everything needed to
continue bit for bit (network, optimiser, schedule, random generator, surface samples, log)
and a digest of the data, so ``resume=True`` after a kill gives the same result as an
uninterrupted run, and refuses other data. A NaN/Inf loss stops the run with a clear error
and leaves the last good checkpoint in place.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from ..device import resolve_device
from ..errors import RfsdfError
from ..field import RadarField, levels_for
from ..geometry import Grid
from ..progress import progress_bar
from ..radar import Measurements, matched_filter
from ..radar.clean import CleanResult, clean_image
from ..radar.imaging import Image
from ..radar.glint_sidelobes import sidelobe_peaks, sidelobe_voxels
from ..radar.range_peaks import range_peaks
from ..radar.specular import specular_normals
from ..scene import Scene
from .checkpoint import CHECKPOINT_NAME, read_checkpoint, save_checkpoint, write_config, write_log
from .config import ReconConfig
from .glints import cap_minimum, glint_caps
from .losses import (DATA_LOSSES, bands_of, eikonal_loss, material_cross_entropy, material_entropy, normal_variation,
                     peak_match_loss, uses_phase)
from .object_primitives import FramedPrimitive, bridged_peaks, primitive_start
from .render import RENDERERS
from .sampling import bending_pairs, data_batch, data_voxel_probabilities, eikonal_points, pooled_amplitude
from .schedules import SCHEDULES
from .warm_start import detection_threshold, excluded_voxels, known_exclusion, warm_start

__all__ = ["Problem", "StepRecord", "FitResult", "Trainer", "initial_field"]

PEAK_MATCH_SAMPLES = 5  # points along each range peak's line (LossConfig.peak_match_weight)
PEAK_MATCH_SCALE_M = 1e-3  # the peak-match misfit's knee: quadratic below it, linear beyond [m]


@dataclass(frozen=True)
class Problem:
    """What the fit sees: the measurements, the voxel grid of its images, where the data
    came from (a file name, for messages), and optionally their matched-filter ``image`` or
    their ``clean`` of that grid, when the caller has them already (else the warm start
    computes the one its method needs).

    ``gain``: the radar gain from the renderer's amplitudes to the data's, when known: 1 for
    data rfsdf simulated (the renderer is the simulator's physics), a calibrated value for a
    real radar; None fits one gain at each step, and a material head then learns only the
    ratios of its surfaces' |Gamma| (a free reflectivity always has its gain fitted: it
    carries its own scale). ``material_labels``: points (Q, 3) [m] -> (Q,) class
    indices into the config's materials (-1 unknown), for a cross-entropy term.
    ``known_materials``: the same kind of function for surfaces whose material is known
    (a calibration reference, ``recon.calibration``): they are rendered with it whatever
    the head says, so with the gain fitted they set its scale. ``through``: a known scene
    the surface is seen through (a box whose own return is out of the data already), in the
    renderer's lines of sight (``CoherentRenderer``'s ``through``)."""

    measurements: Measurements
    grid: Grid
    source: str = "measurements"
    clean: CleanResult | None = None
    image: Image | None = None
    gain: float | None = None
    material_labels: Callable[[torch.Tensor], torch.Tensor] | None = None
    known_materials: Callable[[torch.Tensor], torch.Tensor] | None = None
    through: Scene | None = None

    def digest(self) -> str:
        """SHA-256 of the samples, the acquisition geometry, the grid and the scene the surface
        is seen ``through`` (hex, 16 digits)."""
        acq, h = self.measurements.acquisition, hashlib.sha256()
        for tensor in (self.measurements.data, acq.tx_m, acq.rx_m, acq.frequencies_hz):
            h.update(tensor.detach().cpu().contiguous().numpy().tobytes())
        h.update(repr((self.grid.lower_m, self.grid.upper_m, self.grid.shape)).encode())
        if self.through is not None:
            h.update(self.through.spec.model_dump_json().encode())
        return h.hexdigest()[:16]


@dataclass(frozen=True)
class StepRecord:
    """One line of ``log.csv``: losses (data relative misfit, Eikonal, total), learning rate,
    surface samples, wall time of the step [s]."""

    step: int
    loss: float
    data: float
    eikonal: float
    lr: float
    samples: int
    seconds: float


@dataclass(frozen=True)
class FitResult:
    """The fitted field, the field as the warm start left it (to measure what the fit
    adds), and how the fit went."""

    field: RadarField
    warm_field: RadarField
    log: list[StepRecord]

    @property
    def seconds_per_step(self) -> float:
        """Median wall time of a step [s] (refresh steps included in the distribution)."""
        return float(np.median([r.seconds for r in self.log])) if self.log else float("nan")


def _field_kwargs(grid: Grid, config: ReconConfig) -> dict:
    fc = config.field
    extent = float(np.max(np.asarray(grid.upper_m) - np.asarray(grid.lower_m)))
    levels = fc.levels if fc.levels is not None else levels_for(extent, float(grid.voxel_m.max()))
    radius = fc.init_radius_m if fc.init_radius_m is not None else extent / 6
    return dict(lower_m=grid.lower_m, upper_m=grid.upper_m, levels=levels, depth=fc.depth, width=fc.width,
                init_radius_m=radius, geometric_init=fc.geometric_init,
                reflectivity_width=fc.reflectivity_width, reflectivity_floor=fc.reflectivity_floor,
                materials=tuple(fc.materials),
                **({} if fc.displacement_knot_m is None else {"displacement_knot_m": fc.displacement_knot_m}))


def initial_field(grid: Grid, config: ReconConfig, device) -> RadarField:
    """The field a fit of ``config`` on ``grid`` starts from before its warm start (seeded by
    ``train.seed``, the global random state left as it was), on ``device``."""
    with torch.random.fork_rng():
        torch.manual_seed(config.train.seed)
        return RadarField(**_field_kwargs(grid, config)).to(device)


def _resumable(config: dict) -> dict:
    """What a checkpoint must share with the config that resumes it: all but the device (a
    fit started on a GPU may go on on a CPU) and a known gain given after the fit
    (``calibration.gain``: the materials are read in it, the fit never sees it)."""
    def without(table: str, key: str) -> dict:
        return {k: v for k, v in config.get(table, {}).items() if k != key}

    return {**config, "train": without("train", "device"), "calibration": without("calibration", "gain")}


class Trainer:
    """Fits a :class:`RadarField` to a :class:`Problem`; checkpoints go to ``run_dir``."""

    def __init__(self, problem: Problem, config: ReconConfig, run_dir, *, start: dict | None = None,
                 progress: bool = False):
        """``start``: a state of the field (``RadarField.state_dict``) to fit from instead of
        the warm start (a study's chosen surface)."""
        self.problem, self.config, self.run_dir = problem, config, Path(run_dir)
        self.progress, self.start = progress, start
        self.device = resolve_device(config.train.device, "train.device")
        self.field_kwargs = _field_kwargs(problem.grid, config)
        self.field = initial_field(problem.grid, config, self.device)
        tc, rc = config.train, config.render
        head, displacement = self.field.material_head, self.field.displacement
        geometry = (displacement if displacement is not None else self.field.geometry).parameters()
        groups = [{"params": geometry, "lr": tc.lr},
                  {"params": self.field.reflectance.parameters(), "lr": tc.lr * tc.reflectivity_lr_scale},
                  {"params": head.parameters() if head is not None else [], "lr": tc.lr * tc.material_lr_scale}]
        self.optimizer = torch.optim.AdamW(groups, lr=tc.lr, weight_decay=tc.weight_decay)
        schedule = SCHEDULES.get(tc.schedule)
        decay = lambda step, total=tc.steps: schedule(step, total, 1.0, tc.lr_end / tc.lr)  # noqa: E731
        # Gamma alone first: a surface the data do not show should dim before it moves.
        freed = tc.geometry_delay_steps
        origin = freed if tc.geometry_schedule == "from_release" else 0  # where f's decay starts
        delayed = lambda step: decay(step - origin, tc.steps - origin) if step >= freed else 0.0  # noqa: E731
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(self.optimizer, [delayed, decay, decay])
        self.generator = torch.Generator().manual_seed(tc.seed)
        self.renderer = RENDERERS.get(rc.renderer)(
            problem.measurements, problem.grid, element_step=rc.element_step, frequency_step=rc.frequency_step,
            surface=rc.surface,
            spacing_m=rc.spacing_m,
            shadows=rc.shadows, device=self.device, smoothing_m=rc.surface_smoothing_m,
            bands=max(bands_of(DATA_LOSSES.get(name)) for name in config.loss.names()), through=problem.through,
            progress=progress)
        self.observed = self.renderer.observed.abs()  # (V, N) amplitude, peak 1
        self.probabilities = data_voxel_probabilities(self.observed, config.sampling.data_focus)
        self.step = 0
        self.log: list[StepRecord] = []
        self.warm_state: dict | None = None  # the field's state after the warm start
        # the warm start's range peaks: points (N, 3) [m], amplitude (N,), view (N,) and the
        # unit vectors (N, 3) along which each was found (radar.range_peaks.RangePeaks)
        self.peaks: tuple[torch.Tensor, ...] | None = None
        self._peak_lines: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None = None  # see peak_lines()
        self.primitive_fits: list | None = None  # the fragments' primitives, with init.primitives
        self.primitives: list[FramedPrimitive] = []  # those that replaced their fragments (checkpointed)

    # Checkpoints -------------------------------------------------------------------------
    @property
    def checkpoint_path(self) -> Path:
        return self.run_dir / CHECKPOINT_NAME

    def save(self) -> None:
        save_checkpoint(self.run_dir, {
            "step": self.step, "field": self.field.state_dict(), "field_kwargs": self.field_kwargs,
            "optimizer": self.optimizer.state_dict(), "scheduler": self.scheduler.state_dict(),
            "generator": self.generator.get_state(), "surface": self.renderer.surface_state(),
            "log": [asdict(r) for r in self.log], "config": self.config.model_dump(), "warm_field": self.warm_state,
            "data_digest": self.problem.digest(), "data_source": self.problem.source, "gain": self.problem.gain,
            "peaks": self.peaks, "primitives": [primitive.state() for primitive in self.primitives],
            "grid": {"lower_m": list(self.problem.grid.lower_m), "upper_m": list(self.problem.grid.upper_m),
                     "shape": list(self.problem.grid.shape)},  # what a later readout renders on (run_materials)
        })
        write_log(self.run_dir, [asdict(r) for r in self.log])

    def load(self) -> None:
        state = read_checkpoint(self.checkpoint_path, self.device)
        try:
            if _resumable(state["config"]) != _resumable(self.config.model_dump()):
                raise RfsdfError(f"{self.checkpoint_path}: the checkpoint was made with another config; "
                                 "resume with the run's own config.toml")
            if state["data_digest"] != self.problem.digest() or state["field_kwargs"] != self.field_kwargs:
                raise RfsdfError(f"{self.checkpoint_path}: the run was fitted on {state['data_source']} "
                                 f"(digest {state['data_digest']}), not on {self.problem.source} "
                                 f"(digest {self.problem.digest()}) on this grid; resume with the same data")
            self.field.load_state_dict(state["field"])
            self.optimizer.load_state_dict(state["optimizer"])
            self.scheduler.load_state_dict(state["scheduler"])
            self.generator.set_state(state["generator"])
            self.renderer.load_surface_state(state["surface"])
            self.step = state["step"]
            self.log = [StepRecord(**row) for row in state["log"]]
            self.warm_state = state["warm_field"]
            self.peaks = state["peaks"]
            self.primitives = [FramedPrimitive.from_state(p) for p in state.get("primitives", [])]  # older runs hold none
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            if isinstance(exc, RfsdfError):
                raise
            raise RfsdfError(f"{self.checkpoint_path}: not a readable rfsdf checkpoint ({exc})") from None

    # Training ----------------------------------------------------------------------------
    def warm_start(self) -> None:
        """Pre-fit f to the signed distance of a thresholded image (view-mean MF power, or its
        CLEAN image), and Gamma to its local peak amplitude (see ``warm_start``)."""
        ic = self.config.init
        if ic.method == "sphere" or ic.steps == 0:
            return
        grid = self.problem.grid
        clean = None
        if ic.method == "clean":
            clean = self.problem.clean or clean_image(self.problem.measurements, grid, device=self.device,
                                                      progress=self.progress)
            per_view = clean.per_view_power.numpy()
        else:  # every frame and frequency, not the renderer's thinned data
            image = self.problem.image or matched_filter(self.problem.measurements, grid, device=self.device)
            per_view = (image.per_view.abs() ** 2).numpy()
        power = per_view.mean(0)
        threshold = detection_threshold(ic.threshold, clean)
        acquisition = self.problem.measurements.acquisition
        matched = None
        if clean is not None and ic.sidelobes_in_mf:  # every Tx and Rx, as CLEAN's own images
            image = matched_filter(self.problem.measurements, grid, device=self.device)
            matched = (image.per_view.abs() ** 2).numpy()
        exclude = excluded_voxels(ic, per_view, acquisition, grid, threshold, matched_filter_power=matched)
        if self.problem.through is not None:
            exclude |= known_exclusion(grid, self.problem.through, ic.known_margin_m)
        normals = None
        if ic.normal_weight > 0:
            normals = specular_normals(per_view, *(c.cpu().numpy() for c in acquisition.view_centres()), grid)
        peaks = None
        if ic.peak_weight > 0 or self.config.loss.peak_weight > 0 or self.config.loss.peak_match_weight > 0:
            peaks = range_peaks(self.problem.measurements, per_view, grid, threshold=threshold,
                                local_threshold=ic.local_threshold, window_m=ic.window_m, keep=~exclude,
                                through=self.problem.through)
            if ic.glint_sidelobes:  # neither peaks nor detections on what the glints' sidelobes explain
                exclude |= sidelobe_voxels(self.problem.measurements, peaks, per_view, grid, threshold=threshold,
                                           local_threshold=ic.local_threshold, window_m=ic.window_m)
                peaks = peaks.select(~sidelobe_peaks(self.problem.measurements, peaks))
            if len(peaks.points):
                self.peaks = tuple(torch.from_numpy(a).to(self.device) for a in
                                   (peaks.points.astype(np.float32), peaks.amplitude.astype(np.float32),
                                    peaks.view.astype(np.int64), peaks.towards.astype(np.float32)))
        warm_start(self.field, power, grid, threshold=threshold, local_threshold=ic.local_threshold,
                   window_m=ic.window_m, closing_m=ic.closing_m, steps=ic.steps, lr=ic.lr, batch=ic.batch,
                   near_share=ic.near_share, exclude=exclude, normals=normals, normal_weight=ic.normal_weight,
                   peaks=peaks if ic.peak_weight > 0 else None, peak_weight=ic.peak_weight,
                   peak_normal_weight=ic.peak_normal_weight, peak_apex_m=ic.peak_apex_m,
                   eikonal_weight=ic.eikonal_weight, bending_weight=ic.bending_weight,
                   bending_step_m=self.config.loss.bending_step_m,
                   generator=self.generator, progress=self.progress)
        if ic.primitives and self.peaks is not None:
            caps = self.peak_caps(ic.peak_cone_deg)
            self.primitive_fits = primitive_start(
                self.field, self.peaks[0].cpu(), self.peaks[3].cpu(), grid.lower_m, grid.upper_m, lr=ic.lr,
                batch=ic.batch, eikonal_weight=ic.eikonal_weight, near_share=ic.near_share, generator=self.generator,
                caps=None if caps is None else caps.cpu(), amplitude=self.peaks[1].cpu(), progress=self.progress)
            self.primitives = [fit.primitive for fit in self.primitive_fits if fit.explains]
            held = ~bridged_peaks(self.primitive_fits, self.peaks[0].cpu())  # a bridge's rim returns are not held
            self.peaks = tuple(a[held.to(a.device)] for a in self.peaks)

    @torch.no_grad()
    def refresh_surface(self) -> None:
        """New surface samples of the current field (and their facing/shadow masks)."""
        self.renderer.refresh(self.field.sdf, self.generator)

    def cell_size(self) -> int:
        """Edge [voxels] of the cubes the data loss compares at this step: ``cell_voxels``, or
        annealed from ``cell_voxels_start`` (once f moves) down to it at the last step."""
        sampling, delay = self.config.sampling, self.config.train.geometry_delay_steps
        if sampling.cell_voxels_start is None:
            return sampling.cell_voxels
        fraction = min(max((self.step - delay) / max(self.config.train.steps - 1 - delay, 1), 0.0), 1.0)
        return round(sampling.cell_voxels_start + fraction * (sampling.cell_voxels - sampling.cell_voxels_start))

    def surface_materials(self, *, geometry: bool = True) -> torch.Tensor | None:
        """(Q, K) class probabilities at the renderer's surface candidates
        (``CoherentRenderer.surface_materials``), certain of its material where the problem
        knows it (``Problem.known_materials``); None with a free reflectivity."""
        probabilities = self.renderer.surface_materials(self.field, geometry=geometry)
        if probabilities is None or self.problem.known_materials is None:
            return probabilities
        known = self.problem.known_materials(self.renderer.candidates.anchors)
        certain = torch.nn.functional.one_hot(known.clamp(min=0), probabilities.shape[1]).to(probabilities)
        return torch.where((known >= 0)[:, None], certain, probabilities)

    def loss_terms(self) -> dict[str, torch.Tensor]:
        """Data and Eikonal losses for one step (draws from the generator). While f is frozen
        (the first ``train.geometry_delay_steps``) no graph is built through it: those steps
        fit Gamma only and cost less."""
        cfg = self.config
        size = self.cell_size()
        views, cells, voxels = data_batch(self.renderer.num_views, cfg.sampling.views_per_step, self.probabilities,
                                          cfg.sampling.data_batch, self.problem.grid.shape, size, self.generator,
                                          self.device)
        frozen = self.step < cfg.train.geometry_delay_steps
        probabilities = self.surface_materials(geometry=not frozen)
        data_loss = DATA_LOSSES.get(cfg.loss.stage_at(self.step / cfg.train.steps))
        bands = bands_of(data_loss) > 1
        chosen = self.matched_lines(views) if not frozen and cfg.loss.peak_match_weight > 0 else None
        lines = None if chosen is None else [None if i is None else self.peak_lines()[0][i].reshape(-1, 3)
                                             for i in chosen]
        predicted = self.renderer(self.field, views, voxels, geometry=not frozen, probabilities=probabilities,
                                  bands=bands, lines=lines)
        if lines is not None:
            predicted, line_images = predicted
        observed = self.renderer.band_observed[views][:, :, voxels] if bands else self.renderer.observed[views][:, voxels]
        known_gain = self.problem.gain is not None and probabilities is not None
        if known_gain:  # into the units of the observed images (peak 1)
            predicted = predicted * (self.problem.gain / self.renderer.observed_peak)
        if size > 1 and not uses_phase(data_loss):
            predicted, observed = pooled_amplitude(predicted, cells), pooled_amplitude(observed, cells)
        data = data_loss(predicted, observed, fit_gain=not known_gain)
        terms = {"data": data}
        if probabilities is not None:
            terms["material"] = cfg.loss.material_entropy_weight * material_entropy(
                probabilities, self.renderer.candidates.area_m2)
            if self.problem.material_labels is not None:
                labels = self.problem.material_labels(self.renderer.candidates.anchors)
                terms["material"] = terms["material"] + cfg.loss.material_label_weight * material_cross_entropy(
                    probabilities, labels)
        grid = self.problem.grid
        eik_points = eikonal_points(grid.lower_m, grid.upper_m, self.renderer.candidates.anchors,
                                    cfg.sampling.eikonal_batch, cfg.sampling.eikonal_near,
                                    float(np.max(grid.voxel_m)), self.generator)
        if frozen:  # the Eikonal term moves only f: skip it (the points are still drawn, for the generator)
            eikonal = torch.zeros((), device=self.device)
        else:
            eikonal = eikonal_loss(self.field.sdf, eik_points.to(self.device))
        terms["eikonal"] = eikonal
        terms["loss"] = data + cfg.loss.eikonal_weight * eikonal + terms.get("material", 0.0)
        if not frozen and cfg.loss.peak_weight > 0 and self.peaks is not None:
            points, amplitude = self.peaks[:2]
            caps = self.peak_caps(cfg.loss.peak_cone_deg)
            gaps = self.field.sdf(points) if caps is None else cap_minimum(self.field.sdf, caps)
            held = (gaps.abs() * amplitude).sum() / amplitude.sum()
            terms["peaks"] = cfg.loss.peak_weight * held
            terms["loss"] = terms["loss"] + terms["peaks"]
        if not frozen and cfg.loss.bending_weight > 0:
            points, offsets = bending_pairs(self.renderer.candidates.anchors, cfg.loss.bending_points,
                                            cfg.loss.bending_step_m, self.generator)
            terms["bending"] = cfg.loss.bending_weight * normal_variation(self.field.sdf, points.to(self.device),
                                                                          offsets.to(self.device))
            terms["loss"] = terms["loss"] + terms["bending"]
        if chosen is not None and any(i is not None for i in chosen):
            _, observed_lines, offsets = self.peak_lines()
            index = torch.cat([i for i in chosen if i is not None])
            line_predicted = torch.cat([image.reshape(len(i), -1) for i, image in zip(chosen, line_images)
                                        if i is not None])
            terms["peak_match"] = cfg.loss.peak_match_weight * peak_match_loss(
                line_predicted, observed_lines[index], offsets, self.peaks[1][index], PEAK_MATCH_SCALE_M)
            terms["loss"] = terms["loss"] + terms["peak_match"]
        return terms

    def peak_ranges(self) -> torch.Tensor:
        """(N,) each range peak's distance [m] from its view's centre, the radius of the sphere
        :func:`~rfsdf.recon.glints.glint_gap` holds it on; 0 where the views are planar scans
        (their lines are parallel, not a cone's: f at the peak)."""
        points, _, view, _ = self.peaks
        acquisition = self.problem.measurements.acquisition
        centres = acquisition.view_centres()[0].to(points)
        return (points - centres[view]).norm(dim=1) * (0.0 if acquisition.scans is not None else 1.0)

    def peak_caps(self, cone_deg: float) -> torch.Tensor | None:
        """(N, K, 3) each range peak's glint cap [m] within ``cone_deg`` [deg] of its line
        (:func:`~rfsdf.recon.glints.glint_caps` at :meth:`peak_ranges`), on the fit's device;
        None for a cone of 0 (the peaks read as points on their lines)."""
        if cone_deg <= 0:
            return None
        points, _, _, towards = self.peaks
        return glint_caps(points, towards, self.peak_ranges(), math.radians(cone_deg))

    def peak_lines(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Each range peak's line of sight, sampled at ``PEAK_MATCH_SAMPLES`` offsets (S,) [m]
        within +-``loss.peak_match_span_m`` of it towards its view: points (N, S, 3) [m], the
        data's image there (N, S) complex (the renderer's, formed once), and the offsets."""
        if self._peak_lines is None:
            span = self.config.loss.peak_match_span_m
            points, _, view, towards = self.peaks
            offsets = torch.linspace(-span, span, PEAK_MATCH_SAMPLES, device=self.device)
            lines = points[:, None] + offsets[None, :, None] * towards[:, None]  # (N, S, 3)
            observed = torch.zeros(lines.shape[:2], dtype=torch.complex64, device=self.device)
            with torch.no_grad():
                for v in view.unique().tolist():
                    mine = view == v
                    observed[mine] = self.renderer.observed_at(v, lines[mine].reshape(-1, 3)).reshape(-1, len(offsets))
            self._peak_lines = (lines, observed, offsets)
        return self._peak_lines

    def matched_lines(self, views: torch.Tensor) -> list[torch.Tensor | None] | None:
        """For each of ``views``, the indices of up to ``loss.peak_match_lines`` of its range
        peaks (drawn from the generator; None: it has none); None without peaks."""
        if self.peaks is None:
            return None
        most, chosen = self.config.loss.peak_match_lines, []
        for v in views.tolist():
            index = (self.peaks[2] == v).nonzero().squeeze(1)
            if len(index) > most:
                index = index[torch.randperm(len(index), generator=self.generator)[:most].to(index.device)]
            chosen.append(index if len(index) else None)
        return chosen

    def fit(self, *, resume: bool = False, on_step: Callable[[int], None] | None = None) -> FitResult:
        """Train to ``config.train.steps``; returns the field and the log. See the module docstring."""
        tc = self.config.train
        if resume and self.checkpoint_path.exists():
            self.load()
        elif self.checkpoint_path.exists():
            raise RfsdfError(f"{self.run_dir}: already holds a run; resume it or choose another output folder")
        else:
            self.run_dir.mkdir(parents=True, exist_ok=True)
            write_config(self.run_dir, self.config)
            if self.start is None:
                self.warm_start()
            else:
                self.field.load_state_dict(self.start)
            self.warm_state = {k: v.detach().clone() for k, v in self.field.state_dict().items()}
            self.save()  # a run killed from here on resumes after the warm start
        bar = progress_bar(total=tc.steps, initial=self.step, desc="fit", enabled=self.progress, leave=True)
        while self.step < tc.steps:
            clock = time.perf_counter()
            if self.renderer.candidates is None or self.step % self.config.render.refresh_every == 0:
                self.refresh_surface()
            terms = self.loss_terms()
            if not all(torch.isfinite(v) for v in terms.values()):
                bad = ", ".join(f"{k}={float(v.detach())}" for k, v in terms.items())
                raise RfsdfError(f"step {self.step}: loss is not finite ({bad}); stopped, "
                                 f"last good checkpoint kept at {self.checkpoint_path}")
            self.optimizer.zero_grad(set_to_none=True)
            terms["loss"].backward()
            self.optimizer.step()
            self.scheduler.step()
            self.step += 1
            self.log.append(StepRecord(self.step, *(float(terms[k].detach()) for k in ("loss", "data", "eikonal")),
                                       self.scheduler.get_last_lr()[0], len(self.renderer.candidates),
                                       round(time.perf_counter() - clock, 3)))
            # no forced redraw: update() draws, at most every 30 s into a log (rfsdf.progress)
            bar.set_postfix(data=f"{self.log[-1].data:.3g}", eik=f"{self.log[-1].eikonal:.3g}", refresh=False)
            bar.update(1)
            if self.step % tc.checkpoint_every == 0 or self.step == tc.steps:
                self.save()
            if on_step is not None:
                on_step(self.step)
        bar.close()
        warm = RadarField(**self.field_kwargs).to(self.device)
        warm.load_state_dict(self.warm_state)
        return FitResult(self.field, warm.eval(), self.log)
