"""Calibrating the radar gain with a reference object of known material.

A real radar's data carry an unknown gain (antennas, receiver chain, cables), so a fit with a
material head learns only the ratios of its surfaces' |Gamma| (``Problem.gain = None``: one
gain is fitted at each step). A radar engineer calibrates with an object of known reflection
in the scene, a metal sphere or plate; so does rfsdf: the reference's surface is rendered
with its stated material whatever the material head says (``Problem.known_materials``), so
the gain fitted at each step is the one that makes the reference as bright as its material,
and every other surface's class is absolute. (Labelling it for the cross-entropy term
instead does not calibrate: the head shares its features between surfaces, and on two
balls the label on the metal one pulled the wooden one to metal too.) The reference's place and shape come from a scene file (for a real capture, a
scene file that holds the reference where it stood).

A wrong reference cannot show in its own return (one object's brightness is gain times
|Gamma|, a product), only against the rest of the scene. After the fit, the predicted image
is split into the reference's part and the rest's (rendering is linear in the reflection),
and the powers of the data are fitted by a^2 |p_ref|^2 + b^2 |p_rest|^2 (a, b >= 0, least
squares over the bright voxels of every view): a / b is how much brighter the data want the
reference than its stated material, with the other surfaces as they were fitted. A
reference stated brighter than it is cannot be followed by the others (none is brighter
than metal), so a / b falls below 1, and the other way round. ``Calibration.warning``
says so when a / b leaves [1/2, 2] (``AGREEMENT``). A reference alone in the image has nothing to
disagree with: the check is then void, and says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

__all__ = ["Reference", "Calibration", "AGREEMENT", "BRIGHT", "CALIBRATION_NAME", "check_reference", "fitted_gain",
           "split_powers"]

CALIBRATION_NAME = "calibration.json"  # a run folder's Calibration.as_dict(), when a reference calibrated it
# the reference agrees when the data want between 1/AGREEMENT and AGREEMENT x its |Gamma|: a
# right metal reference read 0.89 on two balls whose geometry was regressed onto the truth,
# wrong ones 0.23 and 3.8 (tests/test_material_fit.py); a factor 2 tells metal from wood,
# plasterboard and concrete (5.9, 4.0 and 2.6 times brighter at normal incidence), hardly from
# glass (2.3)
AGREEMENT = 2.0
BRIGHT = 0.1  # voxels whose observed amplitude (peak 1, brightest view) reaches this share are compared


@dataclass(frozen=True)
class Reference:
    """An object of known material: ``name`` (for messages), ``material`` (a class of the
    head), ``sdf`` its signed distance (N, 3) -> (N,) [m], ``others`` the rest of the
    scene's (None: it stands alone) and ``distance_m``, how near its surface a point counts
    as it (and is nearer to it than to any other object)."""

    name: str
    material: str
    sdf: Callable[[torch.Tensor], torch.Tensor]
    others: Callable[[torch.Tensor], torch.Tensor] | None
    distance_m: float

    def mask(self, points: torch.Tensor) -> torch.Tensor:
        """(N,) bool: points (N, 3) [m] that belong to the reference."""
        with torch.no_grad():
            points = points.double().cpu()
            mine = self.sdf(points)
            near = mine.abs() < self.distance_m
            return near if self.others is None else near & (mine < self.others(points))

    def labels(self, classes: tuple[str, ...]) -> Callable[[torch.Tensor], torch.Tensor]:
        """points (Q, 3) -> (Q,) int64 for ``Problem.known_materials``: the index of the
        reference's material in ``classes`` on the reference, -1 elsewhere."""
        index = classes.index(self.material)

        def label(points: torch.Tensor) -> torch.Tensor:
            mask = self.mask(points).to(points.device)
            return torch.where(mask, index, -1).to(torch.int64)

        return label


@dataclass(frozen=True)
class Calibration:
    """What a reference said after the fit: the ``gain`` [data units per renderer unit]
    that fits the whole image, and ``ratio``, the gain that fits the amplitudes around the
    reference over that one (None when the reference is all the image holds)."""

    reference: str  # "NAME=MATERIAL"
    gain: float
    ratio: float | None

    @property
    def stated(self) -> tuple[str, str]:
        """(the reference's object name, its stated material), from ``reference``."""
        name, _, material = self.reference.partition("=")
        return name, material

    def text(self) -> str:
        """One line for the materials table."""
        agreement = ("nothing else in the image to check it against" if self.ratio is None else
                     f"the data around it want {self.ratio:.2f} x its |Gamma|")
        return f"reference {self.reference}: rendered as stated, gain {self.gain:.3g}; {agreement}"

    def warning(self) -> str | None:
        """A sentence when the reference disagrees with the rest of the scene, else None."""
        if self.ratio is None or 1 / AGREEMENT <= self.ratio <= AGREEMENT:
            return None
        side = "dimmer" if self.ratio < 1 else "brighter"
        return (f"reference {self.reference}: the data around it want {self.ratio:.2f} x the |Gamma| of its stated "
                f"material, against the rest of the scene: it is likely {side} than stated (another material, "
                "or not where the scene puts it), and every absolute class is off by that factor")

    def as_dict(self) -> dict:
        return {"reference": self.reference, "gain": self.gain, "ratio": self.ratio, "warning": self.warning()}


def split_powers(parts: list[torch.Tensor], observed: torch.Tensor) -> np.ndarray:
    """(len(parts),) a_i >= 0 with sum_i a_i^2 |p_i|^2 closest to o^2 in least squares, for complex
    images p_i and observed amplitudes o (all the same shape): powers add where the parts' phases
    are unrelated, which is what a fitted geometry's errors leave of them (fitting |sum_i a_i p_i|
    to o instead trusts the parts' interference, and on two balls 1.3 range resolutions apart it
    explained the data by one ball alone)."""
    from scipy.optimize import nnls

    design = torch.stack([part.abs().flatten() ** 2 for part in parts], dim=1)
    powers, _ = nnls(design.double().cpu().numpy(), (observed.flatten() ** 2).double().cpu().numpy())
    return np.sqrt(powers)


def _bright(trainer) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The bright voxels of the data (N,), every view (V,) and the finished fit's class
    probabilities on new surface samples: what the checks below render."""
    trainer.refresh_surface()
    index = (trainer.observed.max(0).values >= BRIGHT).nonzero().squeeze(1)
    views = torch.arange(trainer.renderer.num_views, device=trainer.renderer.device)
    return index, views, trainer.surface_materials(geometry=False)


def _least_squares_gain(predicted: torch.Tensor, observed: torch.Tensor) -> float:
    return float((predicted * observed).sum() / (predicted * predicted).sum().clamp(min=1e-30))


@torch.no_grad()
def fitted_gain(trainer) -> float:
    """The gain [data units per renderer unit] that fits a finished fit's own prediction (its
    head's reflection) to the data's amplitudes at their bright voxels: the scale its head's
    classes are read in when neither a reference nor a known gain set one."""
    index, views, probabilities = _bright(trainer)
    predicted = trainer.renderer(trainer.field, views, index, geometry=False, probabilities=probabilities).abs()
    return _least_squares_gain(predicted, trainer.observed[:, index]) * trainer.renderer.observed_peak


@torch.no_grad()
def check_reference(trainer, reference: Reference) -> Calibration:
    """The gain and the reference's agreement (:class:`Calibration`) of a finished fit:
    complex images of all views at the bright voxels of the data, predicted by the fitted
    field (new surface samples) for the reference's surface and the rest's, and the
    observed amplitudes there."""
    renderer, field = trainer.renderer, trainer.field
    index, all_views, probabilities = _bright(trainer)
    mine = reference.mask(renderer.candidates.anchors).to(probabilities.device)[:, None]

    def image(p: torch.Tensor) -> torch.Tensor:  # one prediction a view, imaged at every bright voxel
        return renderer(field, all_views, index, geometry=False, probabilities=p)

    own, rest = image(probabilities * mine), image(probabilities * ~mine)
    measured = trainer.observed[:, index]
    gain = _least_squares_gain((own + rest).abs(), measured)
    ratio = None
    if float(own.abs().max()) > 0 and float(rest.abs().max()) > 0:
        a, b = (float(x) for x in split_powers([own, rest], measured))
        ratio = a / b if b > 0 else float("inf")
    return Calibration(f"{reference.name}={reference.material}", gain * renderer.observed_peak, ratio)
