"""Where tensors live: every stage takes ``--device auto|cpu|cuda`` and resolves it here.

``auto`` is CUDA when torch sees a GPU and the CPU otherwise. The stages keep their inputs
and outputs (measurements, images, meshes, files) on the CPU and move only the hot tensors
(surface samples, voxel centres, the network) to the device, so a run's files do not depend
on where it ran.
"""

from __future__ import annotations

import torch

from .errors import RfsdfError

__all__ = ["DEVICES", "resolve_device"]

DEVICES = ("auto", "cpu", "cuda")


def resolve_device(name: str | torch.device | None, setting: str = "--device") -> torch.device:
    """'auto' or None (CUDA when torch sees a GPU), 'cpu' or 'cuda[:N]'; anything else, or
    CUDA on a machine without one, is one :class:`RfsdfError` naming ``setting``."""
    if isinstance(name, torch.device):
        name = str(name)
    if name is None or name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        device = torch.device(name)
    except RuntimeError:
        raise RfsdfError(f"{setting}: unknown device {name!r}; use auto, cpu or cuda") from None
    if device.type not in ("cpu", "cuda"):
        raise RfsdfError(f"{setting}: {name!r} is not supported; use auto, cpu or cuda")
    if device.type == "cuda" and not torch.cuda.is_available():
        raise RfsdfError(f"{setting}: {name!r} asked for, but torch sees no CUDA GPU here; use auto or cpu")
    return device
