"""Rendering a neural scene into predicted per-view matched-filter power images.

The scene's reflectivity on the voxel centres p is c(p) = Gamma(p) delta_sigma(f(p)) dV,
with delta_sigma(s) = exp(-s^2 / 2 sigma^2); dV is constant and folded into Gamma's relative
units. View v sees a surface voxel with weight w_v(p) = max(0, n(p) . u_v(p))^e (n the SDF
normal, u_v the unit vector to the view's array centre): a surface returns nothing to a
radar behind it. Two renderers turn I_v = w_v |c|^2 into predicted MF power P_v:

* ``LocalRenderer``: P_v = I_v. The textbook picture: the MF image is the local reflectivity.
* ``PhysicsRenderer``: P_v = |h_v|^2 * I_v (3-D convolution), h_v the exact column-normalised
  PSF of view v, A_v^H A_v delta / ||A_v||^2, computed through the sensing operator for a
  point at the grid centre. Range and cross-range blur, range sidelobes and the array's
  sidelobes are therefore in the prediction, so the fit can undo the MF's blur and bias.
  Two approximations, both measured in the README: the PSF is taken as shift-invariant
  over the scene, and sums are incoherent in power (speckle-averaged): voxel-sampled
  reflectivity at spacings above lambda/4 cannot carry the carrier phase, so coherent
  interference between voxels would be aliasing, not physics. Nor can the shell
  delta_sigma(f) itself be rendered coherently at these sigmas: across a flat surface it
  returns exp(-2 k^2 sigma^2) of a sheet's amplitude (the Gaussian's Fourier transform at
  the round-trip wavenumber 2k), e^-197 at 79 GHz and sigma = 6 mm. A coherent model needs
  the geometry within about lambda/8 (``benchmarks/coherent_model.py``).
"""

from __future__ import annotations

import numpy as np
import torch

from ..geometry import Grid
from ..radar import Acquisition, point_spread

__all__ = ["delta_sigma", "facing_weights", "LocalRenderer", "PhysicsRenderer", "make_renderer"]


def delta_sigma(sdf_m: torch.Tensor, sigma_m: float) -> torch.Tensor:
    """Surface kernel exp(-f^2 / (2 sigma^2)): 1 on the zero level set, ~0 beyond 3 sigma."""
    return torch.exp(-0.5 * (sdf_m / sigma_m) ** 2)


def facing_weights(points: torch.Tensor, normals: torch.Tensor, view_centres_m: torch.Tensor,
                   exponent: float) -> torch.Tensor:
    """(V, N) weights max(0, n . u_v)^exponent of points (N, 3) with unit normals (N, 3)."""
    if exponent == 0:
        return torch.ones(len(view_centres_m), len(points), device=points.device)
    to_view = torch.nn.functional.normalize(view_centres_m[:, None, :] - points[None], dim=2)
    return ((to_view * normals[None]).sum(2).clamp(min=0)) ** exponent


class LocalRenderer:
    """P_v = I_v: the predicted MF power is the view-weighted local |c|^2."""

    name = "local"

    def __call__(self, intensity: torch.Tensor, views: torch.Tensor) -> torch.Tensor:
        return intensity


class PhysicsRenderer:
    """P_v = |h_v|^2 * I_v with each view's exact PSF power as a convolution kernel.

    grid : the image grid; kernels : (V, 2r+1, 2r+1, 2r+1) float32 |h_v|^2 (1 at the centre).
    The convolution is linear (zero padded), by real FFTs of the padded size.
    """

    name = "physics"

    def __init__(self, grid: Grid, kernels: torch.Tensor):
        self.grid_shape = tuple(grid.shape)
        self.radius = (kernels.shape[1] - 1) // 2
        self.fft_shape = tuple(n + 2 * self.radius for n in self.grid_shape)
        self.kernel_fft = torch.fft.rfftn(kernels, s=self.fft_shape, dim=(1, 2, 3))

    @classmethod
    def from_acquisition(cls, acquisition: Acquisition, grid: Grid, psf_radius_m: float,
                         device: torch.device | str = "cpu") -> "PhysicsRenderer":
        """Compute each view's PSF around the grid's central voxel through the operator (on the
        CPU, once); the kernels then live on ``device``, where the intensities will be."""
        voxel = grid.voxel_m
        radius = max(1, int(round(psf_radius_m / float(voxel.max()))))
        centre_index = np.asarray(grid.shape) // 2
        centre = np.asarray(grid.lower_m) + (centre_index + 0.5) * voxel
        kernel_grid = Grid(tuple(centre - (radius + 0.5) * voxel), tuple(centre + (radius + 0.5) * voxel),
                           (2 * radius + 1,) * 3)
        kernels = []
        for v in range(acquisition.shape[0]):
            psf = point_spread(acquisition.view(v), centre, kernel_grid).per_view[0]
            kernels.append(psf.abs() ** 2)
        return cls(grid, torch.stack(kernels).to(device))

    def __call__(self, intensity: torch.Tensor, views: torch.Tensor) -> torch.Tensor:
        """intensity : (v, nx, ny, nz) for the views ``views`` (v,); returns (v, nx, ny, nz)."""
        spectrum = torch.fft.rfftn(intensity, s=self.fft_shape, dim=(1, 2, 3))
        full = torch.fft.irfftn(spectrum * self.kernel_fft[views], s=self.fft_shape, dim=(1, 2, 3))
        r = self.radius
        nx, ny, nz = self.grid_shape
        return full[:, r:r + nx, r:r + ny, r:r + nz].clamp(min=0)  # FFT round-off dips below 0


def make_renderer(name: str, acquisition: Acquisition, grid: Grid, psf_radius_m: float,
                  device: torch.device | str = "cpu"):
    """The renderer called ``name`` ('physics' or 'local') for this acquisition and grid, rendering on ``device``."""
    if name == "local":
        return LocalRenderer()
    return PhysicsRenderer.from_acquisition(acquisition, grid, psf_radius_m, device)
