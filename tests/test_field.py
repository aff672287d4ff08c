import math

import pytest
import torch

from rfsdf.field import PositionalEncoding, RadarField, levels_for
from rfsdf.geometry import Sphere
from rfsdf.recon import eikonal_loss
from rfsdf.recon.losses import normal_variation
from rfsdf.recon.sampling import random_offsets


def test_levels_for_resolves_the_feature():
    assert levels_for(1.0, 0.25) == 2  # finest half-period 1 / 2^2 = 0.25
    assert levels_for(0.3, 0.006) == 6
    # Convention: the finest half-period S / 2^L is at most the feature, and L is minimal.
    for scene, feature in [(0.3, 0.0038), (2.0, 0.01), (0.5, 0.4)]:
        levels = levels_for(scene, feature)
        assert scene / 2**levels <= feature < scene / 2 ** (levels - 1) or levels == 0
    with pytest.raises(ValueError):
        levels_for(0.3, 0.0)


def test_encoding_normalises_to_the_bounds_with_one_scale():
    enc = PositionalEncoding((-0.1, -0.2, 0.0), (0.1, 0.2, 0.2), levels=3)
    x = enc.normalise(torch.tensor([[0.1, 0.2, 0.1], [0.0, 0.0, 0.1]]))
    assert torch.allclose(x, torch.tensor([[0.5, 1.0, 0.0], [0.0, 0.0, 0.0]]))
    features = enc(torch.tensor([[0.1, 0.2, 0.1]]))
    assert features.shape == (1, enc.out_dim) == (1, 3 + 6 * 3)
    assert features[0, 3 + 1].item() == pytest.approx(math.sin(math.pi * 1.0), abs=1e-6)  # level 0, y


def test_geometric_init_starts_close_to_a_sphere():
    torch.manual_seed(0)
    radius = 0.06
    field = RadarField((-0.15,) * 3, (0.15,) * 3, levels=6, init_radius_m=radius)
    directions = torch.nn.functional.normalize(torch.randn(2000, 3), dim=1)
    shell = directions * (radius * (0.75 + 0.5 * torch.rand(2000, 1)))  # |p| in [0.75 r, 1.25 r]
    with torch.no_grad():
        err = (field.sdf(shell) - (shell.norm(dim=1) - radius)).abs()
        on_sphere = field.sdf(directions * radius)
    assert err.mean() < 0.1 * radius
    assert on_sphere.mean().abs() < 0.02 * radius  # the zero level set sits at the radius
    # Over the whole box, default initialisation is nowhere near the sphere's SDF.
    box = (torch.rand(2000, 3) - 0.5) * 0.3
    torch.manual_seed(0)
    plain = RadarField((-0.15,) * 3, (0.15,) * 3, levels=6, init_radius_m=radius, geometric_init=False)
    with torch.no_grad():
        truth = box.norm(dim=1) - radius
        assert (plain.sdf(box) - truth).abs().mean() > 3 * (field.sdf(box) - truth).abs().mean()


def test_reflectivity_is_non_negative_with_a_floor():
    field = RadarField((-1,) * 3, (1,) * 3, levels=2, reflectivity_floor=0.05)
    with torch.no_grad():
        gamma = field.reflectivity(torch.rand(500, 3) * 2 - 1)
    assert (gamma >= 0.05).all()


def test_eikonal_loss_of_an_exact_sdf_is_zero_and_of_a_scaled_one_is_not():
    points = torch.rand(1000, 3) - 0.5
    sphere = Sphere(0.2)
    assert eikonal_loss(sphere, points).item() < 1e-10
    assert eikonal_loss(lambda p: 2 * sphere(p), points).item() == pytest.approx(1.0, rel=1e-4)
    field = RadarField((-0.5,) * 3, (0.5,) * 3, levels=2)
    loss = eikonal_loss(field.sdf, points)
    loss.backward()  # create_graph: the loss trains the network
    assert field.geometry.layers[0].weight.grad is not None


def test_normal_variation_is_zero_on_a_plane_and_the_closed_form_on_a_sphere_and_trains_the_network():
    """Normals of a plane do not vary; on a sphere of radius R, p on it and a tangent offset of
    length s, the two normals part by theta = atan(s / R): |n - n'|^2 = 2 - 2 cos(theta). A
    plane rippled by 0.3 mm over 1 cm costs more than a 2.5 cm ball's curve (the bending energy)."""
    generator = torch.Generator().manual_seed(0)
    points = torch.rand(500, 3, generator=generator) - 0.5
    offsets = random_offsets(500, 0.003, generator)
    assert normal_variation(lambda p: p[:, 2] - 0.1, points, offsets).item() < 1e-12
    radius, step = 0.025, 0.003
    on_sphere = radius * torch.nn.functional.normalize(torch.randn(500, 3, generator=generator), dim=1)
    tangent = torch.nn.functional.normalize(torch.linalg.cross(on_sphere, torch.randn(500, 3, generator=generator)),
                                            dim=1)
    expected = 2 - 2 * math.cos(math.atan(step / radius))
    assert normal_variation(Sphere(radius), on_sphere, step * tangent).item() == pytest.approx(expected, rel=1e-4)
    wavelength, amplitude = 0.01, 0.0003  # peak curvature 118 / m, the ball's 40 / m
    ripple = lambda p: p[:, 2] - amplitude * torch.sin(2 * math.pi * p[:, 0] / wavelength)  # noqa: E731
    flat = torch.cat([points[:, :2], torch.zeros(500, 1)], dim=1)
    assert normal_variation(ripple, flat, offsets).item() > expected
    field = RadarField((-0.5,) * 3, (0.5,) * 3, levels=2)
    normal_variation(field.sdf, points, offsets).backward()
    assert field.geometry.layers[0].weight.grad is not None


def test_a_knot_displacement_moves_the_zero_set_along_the_normal_and_reads_a_linear_field_exactly():
    """f - d: a uniform d grows a ball by d (|p| - r - d is zero at |p| = r + d); a d linear
    in x is read exactly between the knots."""
    field = RadarField((-0.1,) * 3, (0.1,) * 3, levels=2, init_radius_m=0.05, displacement_knot_m=0.02)
    knots = field.displacement.grid
    assert knots.voxel_m == pytest.approx([0.02] * 3)
    assert all(lo < -0.1 and hi > 0.1 for lo, hi in zip(knots.lower_m, knots.upper_m))  # a knot beyond each side
    points = (torch.rand(500, 3) - 0.5) * 0.2
    with torch.no_grad():
        plain = field.sdf(points)
        field.displacement.offsets_m.fill_(0.003)
        assert torch.allclose(plain - field.sdf(points), torch.full((500,), 0.003), atol=1e-7)
        x = torch.as_tensor(knots.axes()[0], dtype=torch.float32)
        field.displacement.offsets_m.copy_(0.01 * x[:, None, None].expand(knots.shape))
        assert torch.allclose(plain - field.sdf(points), 0.01 * points[:, 0], atol=1e-7)
    assert field.state_dict()["displacement.offsets_m"].shape == knots.shape
    with pytest.raises(ValueError, match="knot spacing"):
        RadarField((-0.1,) * 3, (0.1,) * 3, levels=2, displacement_knot_m=0.0)
