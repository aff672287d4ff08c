"""The networks of a radar scene: geometry f_theta(p) [m], reflectivity Gamma_phi(p) >= 0,
and the material of each point.

``SDFNetwork`` is the GeRaF/IDR geometry MLP: Softplus(beta=100) activations, the input
re-fed midway (skip connection), and the geometric initialisation of SAL (Atzmon & Lipman,
CVPR 2020) so that f starts close to |p - centre| - r. ``ReflectivityNetwork`` is a small
MLP on the same encoding (the free reflectivity). ``MaterialHead`` is a softmax over a
catalogue's material classes fed by the geometry network's last hidden layer, as NeuS feeds
its colour network: what a point is made of is read where its shape is. ``RadarField``
holds the shared encoding and the networks.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from .displacement import KnotDisplacement
from .encoding import PositionalEncoding

__all__ = ["SDFNetwork", "ReflectivityNetwork", "MaterialHead", "RadarField"]


class SDFNetwork(nn.Module):
    """f_theta : encoded points (N, D) -> (N,) signed distance in normalised units.

    depth linear layers (depth - 1 hidden), ``width`` units, the encoded input concatenated
    again before layer ``depth // 2``. With ``geometric_init`` the output starts close to
    |x| - radius (x the normalised position, first three encoded features).
    """

    def __init__(self, in_dim: int, *, depth: int = 6, width: int = 128, radius: float = 0.5,
                 geometric_init: bool = True):
        super().__init__()
        if depth < 3:
            raise ValueError(f"depth must be >= 3, got {depth}")
        self.skip = depth // 2
        dims_in = [in_dim] + [width + (in_dim if i == self.skip else 0) for i in range(1, depth)]
        dims_out = [width] * (depth - 1) + [1]
        self.layers = nn.ModuleList(nn.Linear(i, o) for i, o in zip(dims_in, dims_out))
        self.activation = nn.Softplus(beta=100)
        if geometric_init:
            self._geometric_init(in_dim, radius)

    @torch.no_grad()
    def _geometric_init(self, in_dim: int, radius: float) -> None:
        """SAL: hidden layers N(0, sqrt(2/out)), encoded sin/cos inputs start at zero weight,
        and the last layer N(sqrt(pi/in), 1e-4) with bias -radius, so f(x) ~ |x| - radius."""
        last = len(self.layers) - 1
        for index, layer in enumerate(self.layers):
            if index == last:
                nn.init.normal_(layer.weight, mean=math.sqrt(math.pi / layer.in_features), std=1e-4)
                nn.init.constant_(layer.bias, -radius)
                continue
            nn.init.normal_(layer.weight, 0.0, math.sqrt(2.0 / layer.out_features))
            nn.init.zeros_(layer.bias)
            if index == 0:
                layer.weight[:, 3:] = 0.0  # only x itself feeds the first layer at start
            elif index == self.skip:
                layer.weight[:, -(in_dim - 3):] = 0.0  # the re-fed sin/cos features too
        # At finite width, and with Softplus(0) = log(2)/100 instead of ReLU's 0, the net is
        # only roughly |x| + const, with a slope that drops near x = 0. Measure the mean
        # radial profile on spheres |x| = radius and radius + 1/4 (sin/cos weights are 0, so
        # the other inputs do not matter) and rescale the last layer so that the zero level
        # set sits at ``radius`` with unit slope there.
        directions = _fibonacci_sphere(64)
        probe = torch.zeros(128, in_dim)
        probe[:64, :3] = radius * directions
        probe[64:, :3] = (radius + 0.25) * directions
        values = self.forward(probe)
        at_radius, outside = values[:64].mean(), values[64:].mean()
        slope = (outside - at_radius) / 0.25
        self.layers[last].weight /= slope
        self.layers[last].bias.copy_((self.layers[last].bias - at_radius) / slope)

    def forward_with_features(self, encoded: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N,) f in normalised units and (N, width) the last hidden layer's activations."""
        h = encoded
        for index, layer in enumerate(self.layers[:-1]):
            if index == self.skip:
                h = torch.cat([h, encoded], dim=1) / math.sqrt(2)
            h = self.activation(layer(h))
        return self.layers[-1](h)[:, 0], h

    def forward(self, encoded: torch.Tensor) -> torch.Tensor:
        return self.forward_with_features(encoded)[0]


def _fibonacci_sphere(n: int) -> torch.Tensor:
    """(n, 3) nearly uniform unit vectors (golden-angle spiral)."""
    i = torch.arange(n, dtype=torch.float32) + 0.5
    z = 1 - 2 * i / n
    phi = math.pi * (3 - math.sqrt(5)) * i
    r = torch.sqrt(1 - z**2)
    return torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], dim=1)


class ReflectivityNetwork(nn.Module):
    """Gamma_phi : encoded points (N, D) -> (N,) reflectivity >= floor (relative units)."""

    def __init__(self, in_dim: int, *, depth: int = 3, width: int = 64, floor: float = 0.02):
        super().__init__()
        dims = [in_dim] + [width] * (depth - 1)
        layers: list[nn.Module] = []
        for i, o in zip(dims[:-1], dims[1:]):
            layers += [nn.Linear(i, o), nn.Softplus(beta=10)]
        layers.append(nn.Linear(dims[-1], 1))
        self.mlp = nn.Sequential(*layers)
        self.floor = float(floor)
        with torch.no_grad():  # start near Gamma = 1 everywhere
            self.mlp[-1].weight.mul_(0.1)
            self.mlp[-1].bias.fill_(math.log(math.e - 1.0))

    def forward(self, encoded: torch.Tensor) -> torch.Tensor:
        return self.floor + nn.functional.softplus(self.mlp(encoded)[:, 0])


class MaterialHead(nn.Module):
    """p_psi : geometry features (N, F) -> (N, K) probabilities of K material classes.

    One hidden layer; the logits start at zero, so every class starts equally likely."""

    def __init__(self, in_dim: int, classes: int, *, width: int = 64):
        super().__init__()
        if classes < 1:
            raise ValueError(f"a material head needs at least one class, got {classes}")
        self.mlp = nn.Sequential(nn.Linear(in_dim, width), nn.Softplus(beta=10), nn.Linear(width, classes))
        with torch.no_grad():
            self.mlp[-1].weight.mul_(0.1)
            self.mlp[-1].bias.zero_()

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.mlp(features), dim=1)


class RadarField(nn.Module):
    """Shared encoding + geometry + reflectivity (+ material head), in scene units.

    ``sdf(points)`` : (N, 3) [m] -> (N,) [m]; ``reflectivity(points)`` : (N,) >= 0;
    ``material(points)`` : (N, K) class probabilities over ``materials`` (catalogue names,
    ``rfsdf.materials``), when the field has any. With ``displacement_knot_m`` f is the
    network's SDF less a coarse displacement (``KnotDisplacement``, zero at the start), the
    part of the geometry a fit may move alone.
    """

    def __init__(self, lower_m, upper_m, *, levels: int, depth: int = 6, width: int = 128,
                 init_radius_m: float | None = None, geometric_init: bool = True,
                 reflectivity_width: int = 64, reflectivity_floor: float = 0.02, materials: tuple[str, ...] = (),
                 displacement_knot_m: float | None = None):
        super().__init__()
        self.lower_m, self.upper_m = tuple(map(float, lower_m)), tuple(map(float, upper_m))  # [m]
        self.encoding = PositionalEncoding(lower_m, upper_m, levels)
        h = self.encoding.half_extent_m
        radius = 0.5 if init_radius_m is None else init_radius_m / h
        self.geometry = SDFNetwork(self.encoding.out_dim, depth=depth, width=width, radius=radius,
                                   geometric_init=geometric_init)
        self.reflectance = ReflectivityNetwork(self.encoding.out_dim, width=reflectivity_width,
                                               floor=reflectivity_floor)
        self.materials = tuple(materials)
        self.material_head = MaterialHead(width, len(materials), width=reflectivity_width) if materials else None
        self.displacement = (None if displacement_knot_m is None
                             else KnotDisplacement(lower_m, upper_m, displacement_knot_m))

    def _displaced(self, values: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
        return values if self.displacement is None else values - self.displacement(points)

    def sdf(self, points: torch.Tensor) -> torch.Tensor:
        return self._displaced(self.geometry(self.encoding(points)) * self.encoding.half_extent_m, points)

    def sdf_and_reflectivity(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        encoded = self.encoding(points)
        return self._displaced(self.geometry(encoded) * self.encoding.half_extent_m, points), self.reflectance(encoded)

    def reflectivity(self, points: torch.Tensor) -> torch.Tensor:
        return self.reflectance(self.encoding(points))

    def material_features(self, points: torch.Tensor) -> torch.Tensor:
        """(N, width) the geometry network's last hidden layer at points (N, 3) [m]: what the
        material head reads."""
        if self.material_head is None:
            raise ValueError("this field has no material head (it was fitted with a free reflectivity)")
        return self.geometry.forward_with_features(self.encoding(points))[1]

    def material(self, points: torch.Tensor) -> torch.Tensor:
        """(N, K) probabilities of ``self.materials`` at points (N, 3) [m]; differentiable in
        the head and (through its features) the geometry network."""
        return self.material_head(self.material_features(points))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.sdf(points)
