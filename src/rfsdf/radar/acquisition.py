"""What a measurement set is: where each Tx and Rx was, at which frequencies, and the samples.

Layout used everywhere: V frames (poses of the radar, or frames of a capture), T
transmitters, R receivers, K frequencies; ``data[v, i, j, k]`` is the sample of Tx i to
Rx j at frequency k in frame v. Positions are in the scene frame, already placed by the pose.

A view is what is imaged coherently: by default each frame (a MIMO snapshot), or, with
``scans``, every frame of one scan (a board moved over a synthetic aperture, each frame
pairing only its own Tx and Rx, one scan a view at each turntable angle).
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field, replace

import torch

__all__ = ["Acquisition", "Measurements", "SPEED_OF_LIGHT", "swept_bandwidth_hz"]

SPEED_OF_LIGHT = 299_792_458.0  # [m/s]


def swept_bandwidth_hz(frequencies_hz) -> float:
    """K * delta_f [Hz] of K uniformly spaced frequencies (K,) (a NumPy array or a tensor):
    the span that sets the range resolution c / 2B, one step wider than max - min.

    >>> swept_bandwidth_hz(torch.tensor([77e9, 78e9, 79e9, 80e9], dtype=torch.float64)) / 1e9
    4.0
    """
    f = frequencies_hz
    return float(f.max() - f.min()) * len(f) / max(len(f) - 1, 1)


@dataclass(frozen=True)
class Acquisition:
    """Geometry of a measurement set (no samples).

    tx_m : (V, T, 3) float64 [m], scene frame. rx_m : (V, R, 3) float64 [m].
    frequencies_hz : (K,) float64 [Hz]. boresight : (V, 3) unit vectors, scene frame.
    pattern_exponent : antenna amplitude pattern cos^n(angle from boresight); 0 = isotropic.
    spreading : whether the 1/(d_tx d_rx) spreading factor is applied.
    scans : (V,) int64, the view (scan) 0..S-1 each frame belongs to, every number used; None:
    every frame is its own view.
    """

    tx_m: torch.Tensor
    rx_m: torch.Tensor
    frequencies_hz: torch.Tensor
    boresight: torch.Tensor
    pattern_exponent: float = 0.0
    spreading: bool = True
    scans: torch.Tensor | None = None

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
        if self.scans is not None:
            scans = torch.as_tensor(self.scans).detach().cpu()
            if scans.shape != (tx.shape[0],) or scans.is_floating_point() or scans.is_complex():
                raise ValueError(f"scans must be (V,) = ({tx.shape[0]},) integers, got {tuple(scans.shape)} {scans.dtype}")
            if len(scans) and (scans.min() < 0 or len(torch.unique(scans)) != int(scans.max()) + 1):
                raise ValueError("scans must number the views 0, 1, ... with every number used")
            object.__setattr__(self, "scans", scans.to(torch.int64))

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """(V, T, R, K)."""
        return (self.tx_m.shape[0], self.tx_m.shape[1], self.rx_m.shape[1], len(self.frequencies_hz))

    @property
    def num_views(self) -> int:
        """Views imaged coherently: the scans, or the frames."""
        return self.shape[0] if self.scans is None else int(self.scans.max()) + 1

    def frames(self, view: int) -> torch.Tensor:
        """(F,) int64 indices of the frames of view ``view``."""
        if not 0 <= view < self.num_views:
            raise IndexError(f"view {view} of {self.num_views}")
        return torch.tensor([view]) if self.scans is None else torch.nonzero(self.scans == view).squeeze(1)

    def coherent_view(self, view: int) -> Acquisition:
        """The frames of view ``view`` alone, as one acquisition (``scans`` None)."""
        sub = self.view(self.frames(view))
        return replace(sub, scans=None)

    def view_elements(self, view: int) -> tuple[torch.Tensor, torch.Tensor]:
        """Every Tx (F T, 3) and Rx (F R, 3) [m] of view ``view``'s frames."""
        frames = self.frames(view)
        return self.tx_m[frames].reshape(-1, 3), self.rx_m[frames].reshape(-1, 3)

    def view_centres(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The Tx and Rx phase centres (num_views, 3) [m] of each view: its elements' mean."""
        if self.scans is None:
            return self.tx_m.mean(1), self.rx_m.mean(1)
        tx, rx = zip(*(self.view_elements(v) for v in range(self.num_views)))
        return torch.stack([t.mean(0) for t in tx]), torch.stack([r.mean(0) for r in rx])

    @property
    def num_measurements(self) -> int:
        v, t, r, k = self.shape
        return v * t * r * k

    @property
    def bandwidth_hz(self) -> float:
        """K * delta_f [Hz] (:func:`swept_bandwidth_hz`)."""
        return swept_bandwidth_hz(self.frequencies_hz)

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

    def view(self, index: int | slice | torch.Tensor) -> Acquisition:
        """The acquisition restricted to some frames (an int, a slice or (F,) indices); their
        scans renumbered in order."""
        sel = slice(index, index + 1) if isinstance(index, int) else index
        scans = None if self.scans is None else torch.unique(self.scans[sel], return_inverse=True)[1]
        return Acquisition(self.tx_m[sel], self.rx_m[sel], self.frequencies_hz, self.boresight[sel],
                           self.pattern_exponent, self.spreading, scans)

    def thinned(self, step: int) -> Acquisition:
        """A sparse sub-array: 1/``step`` of the Tx and of the Rx, step^2 fewer pairs; of a
        scanned acquisition (``scans``), 1/step^2 of each scan's frames instead.

        The elements kept are a fixed pseudo-random choice (the same for every call), not
        every step-th one: a regular thinning multiplies the element spacing and puts
        grating lobes into the scene, a random one only raises the sidelobe floor.
        """
        if step < 1:
            raise ValueError(f"element step must be >= 1, got {step}")
        if self.scans is not None:
            return self.view(self.thinned_frames(step))
        return Acquisition(self.tx_m[:, _kept(self.tx_m.shape[1], step)], self.rx_m[:, _kept(self.rx_m.shape[1], step)],
                           self.frequencies_hz, self.boresight, self.pattern_exponent, self.spreading)

    def every_frequency(self, step: int) -> Acquisition:
        """Every ``step``-th frequency (from the first): the same band, step x shorter
        unambiguous range c / (2 step df)."""
        if step < 1:
            raise ValueError(f"frequency step must be >= 1, got {step}")
        return replace(self, frequencies_hz=self.frequencies_hz[::step])

    def thinned_frames(self, step: int) -> torch.Tensor:
        """(F,) sorted indices of the frames :meth:`thinned` keeps of a scanned acquisition:
        a fixed pseudo-random 1/step^2 of each scan's frames."""
        kept = [frames[_kept(len(frames), step * step)] for frames in map(self.frames, range(self.num_views))]
        return torch.cat(kept).sort().values


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
        if self.acquisition.scans is not None:
            frames = self.acquisition.thinned_frames(step)
            return Measurements(self.acquisition.view(frames), self.data[frames], self.noise_std, self.metadata)
        _, t, r, _ = self.acquisition.shape
        data = self.data[:, _kept(t, step)][:, :, _kept(r, step)]
        return Measurements(self.acquisition.thinned(step), data, self.noise_std, self.metadata)

    def every_frequency(self, step: int) -> Measurements:
        """The samples of :meth:`Acquisition.every_frequency`."""
        return Measurements(self.acquisition.every_frequency(step), self.data[..., ::step], self.noise_std, self.metadata)

    def coherent_view(self, view: int) -> Measurements:
        """The frames of view ``view`` alone (:meth:`Acquisition.coherent_view`) and their samples."""
        acq = self.acquisition
        return Measurements(acq.coherent_view(view), self.data[acq.frames(view)], self.noise_std, self.metadata)

    def less(self, background: Measurements) -> Measurements:
        """These samples less ``background``'s, of the same acquisition (what the scene
        returns without the objects: an empty box's capture, or its simulation); ValueError
        naming the first field that differs (Tx or Rx positions beyond 1 um, frequencies
        beyond 1 Hz, views, shape)."""
        mine, theirs = self.acquisition, background.acquisition
        for name, tolerance in (("tx_m", 1e-6), ("rx_m", 1e-6), ("frequencies_hz", 1.0)):
            a, b = getattr(mine, name), getattr(theirs, name)
            if a.shape != b.shape or not bool(((a.double() - b.double()).abs() <= tolerance).all()):
                raise ValueError(f"{name}: differs from the data's (a background must share their acquisition)")
        if not (mine.scans is None) == (theirs.scans is None) or (
                mine.scans is not None and not torch.equal(mine.scans, theirs.scans)):
            raise ValueError("scans: differ from the data's (a background must share their acquisition)")
        noise = (None if self.noise_std is None or background.noise_std is None
                 else math.hypot(self.noise_std, background.noise_std))
        return Measurements(mine, self.data - background.data, noise, self.metadata)


def _kept(count: int, step: int) -> torch.Tensor:
    """Sorted indices of ceil(count / step) of ``count`` elements, a fixed pseudo-random choice."""
    if step == 1:
        return torch.arange(count)
    keep = -(-count // step)
    return torch.randperm(count, generator=torch.Generator().manual_seed(count))[:keep].sort().values
