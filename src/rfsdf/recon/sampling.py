"""Where the losses look: data voxels and Eikonal points."""

from __future__ import annotations

import torch

__all__ = ["data_voxel_probabilities", "sample_data_voxels", "cell_voxels", "data_batch", "pooled_amplitude",
           "eikonal_points"]


def data_voxel_probabilities(observed_amplitude: torch.Tensor, focus: float) -> torch.Tensor:
    """(N,) sampling probabilities of the voxels of (V, N) per-view MF amplitudes.

    ``focus`` of the mass follows the view-mean amplitude (where the radar saw something)
    and the rest is uniform, so empty space, where the fit must not put surfaces, still counts.
    """
    amplitude = observed_amplitude.mean(0).clamp(min=0)
    uniform = torch.full_like(amplitude, 1.0 / amplitude.numel())
    if amplitude.sum() <= 0:
        return uniform
    return focus * amplitude / amplitude.sum() + (1 - focus) * uniform


def sample_data_voxels(probabilities: torch.Tensor, batch: int, generator: torch.Generator) -> torch.Tensor:
    """(batch,) voxel indices drawn with replacement."""
    return torch.multinomial(probabilities.cpu(), batch, replacement=True, generator=generator)


def cell_voxels(corner_index: torch.Tensor, grid_shape, size: int) -> torch.Tensor:
    """(C, size^3) flat voxel indices of the cubes of ``size`` voxels whose lowest corners are
    the voxels ``corner_index`` (C,), shifted back where they would leave the grid."""
    nx, ny, nz = grid_shape
    corner = torch.stack([corner_index // (ny * nz), (corner_index // nz) % ny, corner_index % nz], dim=1)
    corner = torch.minimum(corner, torch.tensor([nx - size, ny - size, nz - size], device=corner.device))
    offsets = torch.stack(torch.meshgrid(*[torch.arange(size, device=corner.device)] * 3, indexing="ij"), -1)
    cells = corner[:, None] + offsets.reshape(1, -1, 3)
    return (cells[..., 0] * ny + cells[..., 1]) * nz + cells[..., 2]


def data_batch(num_views: int, views_per_step: int, probabilities: torch.Tensor, voxels_per_step: int,
               grid_shape, size: int, generator: torch.Generator, device) -> tuple[torch.Tensor, int, torch.Tensor]:
    """One step's data: ``views_per_step`` random views (sorted), and cubes of ``size``
    voxels per edge, about ``voxels_per_step`` voxels in all, their corners drawn by
    ``probabilities``: (views, number of cubes, flat voxel indices cube by cube)."""
    views = torch.randperm(num_views, generator=generator)[:views_per_step].sort().values.to(device)
    corners = sample_data_voxels(probabilities, max(1, voxels_per_step // size**3), generator)
    return views, len(corners), cell_voxels(corners, grid_shape, size).flatten().to(device)


def pooled_amplitude(image: torch.Tensor, cells: int) -> torch.Tensor:
    """(v, C) root-mean-square amplitude over each cell of an image (v, C * s^3) whose voxels
    come cell by cell: a box blur of the power, which forgives a glint misplaced within a
    cell (the double penalty of comparing misplaced features voxel by voxel)."""
    return (image.abs() ** 2).reshape(image.shape[0], cells, -1).mean(2).sqrt()


def eikonal_points(lower_m, upper_m, near_points: torch.Tensor, batch: int, near_fraction: float,
                   jitter_m: float, generator: torch.Generator) -> torch.Tensor:
    """(batch, 3) [m] on the CPU: uniform in the box, and ``near_fraction`` of them near the
    zero level set (random ``near_points``, e.g. surface samples, plus Gaussian jitter of ``jitter_m``)."""
    lower = torch.as_tensor(lower_m, dtype=torch.float32)
    upper = torch.as_tensor(upper_m, dtype=torch.float32)
    near_points = near_points.detach().cpu()
    n_near = int(round(batch * near_fraction)) if len(near_points) else 0
    uniform = lower + (upper - lower) * torch.rand(batch - n_near, 3, generator=generator)
    pick = torch.randint(len(near_points), (n_near,), generator=generator) if n_near else torch.zeros(0, dtype=torch.long)
    near = near_points[pick] + jitter_m * torch.randn(n_near, 3, generator=generator)
    return torch.cat([uniform, near.clamp(lower, upper)])


def random_offsets(count: int, step_m: float, generator: torch.Generator) -> torch.Tensor:
    """(count, 3) [m] offsets of length ``step_m`` in uniformly random directions, on the CPU:
    where :func:`~rfsdf.recon.losses.normal_variation` compares each point's normal."""
    return torch.nn.functional.normalize(torch.randn(count, 3, generator=generator), dim=1) * step_m


def bending_pairs(near_points: torch.Tensor, count: int, step_m: float,
                  generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """``count`` random ``near_points`` (M, 3) [m] (surface samples) and a :func:`random_offsets`
    from each: (count, 3) points and (count, 3) offsets on the CPU."""
    pick = torch.randint(len(near_points), (count,), generator=generator)
    return near_points.detach().cpu()[pick], random_offsets(count, step_m, generator)
