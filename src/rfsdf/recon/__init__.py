"""GeRaF reconstruction: warm start, rendering, losses, sampling, schedules, the trainer."""

from .config import ReconConfig, load_recon_config
from .losses import data_loss, eikonal_loss
from .render import LocalRenderer, PhysicsRenderer, delta_sigma, facing_weights, make_renderer
from .sampling import band_mask, data_voxel_probabilities, eikonal_points, sample_data_voxels
from .schedules import exponential_decay, sigma_at
from .trainer import Problem, Trainer, load_field

__all__ = [
    "ReconConfig", "load_recon_config", "data_loss", "eikonal_loss", "LocalRenderer", "PhysicsRenderer",
    "delta_sigma", "facing_weights", "make_renderer", "band_mask", "data_voxel_probabilities",
    "eikonal_points", "sample_data_voxels", "exponential_decay", "sigma_at", "Problem", "Trainer", "load_field",
]
