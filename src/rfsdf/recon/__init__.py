"""GeRaF reconstruction: warm start, surface sampling, coherent rendering, losses, the trainer."""

from .checkpoint import load_field, read_checkpoint
from .config import ReconConfig, load_recon_config
from .losses import DATA_LOSSES, amplitude_loss, eikonal_loss, power_loss
from .render import RENDERERS, CoherentRenderer
from .sampling import data_voxel_probabilities, eikonal_points, sample_data_voxels
from .schedules import SCHEDULES, constant, exponential_decay
from .surface import SurfaceCandidates, project_to_surface, surface_candidates
from .trainer import FitResult, Problem, StepRecord, Trainer

__all__ = [
    "ReconConfig", "load_recon_config", "DATA_LOSSES", "amplitude_loss", "power_loss", "eikonal_loss",
    "RENDERERS", "CoherentRenderer", "data_voxel_probabilities", "eikonal_points", "sample_data_voxels",
    "SCHEDULES", "exponential_decay", "constant", "SurfaceCandidates", "surface_candidates", "project_to_surface",
    "Problem", "StepRecord", "FitResult", "Trainer", "load_field", "read_checkpoint",
]
