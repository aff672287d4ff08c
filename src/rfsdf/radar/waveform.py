"""Frequency samples of a radar: OFDM subcarriers or FMCW ADC samples, and resolution formulas."""

from __future__ import annotations

import numpy as np

from .acquisition import SPEED_OF_LIGHT

__all__ = ["ofdm_frequencies", "fmcw_frequencies", "range_resolution_m", "cross_range_resolution_m",
           "unambiguous_range_m", "range_response", "range_sidelobes"]


def ofdm_frequencies(carrier_hz: float, bandwidth_hz: float, subcarriers: int) -> np.ndarray:
    """(K,) subcarrier frequencies [Hz]: spacing B/K, centred on the carrier (so B = K delta_f)."""
    if subcarriers < 1 or bandwidth_hz <= 0 or carrier_hz <= bandwidth_hz / 2:
        raise ValueError("need subcarriers >= 1, bandwidth_hz > 0 and carrier_hz > bandwidth_hz / 2")
    spacing = bandwidth_hz / subcarriers
    return carrier_hz + (np.arange(subcarriers) - (subcarriers - 1) / 2) * spacing


def fmcw_frequencies(start_hz: float, slope_hz_per_s: float, sample_rate_hz: float, samples: int) -> np.ndarray:
    """(N,) instantaneous frequencies [Hz] of the ADC samples: f_start + slope * n / f_s."""
    if samples < 1 or slope_hz_per_s <= 0 or sample_rate_hz <= 0 or start_hz <= 0:
        raise ValueError("need samples >= 1 and positive start_hz, slope_hz_per_s, sample_rate_hz")
    return start_hz + slope_hz_per_s * np.arange(samples) / sample_rate_hz


def range_resolution_m(bandwidth_hz: float) -> float:
    """c / (2 B) [m].

    >>> round(range_resolution_m(4e9), 5)  # the near-77g radar's 4 GHz
    0.03747
    """
    return SPEED_OF_LIGHT / (2 * bandwidth_hz)


def cross_range_resolution_m(wavelength_m: float, range_m: float, aperture_m: float) -> float:
    """lambda R / (2 D) [m] for a (monostatic-equivalent) aperture D at range R."""
    return wavelength_m * range_m / (2 * aperture_m)


def unambiguous_range_m(frequency_step_hz: float) -> float:
    """c / (2 delta_f) [m]: range differences beyond it alias.

    >>> round(unambiguous_range_m(4e9 / 16), 3)  # 16 frequencies over 4 GHz
    0.6
    """
    return SPEED_OF_LIGHT / (2 * frequency_step_hz)


def range_response(frequencies_hz, offsets_m) -> np.ndarray:
    """(R,) |sum_k exp(j 4 pi f_k d / c)| / K: the amplitude at range offsets d [m] (R,) of a
    point target's range profile (unweighted matched filter over the frequencies), peak 1 at 0."""
    f = np.asarray(frequencies_hz, float)
    d = np.asarray(offsets_m, float)
    return np.abs(np.exp(4j * np.pi * np.outer(d, f) / SPEED_OF_LIGHT).sum(1)) / len(f)


def range_sidelobes(frequencies_hz) -> tuple[float, float]:
    """(first null [m], peak sidelobe amplitude) of :func:`range_response`, searched up to half
    the unambiguous range of the smallest frequency step. For K uniform frequencies over a
    band B: c / 2B and about 0.22 (-13 dB) for K >= 10. One frequency: (inf, 1.0)."""
    f = np.sort(np.asarray(frequencies_hz, float))
    if len(f) < 2 or f[-1] == f[0]:
        return float("inf"), 1.0
    span = 0.5 * unambiguous_range_m(float(np.diff(f)[np.diff(f) > 0].min()))
    offsets = np.linspace(0.0, span, 20_000)
    response = range_response(f, offsets)
    rising = np.flatnonzero(np.diff(response) > 0)  # the first rise ends the main lobe at its null
    if len(rising) == 0:
        return float("inf"), 1.0
    null = int(rising[0])
    return float(offsets[null]), float(response[null:].max())
