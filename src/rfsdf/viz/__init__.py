"""Figures: SDF slices, matched-filter projections, training curves (matplotlib); 3-D views
(plotly) in :mod:`rfsdf.viz.scene3d`."""

from .projections import plot_mip
from .slices import plot_object_slices, plot_sdf_slices
from .training import plot_training_curves

__all__ = ["plot_sdf_slices", "plot_object_slices", "plot_mip", "plot_training_curves"]
