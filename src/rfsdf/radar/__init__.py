"""Radar: system model, matrix-free sensing operator, simulator, matched-filter imaging, files.

Layout of every measurement set: (V views, T Tx, R Rx, K frequencies); see
:mod:`rfsdf.radar.acquisition`.
"""

from .acquisition import SPEED_OF_LIGHT, Acquisition, Measurements
from .checks import check_materials_in_band, check_radar_for_scene
from .imaging import Image, half_power_width, matched_filter, point_spread
from .io import import_fmcw, parse_bounds, read_image, read_measurements, write_image, write_measurements
from .operator import SensingOperator
from .simulate import simulate
from .system import Radar, load_radar, radar_presets
from .waveform import (
    cross_range_resolution_m, fmcw_frequencies, ofdm_frequencies, range_resolution_m, unambiguous_range_m,
)

__all__ = [
    "SPEED_OF_LIGHT", "Acquisition", "Measurements", "SensingOperator", "Radar", "load_radar", "radar_presets",
    "check_radar_for_scene", "check_materials_in_band", "simulate", "Image", "matched_filter", "point_spread",
    "half_power_width",
    "read_measurements", "write_measurements", "read_image", "write_image", "import_fmcw", "parse_bounds",
    "ofdm_frequencies", "fmcw_frequencies", "range_resolution_m", "cross_range_resolution_m", "unambiguous_range_m",
]
