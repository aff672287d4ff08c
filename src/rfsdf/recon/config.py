"""Reconstruction settings (TOML, validated), with defaults sized for the presets on a CPU.

Every table and key is optional; ``rfsdf reconstruct --config FILE`` overrides the defaults
and the run folder keeps the full, resolved ``config.toml``. Names of renderers, losses and
schedules are checked against their registries when the file is read.
"""

from __future__ import annotations

from typing import Literal

from pydantic import (
    Field, NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt, field_validator, model_validator,
)

from ..config import StrictModel, load_model
from ..materials import MATERIAL_CLASSES
from .losses import BENDING_STEP_M

__all__ = ["ReconConfig", "load_recon_config"]


class FieldConfig(StrictModel):
    levels: int | None = Field(None, ge=0, description="encoding levels; default levels_for(scene, voxel)")
    depth: int = Field(6, ge=3)
    width: PositiveInt = 128
    init_radius_m: PositiveFloat | None = None  # default: a third of the half extent
    geometric_init: bool = True
    reflectivity_width: PositiveInt = 64
    reflectivity_floor: NonNegativeFloat = 0.02
    # the material head's classes (catalogue names, rfsdf.materials): the renderer reflects
    # each surface sample by the Fresnel coefficient of its material; [] fits a free
    # reflectivity instead (the option kept for comparison)
    materials: list[str] = list(MATERIAL_CLASSES)
    # knots [m] of a coarse displacement of the warm start's surface (rfsdf.field.displacement):
    # set, the fit moves f only through it (the network's geometry stays as the warm start left
    # it); None: the fit moves the network itself
    displacement_knot_m: PositiveFloat | None = None

    @field_validator("materials")
    @classmethod
    def _catalogue_materials(cls, names: list[str]) -> list[str]:
        from ..materials import get_material

        canonical = [get_material(name).name for name in names]
        if len(set(canonical)) != len(canonical):
            raise ValueError(f"each material class once, got {names}")
        return canonical


class InitConfig(StrictModel):
    # mf: threshold the matched-filter image; clean: threshold its CLEAN image; sphere: SAL only
    method: Literal["mf", "clean", "sphere"] = "clean"
    # "auto": CLEAN's residual floor (CleanResult.residual_floor), so the threshold follows the
    # radar and the scene (0.063 on the demo, 0.024 on the garage, where a fixed 0.06 lost the
    # glass ball; docs/results/demo-quality.md, "The data-derived threshold"); or a fraction of the peak amplitude
    threshold: float | str = Field("auto", description="inside needs amplitude >= threshold * peak ...")
    local_threshold: float = Field(0.5, ge=0, lt=1, description="... and >= local_threshold * local peak")
    window_m: PositiveFloat = 0.03  # edge of the local-peak window [m]
    closing_m: NonNegativeFloat = 0.012  # morphological closing of the detections, radius [m]
    steps: NonNegativeInt = 300
    lr: PositiveFloat = 1e-3
    batch: PositiveInt = 8192
    # share of each batch drawn within a voxel of the target's zero set: with a uniform batch
    # the 2.5 cm metal ball got ~30 points a step and half its surface (docs/results/demo-quality.md)
    near_share: float = Field(0.25, ge=0, le=1)
    # the warm start's own Eikonal weight: the image it fits is rough, and at the fit's
    # lower weight the warm start got worse (docs/results/demo-quality.md)
    eikonal_weight: NonNegativeFloat = 0.01
    # remove from the detection the voxels in front of a view's range ridge (the blob's half
    # that stands before the seen face; radar.detection.in_front_of_ridges)
    carve_front: bool = True
    # remove the detections that no view shows as more than a range sidelobe of a brighter
    # glint on its line of sight (radar.detection.on_range_sidelobes): the floaters a few
    # centimetres off the objects (docs/results/quality-history.md, "Range-sidelobe blanking")
    blank_range_sidelobes: bool = True
    # how far along each view's line of sight a brighter glint is looked for [range resolutions]:
    # 8 (30 cm at 4 GHz) reaches the demo's floaters 4-24 cm off their glint (4: observed
    # Chamfer 4.89 mm, 8: 4.30), and left the tabletop's warm start unchanged
    # (docs/results/demo-quality.md, "The floaters are far range sidelobes")
    sidelobe_reach: PositiveFloat = 8.0
    # ... and weaker than this fraction of the brighter voxel there (two opaque surfaces on one
    # line of sight cannot both be lit by a view; an extended glint's far artifacts are 2-30x a
    # point's sidelobes). 0.5: demo warm start 4.11-4.36 -> 3.08-3.54 mm observed over three seeds,
    # every untuned scene's detection better (docs/results/demo-quality.md, "Opaque lines of
    # sight"); None: the waveform's peak range sidelobe (0.22, the earlier rule)
    sidelobe_level: float | None = Field(0.5, gt=0, le=1)
    # with method "clean": also blank what is a sidelobe in the matched-filter per-view images,
    # not only in CLEAN's (CLEAN keeps a far sidelobe as a component of its own). Demo 4.30 ->
    # 3.16 mm, but tabletop 4.29 -> 4.58 (real faces dropped), so off by default
    sidelobes_in_mf: bool = False
    # turn the faces the views see towards the power-weighted mean bisector of those views
    # (radar.specular.specular_normals): the detection's boundary has the blur's shape, not
    # the surface's, and its normals on the seen faces were 42 degrees off (12 with 0.01;
    # docs/results/demo-quality.md, "Normals from the views"); 0 turns it off
    normal_weight: NonNegativeFloat = 0.01
    # pull the zero set through each view's range ridges refined along its line of sight on
    # its matched filter (radar.range_peaks: 4.0 -> 1.2 mm from the truth, median, on the
    # demo), weight of that L1 term beside the target's; 0 turns it off
    peak_weight: NonNegativeFloat = 1.0
    # ... and turn its normal towards the view at each glint's centre (a glint is a specular
    # return: the surface there faces its view, within the array's cone), weight of the mean
    # 1 - cos beside it; needs the peaks (peak_weight > 0); 0 (the default) turns it off: at
    # 0.3 the demo's fit ends 0.1-0.3 mm nearer on the seen surface, but its glints render too
    # bright for the materials (docs/results/demo-quality.md, "Normals at the range peaks")
    peak_normal_weight: NonNegativeFloat = 0.0
    # the warm start's bending energy (LossConfig.bending_weight's term, at the near points,
    # offsets of LossConfig.bending_step_m); its misfit is in metres, so a few thousandths
    # weigh what 1 does in the fit (1 flattened the demo's objects: 10 mm observed); 0: off
    bending_weight: NonNegativeFloat = 0.0
    # a glint's centre: a range peak that is the strongest of its view's within this [m]
    # (RangePeaks.apexes); the peaks beside it stand on its tangent plane, and a normal turned
    # there too flattens a curved glint (a metal ball's read 2.4x too bright); 0: every peak
    peak_apex_m: NonNegativeFloat = 0.012
    # the primitives (``primitives``) read each range peak as a glint (recon.glints): the sphere
    # of its range about its view's centre touches the surface within this cone [deg] about its
    # line; 0: the surface crosses the line at the peak. On the true surfaces the demo's peaks
    # stand 0.55 mm off their lines' (median), 0.03 mm off the 0.25-degree caps'
    # (benchmarks/peak_model.py); a planar scan's parallel lines keep 0 (their ranges are 0)
    peak_cone_deg: float = Field(0.25, ge=0, le=5)
    # leave out of the range peaks, and of the detection where no view sees more, what a
    # view's glints explain in its own image as their sidelobes (range and lateral:
    # radar.glint_sidelobes): a metal ball's had held a lump 4 mm outside its far side, and
    # were detections 3-4 cm off it (docs/results/demo-quality.md, "Peaks on sidelobes"); needs the
    # range peaks (a peak weight above 0); False keeps them, as before
    glint_sidelobes: bool = True
    # seen through a known scene (Problem.through: a box whose own return was subtracted),
    # what is left at its walls is no object's (the objects shadow part of the far walls, the
    # empty box's capture does not): the voxels within this distance [m] of the known
    # scene's objects, or in them, and outside the cavity they close (a box's inside) take
    # no part in the detection nor in the range peaks (warm_start.known_exclusion)
    known_margin_m: NonNegativeFloat = 0.003
    # after the warm start, replace each of its fragments by the sphere, box, cylinder, capsule or torus
    # that explains the fragment's range peaks (recon.object_primitives), and regress the
    # network onto that target (400 steps from the warm start's rate, decayed); needs the range peaks
    # (docs/results/demo-quality.md, "Primitives for the warm start's fragments"; the default since
    # the seventieth session: demo 1.93 -> 0.70 mm observed, 64 % removed). False: the warm start alone
    primitives: bool = True

    @field_validator("threshold", mode="before")
    @classmethod
    def _threshold(cls, value):
        if value == "auto":
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1:
            raise ValueError(f'must be "auto" or a number between 0 and 1, got {value!r}')
        return float(value)

    @model_validator(mode="after")
    def _auto_needs_clean(self):
        if self.method == "mf" and self.threshold == "auto":
            raise ValueError('threshold "auto" is the CLEAN residual floor; with method = "mf" give a number')
        return self


class RenderConfig(StrictModel):
    renderer: str = "coherent"
    element_step: PositiveInt = 2  # image data and prediction with every n-th Tx and Rx (n^2 fewer pairs)
    # image data and prediction with every n-th frequency: n x fewer, the same band and range
    # resolution, an n x shorter unambiguous range (refused where that is shorter than the
    # grid's paths); for data with many frequencies, as a scan's
    frequency_step: PositiveInt = 1
    # facets: flat triangles of f = 0 with their phase integrated (the converged quadrature, as
    # the simulator's); points: random points near it (a Monte Carlo quadrature, for comparison)
    surface: Literal["facets", "points"] = "facets"
    spacing_m: PositiveFloat | None = None  # the facets' marching-cubes cell or the points' spacing; default lambda / 3
    shadows: bool = True
    refresh_every: PositiveInt = 10  # steps between new surface samples (and facing/shadow masks)
    # local mean of the surface velocity over this radius [m] (a Sobolev-type gradient); None:
    # 6 mm for points, whose speckle makes each sample's force random, 0 for facets, whose
    # forces are not: there the mean erased the tilt a facet's neighbours ask for, and a fit
    # started on the true ball roughened it (docs/results/demo-quality.md, "The surface's own gradient")
    smoothing_m: NonNegativeFloat | None = None

    @property
    def surface_smoothing_m(self) -> float:
        """``smoothing_m``, or its default for ``surface``."""
        if self.smoothing_m is not None:
            return self.smoothing_m
        return 0.006 if self.surface == "points" else 0.0

    @field_validator("renderer")
    @classmethod
    def _known_renderer(cls, name: str) -> str:
        from .render import RENDERERS

        RENDERERS.get(name)
        return name


class LossStage(StrictModel):
    """One stage of a continuation: the data loss ``data`` until the share ``until`` of the steps."""

    data: str
    until: float = Field(gt=0, le=1, description="share of the steps at which this stage ends")

    @field_validator("data")
    @classmethod
    def _known_loss(cls, name: str) -> str:
        from .losses import DATA_LOSSES

        DATA_LOSSES.get(name)
        return name


class LossConfig(StrictModel):
    data: str = "amplitude"  # the data loss of every step, when no stages are given
    # (ReconConfig's default, when neither is given, is the continuation amplitude -> split)
    # a continuation: data losses in turn, each until its share of the steps (the last until
    # 1), e.g. amplitude while the surface is too far for the phase, then "complex" (recon/losses.py)
    stages: list[LossStage] = []
    eikonal_weight: NonNegativeFloat = 0.01
    # mean entropy of the material probabilities on the surface: favours decisive classes
    material_entropy_weight: NonNegativeFloat = 0.01
    # cross-entropy against known labels (Problem.material_labels), only where they are given
    material_label_weight: NonNegativeFloat = 1.0
    # hold the zero set through the warm start's range peaks while the geometry moves: this
    # times the amplitude-weighted mean |f| [m] over all of them, each step (the peaks place
    # the seen faces to 1.1 mm, finer than the pooled amplitude loss sees; docs/results/
    # demo-quality.md, "The peaks held in the fit"); 0 leaves them to the warm start
    peak_weight: NonNegativeFloat = 1000.0
    # hold each peak as a glint (recon/glints.py; ``[init] peak_cone_deg``): the least f over
    # its range sphere's cap within this cone [deg] of its line, not f at the peak; 0: on the
    # line. With the primitives read so the demo's ball keeps its sphere (0.36 mm, held on the
    # lines 0.76); from the warm start alone ([init] primitives false) the fit ended further off
    # (docs/results/demo-quality.md)
    peak_cone_deg: float = Field(0.25, ge=0, le=5)
    # move the predicted images' range peaks onto the data's, along the lines of sight of the
    # warm start's range peaks, while the geometry moves: this times the mean pseudo-Huber
    # misfit of their positions (in mm, knee 1 mm; recon/losses.py, peak_match_loss); each
    # step up to ``peak_match_lines`` lines a view, sampled at five points within
    # +-``peak_match_span_m`` of the peak; 0: off
    peak_match_weight: NonNegativeFloat = 0.0
    peak_match_lines: PositiveInt = 512
    peak_match_span_m: PositiveFloat = 0.006
    # bending energy while the geometry moves: this times the mean |n(p + o) - n(p)|^2 of the
    # unit normals at ``bending_points`` surface samples p and a random offset o of
    # ``bending_step_m`` (recon/losses.py, normal_variation): the thin-plate prior against
    # ripples of the zero set; at 1 the demo's fit ends as without it (docs/results/
    # demo-quality.md, "Tilted surfaces"); 0: off
    bending_weight: NonNegativeFloat = 0.0
    bending_step_m: PositiveFloat = BENDING_STEP_M
    bending_points: PositiveInt = 2048

    @field_validator("data")
    @classmethod
    def _known_loss(cls, name: str) -> str:
        from .losses import DATA_LOSSES

        DATA_LOSSES.get(name)
        return name

    @field_validator("stages")
    @classmethod
    def _a_schedule(cls, stages: list[LossStage]) -> list[LossStage]:
        ends = [stage.until for stage in stages]
        if stages and (any(b <= a for a, b in zip(ends, ends[1:])) or ends[-1] != 1):
            raise ValueError(f"each stage must end after the one before and the last at 1, got until = {ends}")
        return stages

    def names(self) -> list[str]:
        """Every data loss the fit uses: the stages', or ``data``."""
        return [stage.data for stage in self.stages] or [self.data]

    def stage_at(self, fraction: float) -> str:
        """The data loss at ``fraction`` (0 to 1) of the steps."""
        if not self.stages:
            return self.data
        return next((stage.data for stage in self.stages if fraction < stage.until), self.stages[-1].data)


class SamplingConfig(StrictModel):
    views_per_step: PositiveInt = 6
    data_batch: PositiveInt = 4096  # data voxels per step
    cell_voxels: PositiveInt = 2  # compare RMS amplitudes over cubes of this many voxels per edge
    # coarse to fine: cubes of this edge when f starts to move, shrinking linearly to
    # cell_voxels at the last step (None: cell_voxels throughout; study "sigma-annealing")
    cell_voxels_start: PositiveInt | None = None
    data_focus: float = Field(0.5, ge=0, le=1, description="share of data voxels drawn by MF amplitude")
    eikonal_batch: PositiveInt = 4096
    eikonal_near: float = Field(0.5, ge=0, le=1, description="share of Eikonal points near the zero set")


class TrainConfig(StrictModel):
    # from the primitives' start 50 steps end where 100 do (demo 1.16 mm observed either way) in
    # half the time (docs/results/demo-quality.md, "Fewer steps from a primitive start")
    steps: PositiveInt = 50
    lr: PositiveFloat = 1e-4
    lr_end: PositiveFloat = 1e-5
    schedule: str = "exponential"
    reflectivity_lr_scale: PositiveFloat = 10.0  # Gamma adapts faster than f: dim, don't delete
    # the material head's learning rate over lr: at 10 x the demo's 1e-4 it had not left the
    # uniform start after 100 steps (p 0.21 of 5 classes everywhere); 300 in the default 50 steps
    material_lr_scale: PositiveFloat = 300.0
    # f is frozen for this share of the steps while Gamma adapts: started at the true scene,
    # the fit drifts 1.8 mm without the delay, 0.4 mm with 0.4; from the carved, blanked warm
    # start 0.7 scores 4.82 mm over three seeds against 4.92 at 0.4 (docs/results/quality-history.md)
    geometry_delay: float = Field(0.7, ge=0, lt=1)
    # the geometry's schedule: "shared", the one decay over every step (so f, freed at 0.7,
    # moves at lr 2e-5 -> 1e-5), or "from_release", the whole decay lr -> lr_end over the
    # steps f is free
    geometry_schedule: Literal["shared", "from_release"] = "shared"
    weight_decay: NonNegativeFloat = 0.0
    checkpoint_every: PositiveInt = 50
    seed: int = 0
    device: str = "auto"
    mesh_resolution: PositiveInt = 128

    @property
    def geometry_delay_steps(self) -> int:
        """Steps during which f is frozen (``geometry_delay`` of ``steps``)."""
        return int(self.geometry_delay * self.steps)

    @field_validator("schedule")
    @classmethod
    def _known_schedule(cls, name: str) -> str:
        from .schedules import SCHEDULES

        SCHEDULES.get(name)
        return name


class CalibrationConfig(StrictModel):
    # "NAME=MATERIAL": the scene's object NAME is of MATERIAL, one of field.materials; its
    # surface is rendered as that material whatever the head says, so the gain fitted at each
    # step makes its |Gamma| right and the other classes absolute (rfsdf.recon.calibration).
    # None: materials are relative.
    reference: str | None = None
    # how near the reference's surface [m] a surface sample counts as the reference
    reference_distance_m: PositiveFloat = 0.01
    # a known radar gain [data units per renderer unit] (a calibration capture's, `rfsdf
    # calibrate`; 1 for rfsdf's simulated data). The fit stays relative (one gain fitted at each
    # step) and its materials are read in this gain after it: the head's reflectivities and the
    # closed-form readout times the fitted gain over this one. Held in the loss instead, the head
    # learned only the scene's mean level (docs/results/materials.md). None: no known gain.
    gain: PositiveFloat | None = None

    @field_validator("reference")
    @classmethod
    def _name_and_material(cls, text: str | None) -> str | None:
        if text is None:
            return None
        from ..materials import get_material

        name, sep, material = text.partition("=")
        if not sep or not name.strip() or not material.strip():
            raise ValueError(f"expected NAME=MATERIAL (an object of the scene and its material), got {text!r}")
        return f"{name.strip()}={get_material(material.strip()).name}"

    @model_validator(mode="after")
    def _one_calibration(self) -> CalibrationConfig:
        if self.reference is not None and self.gain is not None:
            raise ValueError("reference and gain: one calibration, not both (a reference calibrates the gain itself)")
        return self

    @property
    def reference_object(self) -> str | None:
        return None if self.reference is None else self.reference.partition("=")[0]

    @property
    def reference_material(self) -> str | None:
        return None if self.reference is None else self.reference.partition("=")[2]


class ReconConfig(StrictModel):
    field: FieldConfig = FieldConfig()
    init: InitConfig = InitConfig()
    render: RenderConfig = RenderConfig()
    loss: LossConfig = LossConfig()
    sampling: SamplingConfig = SamplingConfig()
    train: TrainConfig = TrainConfig()
    calibration: CalibrationConfig = CalibrationConfig()

    @model_validator(mode="before")
    @classmethod
    def _default_continuation(cls, values):
        """Neither ``loss.data`` nor ``loss.stages`` given: the amplitude loss while f is frozen
        (``train.geometry_delay``), then split-spectrum interferometry, which sees position,
        once it moves (issue 51; docs/results/demo-quality.md, "The split stage by default")."""
        if not isinstance(values, dict) or not isinstance(values.get("loss", {}), dict):
            return values
        loss = values.get("loss", {})
        if "data" in loss or "stages" in loss:
            return values
        train = values.get("train", {})
        delay = train.get("geometry_delay", 0.7) if isinstance(train, dict) else getattr(train, "geometry_delay", None)
        if isinstance(delay, bool) or not isinstance(delay, int | float) or not 0 <= delay < 1:
            return values  # train.geometry_delay's own validation says what is wrong with it
        stages = [{"data": "amplitude", "until": delay}] if delay > 0 else []
        return {**values, "loss": {**loss, "stages": [*stages, {"data": "split", "until": 1.0}]}}

    @model_validator(mode="after")
    def _reference_is_a_class(self) -> ReconConfig:
        material = self.calibration.reference_material
        if material is not None and material not in self.field.materials:
            raise ValueError(f"calibration.reference: {material!r} is not one of field.materials "
                             f"{self.field.materials} (a reference calibrates the material head's classes)")
        return self

    def on_device(self, device) -> ReconConfig:
        """The same settings with ``train.device`` set to ``device`` (a name or a torch.device)."""
        return self.model_copy(update={"train": self.train.model_copy(update={"device": str(device)})})


def load_recon_config(path=None) -> ReconConfig:
    """Defaults, or the defaults overridden by the TOML file at ``path``."""
    return ReconConfig() if path is None else load_model(ReconConfig, path)
