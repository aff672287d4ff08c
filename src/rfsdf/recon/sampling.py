"""Where the losses look: data voxels, Eikonal points, and the band of voxels near the surface."""

from __future__ import annotations

import torch

__all__ = ["data_voxel_probabilities", "sample_data_voxels", "eikonal_points", "band_mask"]


def data_voxel_probabilities(observed_power: torch.Tensor, focus: float) -> torch.Tensor:
    """(N,) sampling probabilities of the voxels of (V, *grid) images.

    ``focus`` of the mass follows the view-mean MF amplitude (where the radar saw something)
    and the rest is uniform, so empty space, where the fit must not put surfaces, still counts.
    """
    amplitude = observed_power.mean(0).flatten().clamp(min=0).sqrt()
    uniform = torch.full_like(amplitude, 1.0 / amplitude.numel())
    if amplitude.sum() <= 0:
        return uniform
    return focus * amplitude / amplitude.sum() + (1 - focus) * uniform


def sample_data_voxels(probabilities: torch.Tensor, batch: int, generator: torch.Generator) -> torch.Tensor:
    """(batch,) voxel indices drawn with replacement."""
    return torch.multinomial(probabilities, batch, replacement=True, generator=generator)


def eikonal_points(lower_m, upper_m, near_points: torch.Tensor, batch: int, near_fraction: float,
                   jitter_m: float, generator: torch.Generator) -> torch.Tensor:
    """(batch, 3) [m]: uniform in the box, and ``near_fraction`` of them near the zero level set
    (random ``near_points``, e.g. band voxel centres, plus Gaussian jitter of ``jitter_m``)."""
    lower = torch.as_tensor(lower_m, dtype=torch.float32)
    upper = torch.as_tensor(upper_m, dtype=torch.float32)
    n_near = int(round(batch * near_fraction)) if len(near_points) else 0
    uniform = lower + (upper - lower) * torch.rand(batch - n_near, 3, generator=generator)
    pick = torch.randint(len(near_points), (n_near,), generator=generator) if n_near else torch.zeros(0, dtype=torch.long)
    near = near_points[pick] + jitter_m * torch.randn(n_near, 3, generator=generator)
    return torch.cat([uniform, near.clamp(lower, upper)])


def band_mask(sdf_values: torch.Tensor, half_width_m: float) -> torch.Tensor:
    """Boolean mask of voxels whose |f| is below ``half_width_m`` (where c is not negligible)."""
    return sdf_values.abs() < half_width_m
