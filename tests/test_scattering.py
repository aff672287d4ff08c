"""The one scattering function behind the simulator and the renderer, against a hand computation."""

import math

import numpy as np
import pytest
import torch

from rfsdf.geometry import Sphere
from rfsdf.materials import fresnel
from rfsdf.radar.scattering import DIFFUSE_WEIGHT, SPECULAR_EXPONENT, lit_mask, scatter

TX = np.array([0.0, 0.0, 1.0])
RX = np.array([0.1, 0.0, 1.0])
K = 2 * math.pi * 79e9 / 299_792_458.0  # the wavenumber at 79 GHz [rad/m]


def _by_hand(p, n, area, eps):
    """c = (j k / 2 pi) Gamma(theta) * ((1-w) max(0, m.o)^8 + w cos theta) * dA, written out for one sample."""
    to_tx, to_rx = TX - p, RX - p
    cos_t = to_tx @ n / np.linalg.norm(to_tx)
    if cos_t <= 0 or to_rx @ n <= 0:
        return 0.0
    d = -to_tx / np.linalg.norm(to_tx)  # incident direction
    m = d - 2 * (d @ n) * n
    o = to_rx / np.linalg.norm(to_rx)
    lobe = (1 - DIFFUSE_WEIGHT) * max(0.0, m @ o) ** SPECULAR_EXPONENT + DIFFUSE_WEIGHT * cos_t
    gamma = complex(fresnel(math.acos(cos_t), eps, "mean"))
    return 1j * K / (2 * math.pi) * gamma * lobe * area


def test_scatter_matches_a_hand_computation():
    points = np.array([[0.0, 0.0, 0.0], [0.02, -0.01, 0.0], [0.0, 0.03, 0.01], [0.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.3, 0.0, 1.0], [0.0, -0.6, 0.8], [0.0, 0.0, -1.0]])  # last faces away
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    area = np.array([1e-6, 2e-6, 1.5e-6, 1e-6])
    eps = torch.tensor([6.3 - 0.3j, 2.0 - 0.1j, complex(math.inf), 6.3 - 0.3j], dtype=torch.complex128)
    c = scatter(torch.tensor(points), torch.tensor(normals), torch.tensor(area),
                lambda cos: fresnel(torch.arccos(cos), eps, "mean"), torch.tensor(TX), torch.tensor(RX), K)
    expected = [_by_hand(p, n, a, complex(e)) for p, n, a, e in zip(points, normals, area, eps)]
    np.testing.assert_allclose(c.numpy(), expected, rtol=1e-12, atol=1e-18)
    assert c[3] == 0 and c[2] != 0


def test_shadowed_samples_do_not_scatter_and_gradients_flow():
    points = torch.tensor([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]], dtype=torch.float64, requires_grad=True)
    normals = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    blocker = Sphere(0.04, (0.0, 0.0, 0.5))  # between the first sample and the array
    lit = lit_mask(points, normals, torch.tensor(TX), torch.tensor(RX), occluder=blocker)
    assert lit.tolist() == [False, True]
    c = scatter(points, normals, torch.full((2,), 1e-6, dtype=torch.float64), lambda cos: torch.ones_like(cos),
                torch.tensor(TX), torch.tensor(RX), K, occluder=blocker)
    assert c[0] == 0 and c[1] != 0
    c.abs().sum().backward()
    assert torch.isfinite(points.grad).all() and points.grad[1].abs().sum() > 0


def test_scatter_rejects_nothing_silently_for_grazing_samples():
    grazing = torch.tensor([[0.0, 0.0, 0.0]], dtype=torch.float64)
    normal = torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64)  # perpendicular to the ray to the Tx
    c = scatter(grazing, normal, torch.ones(1, dtype=torch.float64), lambda cos: torch.ones_like(cos),
                torch.tensor(TX), torch.tensor(RX), K)
    assert c.item() == pytest.approx(0.0, abs=1e-12)
