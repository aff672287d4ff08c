"""What a measurement set is: where each Tx and Rx was, at which frequencies, and the samples.

Layout used everywhere: V views (poses of the radar, or frames of a capture), T
transmitters, R receivers, K frequencies; ``data[v, i, j, k]`` is the sample of Tx i to
Rx j at frequency k in view v. Positions are in the scene frame, already placed by the pose.
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field

import torch

__all__ = ["Acquisition", "Measurements", "SPEED_OF_LIGHT"]

SPEED_OF_LIGHT = 299_792_458.0  # [m/s]


@dataclass(frozen=True)
class Acquisition:
    """Geometry of a measurement set (no samples).

    tx_m : (V, T, 3) float64 [m], scene frame. rx_m : (V, R, 3) float64 [m].
    frequencies_hz : (K,) float64 [Hz]. boresight : (V, 3) unit vectors, scene frame.
    pattern_exponent : antenna amplitude pattern cos^n(angle from boresight); 0 = isotropic.
    spreading : whether the 1/(d_tx d_rx) spreading factor is applied.
    """

    tx_m: torch.Tensor
    rx_m: torch.Tensor
    frequencies_hz: torch.Tensor
    boresight: torch.Tensor
    pattern_exponent: float = 0.0
    spreading: bool = True

    def __post_init__(self):
        tx, rx, f, b = self.tx_m, self.rx_m, self.frequencies_hz, self.boresight
        if tx.ndim != 3 or tx.shape[2] != 3 or rx.ndim != 3 or rx.shape[2] != 3 or rx.shape[0] != tx.shape[0]:
            raise ValueError(f"tx_m and rx_m must be (V, T, 3) and (V, R, 3), got {tuple(tx.shape)}, {tuple(rx.shape)}")
        if f.ndim != 1 or len(f) == 0 or not bool((f > 0).all()):
            raise ValueError("frequencies_hz must be a non-empty 1-D array of positive frequencies")
        if b.shape != (tx.shape[0], 3):
            raise ValueError(f"boresight must be (V, 3), got {tuple(b.shape)}")
        if self.pattern_exponent < 0:
            raise ValueError(f"pattern_exponent must be >= 0, got {self.pattern_exponent}")
        for name in ("tx_m", "rx_m", "frequencies_hz", "boresight"):
            value = getattr(self, name)
            if not torch.isfinite(value).all():
                raise ValueError(f"{name} contains NaN or Inf")
            object.__setattr__(self, name, value.detach().to(torch.float64))

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """(V, T, R, K)."""
        return (self.tx_m.shape[0], self.tx_m.shape[1], self.rx_m.shape[1], len(self.frequencies_hz))

    @property
    def num_measurements(self) -> int:
        v, t, r, k = self.shape
        return v * t * r * k

    @property
    def bandwidth_hz(self) -> float:
        """K * delta_f for uniformly spaced frequencies (the span that sets c / 2B)."""
        f = self.frequencies_hz
        return float(f.max() - f.min()) * len(f) / max(len(f) - 1, 1)

    @property
    def center_frequency_hz(self) -> float:
        return float(self.frequencies_hz.mean())

    @property
    def wavelength_m(self) -> float:
        """Wavelength at the centre frequency [m]."""
        return SPEED_OF_LIGHT / self.center_frequency_hz

    @property
    def wavenumber_rad_m(self) -> float:
        """k = 2 pi / lambda at the centre frequency [rad/m]."""
        return 2 * math.pi / self.wavelength_m

    def view(self, index: int | slice) -> Acquisition:
        """The acquisition restricted to some views."""
        sel = slice(index, index + 1) if isinstance(index, int) else index
        return Acquisition(self.tx_m[sel], self.rx_m[sel], self.frequencies_hz, self.boresight[sel],
                           self.pattern_exponent, self.spreading)

    def thinned(self, step: int) -> Acquisition:
        """A sparse sub-array: 1/``step`` of the Tx and of the Rx, step^2 fewer pairs.

        The elements kept are a fixed pseudo-random choice (the same for every call), not
        every step-th one: a regular thinning multiplies the element spacing and puts
        grating lobes into the scene, a random one only raises the sidelobe floor.
        """
        if step < 1:
            raise ValueError(f"element step must be >= 1, got {step}")
        return Acquisition(self.tx_m[:, _kept(self.tx_m.shape[1], step)], self.rx_m[:, _kept(self.rx_m.shape[1], step)],
                           self.frequencies_hz, self.boresight, self.pattern_exponent, self.spreading)


@dataclass(frozen=True)
class Measurements:
    """Samples y (V, T, R, K) complex64 of an :class:`Acquisition`, plus provenance.

    noise_std : std of the complex noise added (simulations), else None.
    metadata : free text fields (scene and radar TOML of a simulation, source file...).
    """

    acquisition: Acquisition
    data: torch.Tensor
    noise_std: float | None = None
    metadata: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        if tuple(self.data.shape) != self.acquisition.shape:
            raise ValueError(f"data must have shape (V, T, R, K) = {self.acquisition.shape}, got {tuple(self.data.shape)}")
        if not torch.isfinite(torch.view_as_real(self.data.to(torch.complex64))).all():
            raise ValueError("measurement data contain NaN or Inf")
        object.__setattr__(self, "data", self.data.to(torch.complex64))

    def thinned(self, step: int) -> Measurements:
        """The samples of :meth:`Acquisition.thinned` (the same sparse sub-array)."""
        _, t, r, _ = self.acquisition.shape
        data = self.data[:, _kept(t, step)][:, :, _kept(r, step)]
        return Measurements(self.acquisition.thinned(step), data, self.noise_std, self.metadata)


def _kept(count: int, step: int) -> torch.Tensor:
    """Sorted indices of ceil(count / step) of ``count`` elements, a fixed pseudo-random choice."""
    if step == 1:
        return torch.arange(count)
    keep = -(-count // step)
    return torch.randperm(count, generator=torch.Generator().manual_seed(count))[:keep].sort().values
