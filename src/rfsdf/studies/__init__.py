"""Studies: each claim behind the method reproduced on the library itself, as a command
(`rfsdf study NAME`) with a figure and its numbers. One module per study; see
:mod:`rfsdf.studies.base` for the shape every study has."""

from . import (
    ambiguity, basin, eikonal, eikonal_1d, eikonal_sampling, encoding_levels, geometric_init, loss_gradient,
    marching_cubes, occupancy_vs_sdf, permittivity, roughness, sigma_annealing, sphere_tracing, super_resolution,
)
from .base import run_study

_MODULES = (sphere_tracing, eikonal, eikonal_1d, encoding_levels, geometric_init, loss_gradient, marching_cubes,
            permittivity, roughness, ambiguity, occupancy_vs_sdf, eikonal_sampling, sigma_annealing,
            super_resolution, basin)
STUDIES = {module.NAME: module for module in _MODULES}

__all__ = ["STUDIES", "run_study"]
