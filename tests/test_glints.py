"""A range peak read as a glint (recon.glints): against a ball's closed form and a dense cap."""

import math

import pytest
import torch

from rfsdf.geometry import Sphere
from rfsdf.recon.glints import cap_directions, glint_gap


def _peaks(count: int, off_deg: float, range_excess_m: torch.Tensor, seed: int = 0):
    """Views 0.3 m from a 25 mm ball at the origin, each with a line ``off_deg`` off the ball's
    centre in a random direction and a peak on it at the glint's range plus ``range_excess_m``:
    points, unit towards, ranges, the view centres (all float64)."""
    generator = torch.Generator().manual_seed(seed)
    random = torch.randn(count, 3, generator=generator, dtype=torch.float64)
    centres = 0.3 * torch.nn.functional.normalize(random, dim=1)
    axis = -torch.nn.functional.normalize(centres, dim=1)
    across = torch.nn.functional.normalize(torch.linalg.cross(axis, torch.randn(count, 3, generator=generator,
                                                                                dtype=torch.float64)), dim=1)
    off = math.radians(off_deg)
    line = math.cos(off) * axis + math.sin(off) * across
    ranges = 0.3 - 0.025 + range_excess_m
    points = centres + ranges[:, None] * line
    return points, -line, ranges, centres


def test_cap_directions_rings_of_six_j_within_the_cone():
    directions = cap_directions(math.radians(0.5), 2)
    assert directions.shape == (19, 2)
    assert torch.equal(directions[0], torch.zeros(2))
    assert torch.allclose(directions[1:7, 0], torch.full((6,), math.radians(0.25), dtype=torch.float64))
    assert torch.allclose(directions[7:, 0], torch.full((12,), math.radians(0.5), dtype=torch.float64))
    assert cap_directions(0.0, 3).shape == (1, 2)


def test_no_cone_or_no_range_is_f_at_the_peak():
    """The line model, exactly: a cone of 0, or a range of 0 (a planar scan's lines)."""
    generator = torch.Generator().manual_seed(1)
    points = 0.05 * torch.randn(50, 3, generator=generator, dtype=torch.float64)
    towards = torch.nn.functional.normalize(torch.randn(50, 3, generator=generator, dtype=torch.float64), dim=1)
    ball = Sphere(0.025)
    assert torch.equal(glint_gap(ball, points, towards, torch.full((50,), 0.3, dtype=torch.float64), 0.0), ball(points))
    assert torch.equal(glint_gap(ball, points, towards, torch.zeros(50, dtype=torch.float64), 0.01), ball(points))


@pytest.mark.parametrize("off_deg, cone_deg, rings", [(0.2, 0.25, 2), (0.8, 1.0, 4)])
def test_a_ball_is_touched_at_its_glint_range_within_the_sag_of_the_rings(off_deg, cone_deg, rings):
    """A ball seen from c: the least f over the sphere of radius rho about c, in a cone that holds
    the direction to its centre, is |c| - R - rho (closed form); the rings miss it by at most the
    sag of the two spheres across the samples' covering radius, and a dense cap (4000 random directions) by
    no more. The line model reads the same peaks off by the ball's curvature across the offset
    (0.3 mm on a line 0.8 degrees off)."""
    excess = torch.linspace(-2e-3, 2e-3, 40, dtype=torch.float64)
    points, towards, ranges, centres = _peaks(40, off_deg, excess)
    cone = math.radians(cone_deg)
    gap = glint_gap(Sphere(0.025), points, towards, ranges, cone, rings)
    exact = centres.norm(dim=1) - 0.025 - ranges
    covering = 0.75 * 0.3 * cone / rings  # any direction in the cap is this near a sample [m at 0.3 m]
    sag = covering**2 / 2 * (1 / 0.025 + 1 / 0.3)
    assert torch.all(gap >= exact - 1e-12) and torch.all(gap <= exact + sag), (gap - exact).max()
    torch.testing.assert_close(exact, -excess, atol=1e-12, rtol=0)
    # a slow reference: the least f over many directions in the cap
    generator = torch.Generator().manual_seed(2)
    polar = cone * torch.rand(4000, generator=generator, dtype=torch.float64).sqrt()
    azimuth = 2 * math.pi * torch.rand(4000, generator=generator, dtype=torch.float64)
    axis = -towards
    z = torch.tensor([[0.0, 0, 1]], dtype=torch.float64).expand_as(axis)
    across = torch.nn.functional.normalize(torch.linalg.cross(axis, z), dim=1)
    other = torch.linalg.cross(axis, across)
    directions = (torch.cos(polar)[None, :, None] * axis[:, None]
                  + torch.sin(polar)[None, :, None] * (torch.cos(azimuth)[None, :, None] * across[:, None]
                                                       + torch.sin(azimuth)[None, :, None] * other[:, None]))
    dense = Sphere(0.025)((centres[:, None] + ranges[:, None, None] * directions).reshape(-1, 3)).reshape(40, -1)
    assert torch.all((gap - dense.min(1).values).abs() <= sag)
    line = Sphere(0.025)(points)
    assert float((line - exact).abs().min()) > (10 if off_deg > 0.5 else 3) * sag


def test_the_gap_moves_the_surface_it_touches():
    """d gap / d R = -1 for a ball's radius: the contact is differentiable through f."""
    points, towards, ranges, _ = _peaks(5, 0.1, torch.zeros(5, dtype=torch.float64))
    radius = torch.tensor(0.025, dtype=torch.float64, requires_grad=True)
    glint_gap(Sphere(radius), points, towards, ranges, math.radians(0.25)).sum().backward()
    assert float(radius.grad) == pytest.approx(-5.0)
