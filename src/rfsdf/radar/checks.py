"""Does a radar see a scene without ambiguity? Grating lobes, range aliasing, beam coverage.

Each check raises RfsdfError with one line naming the radar field to change. They are
approximations (far-field grating-lobe rule on the Tx-Rx midpoint "virtual" array).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import RfsdfError
from .acquisition import SPEED_OF_LIGHT
from .system import Radar
from .waveform import unambiguous_range_m

__all__ = ["check_radar_for_scene", "check_material_in_band", "check_materials_in_band", "max_virtual_spacing_m"]


def _corners(lower_m, upper_m) -> np.ndarray:
    return np.array(list(itertools.product(*zip(lower_m, upper_m))), dtype=float)


def max_virtual_spacing_m(radar: Radar) -> float:
    """Largest gap between neighbouring distinct Tx-Rx midpoint coordinates along x or y [m]."""
    virtual = 0.5 * (radar.tx_m[:, None, :2] + radar.rx_m[None, :, :2]).reshape(-1, 2)
    gaps = []
    for axis in range(2):
        coords = np.unique(np.round(virtual[:, axis], 9))
        if len(coords) > 1:
            gaps.append(np.diff(coords).max())
    return float(max(gaps)) if gaps else 0.0


def check_radar_for_scene(radar: Radar, lower_m, upper_m, *, source: str = "radar") -> None:
    """Raise RfsdfError when ``radar`` cannot image the box [lower_m, upper_m] unambiguously."""
    corners = _corners(lower_m, upper_m)
    centre = corners.mean(axis=0)
    boresights = radar.rotations[:, :, 2]
    sin_half = 0.0
    extent = 0.0
    for v, (origin, axis) in enumerate(zip(radar.positions_m, boresights)):
        inside = bool(np.all((origin >= np.asarray(lower_m)) & (origin <= np.asarray(upper_m))))
        if not inside:  # a radar inside the scene (a room) looks at whatever is in front of it
            to_centre = centre - origin
            angle = np.arccos(np.clip(to_centre @ axis / np.linalg.norm(to_centre), -1, 1))
            if angle >= np.pi / 2:
                raise RfsdfError(f"{source}: views: the scene is behind the radar in view {v}")
            if radar.pattern_exponent > 0 and angle > (half_power := np.arccos(0.5 ** (1 / (2 * radar.pattern_exponent)))):
                raise RfsdfError(f"{source}: antenna.pattern_exponent: the scene centre is outside the "
                                 f"{np.degrees(half_power):.0f} deg half-power beam in view {v}")
        rel = corners - origin
        dist = np.linalg.norm(rel, axis=1)
        sin_half = max(sin_half, float(np.sqrt(np.clip(1 - (rel @ axis / dist) ** 2, 0, 1)).max()))
        extent = max(extent, float(dist.max() - (0.0 if inside else dist.min())))
    freqs = np.sort(radar.frequencies_hz)
    if len(freqs) > 1:
        r_max = unambiguous_range_m(float(np.diff(freqs).min()))
        if r_max < extent:
            raise RfsdfError(f"{source}: waveform: unambiguous range {r_max:.3g} m is shorter than the scene depth "
                             f"{extent:.3g} m; use more subcarriers/samples over the same bandwidth")
    spacing = max_virtual_spacing_m(radar)
    limit = SPEED_OF_LIGHT / freqs.max() / (4 * max(sin_half, 1e-6))
    if spacing > limit * (1 + 1e-6):
        raise RfsdfError(f"{source}: array: virtual element spacing {spacing * 1e3:.2f} mm puts grating lobes inside "
                         f"the scene (needs <= {limit * 1e3:.2f} mm here); use more elements, a smaller array or a "
                         f"larger views.distance_m")


def check_material_in_band(material, radar: Radar, *, where: str) -> None:
    """Raise RfsdfError 'where: reason' when ``material`` (a :class:`~rfsdf.materials.Material`)
    has no permittivity model over the radar's band (e.g. ITU-R brick stops at 40 GHz)."""
    try:  # every frequency: two parameter sets' bands may leave a gap inside the radar's band
        for frequency_hz in np.unique(radar.frequencies_hz):
            material.permittivity(float(frequency_hz))
    except ValueError as exc:
        raise RfsdfError(f"{where}: {exc}") from None


def check_materials_in_band(scene, radar: Radar, *, source: str = "scene") -> None:
    """:func:`check_material_in_band` for every object of ``scene``, before any work rather
    than mid-simulation."""
    for obj in scene.objects:
        check_material_in_band(obj.material, radar, where=f"{source}: object {obj.name!r}")
