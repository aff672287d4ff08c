"""GeRaF reconstruction: warm start, the surface (facets or points), coherent rendering, losses, the trainer."""

from .checkpoint import load_field, read_checkpoint
from .config import ReconConfig, load_recon_config
from .losses import DATA_LOSSES, amplitude_loss, complex_loss, eikonal_loss, power_loss
from .render import RENDERERS, CoherentRenderer
from .sampling import data_voxel_probabilities, eikonal_points, sample_data_voxels
from .schedules import SCHEDULES, constant, exponential_decay
from .surface import SurfaceCandidates, project_to_surface, surface_candidates
from .surface_mesh import SurfaceMesh, mesh_facets, surface_mesh
from .trainer import FitResult, Problem, StepRecord, Trainer

__all__ = [
    "ReconConfig", "load_recon_config", "DATA_LOSSES", "amplitude_loss", "power_loss", "complex_loss", "eikonal_loss",
    "RENDERERS", "CoherentRenderer", "data_voxel_probabilities", "eikonal_points", "sample_data_voxels",
    "SCHEDULES", "exponential_decay", "constant", "SurfaceCandidates", "surface_candidates", "project_to_surface",
    "SurfaceMesh", "surface_mesh", "mesh_facets",
    "Problem", "StepRecord", "FitResult", "Trainer", "load_field", "read_checkpoint",
]
