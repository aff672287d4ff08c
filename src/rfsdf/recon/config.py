"""Reconstruction settings (TOML, validated), with defaults sized for the presets on a CPU.

Every table and key is optional; ``rfsdf reconstruct --config FILE`` overrides the defaults
and the run folder keeps the full, resolved ``config.toml``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt

from ..config import StrictModel, load_model

__all__ = ["ReconConfig", "load_recon_config"]


class FieldConfig(StrictModel):
    levels: int | None = Field(None, ge=0, description="encoding levels; default levels_for(scene, voxel)")
    depth: int = Field(6, ge=3)
    width: PositiveInt = 128
    init_radius_m: PositiveFloat | None = None  # default: a third of the half extent
    geometric_init: bool = True
    reflectivity_width: PositiveInt = 64
    reflectivity_floor: NonNegativeFloat = 0.02


class RenderConfig(StrictModel):
    renderer: Literal["physics", "local"] = "physics"
    psf_radius_m: PositiveFloat = 0.06  # half-width of the PSF kernel the physics renderer uses
    # View weight max(0, n.u)^e; 0 turns it off. Coherent imaging sees smooth surfaces only
    # near specular, so a sharp lobe (16) matches the simulator's images best (README).
    facing_exponent: NonNegativeFloat = 16.0
    train_normals: bool = True  # the data term may turn surfaces (gradient through n)
    band_sigmas: PositiveFloat = 3.0  # c is evaluated where |f| < band_sigmas * sigma + 1 voxel
    band_refresh_every: PositiveInt = 10


class InitConfig(StrictModel):
    method: Literal["image", "sphere"] = "image"  # image: warm start from the MF image; sphere: SAL only
    threshold: float = Field(0.15, gt=0, lt=1, description="inside where MF amplitude >= threshold * peak")
    steps: NonNegativeInt = 300
    lr: PositiveFloat = 1e-3
    batch: PositiveInt = 8192


class SigmaConfig(StrictModel):
    schedule: Literal["exponential", "constant"] = "exponential"
    start_voxels: PositiveFloat = 3.0
    end_voxels: PositiveFloat = 1.0


class LossConfig(StrictModel):
    target: Literal["amplitude", "power"] = "amplitude"
    norm: Literal["l2", "huber"] = "l2"
    huber_delta: PositiveFloat = 0.05
    eikonal_weight: NonNegativeFloat = 0.01


class SamplingConfig(StrictModel):
    data_batch: PositiveInt = 8192
    data_focus: float = Field(0.5, ge=0, le=1, description="share of data voxels drawn by MF amplitude")
    views_per_step: PositiveInt = 4
    eikonal_batch: PositiveInt = 4096
    eikonal_near: float = Field(0.5, ge=0, le=1, description="share of Eikonal points near the zero set")


class TrainConfig(StrictModel):
    steps: PositiveInt = 100
    lr: PositiveFloat = 1e-4
    lr_end: PositiveFloat = 1e-5
    reflectivity_lr_scale: PositiveFloat = 10.0  # Gamma adapts faster than f: dim, don't delete
    weight_decay: NonNegativeFloat = 1e-4
    checkpoint_every: PositiveInt = 50
    seed: int = 0
    device: str = "auto"
    mesh_resolution: PositiveInt = 128


class ReconConfig(StrictModel):
    field: FieldConfig = FieldConfig()
    init: InitConfig = InitConfig()
    render: RenderConfig = RenderConfig()
    sigma: SigmaConfig = SigmaConfig()
    loss: LossConfig = LossConfig()
    sampling: SamplingConfig = SamplingConfig()
    train: TrainConfig = TrainConfig()


def load_recon_config(path=None) -> ReconConfig:
    """Defaults, or the defaults overridden by the TOML file at ``path``."""
    return ReconConfig() if path is None else load_model(ReconConfig, path)
