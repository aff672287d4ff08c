"""Figures: SDF slices, matched-filter projections, training curves, and the report."""

from .projections import plot_mip
from .slices import plot_sdf_slices
from .training import plot_training_curves

__all__ = ["plot_sdf_slices", "plot_mip", "plot_training_curves"]
