"""Fresnel and permittivity against closed forms."""

import math

import numpy as np
import pytest
import torch

from rfsdf.materials import (
    Material, brewster_angle, class_permittivities, estimate_permittivity, fresnel, fresnel_of_cosine, get_material,
    MATERIAL_CLASSES, FresnelTable, mixture_fresnel, reflectance,
)


@pytest.mark.parametrize("eps", [2.0, 4.0, 6.31 - 0.29j])
def test_normal_incidence_closed_form(eps):
    expected = (1 - np.sqrt(eps)) / (1 + np.sqrt(eps))
    assert complex(fresnel(0.0, eps, "TE")) == pytest.approx(expected, abs=1e-12)
    assert complex(fresnel(0.0, eps, "TM")) == pytest.approx(-expected, abs=1e-12)  # design's TM sign
    assert float(reflectance(0.0, eps, "mean")) == pytest.approx(abs(expected) ** 2, abs=1e-12)


@pytest.mark.parametrize("eps", [2.0, 5.24, 9.0])
def test_brewster_angle_zeroes_tm(eps):
    theta_b = brewster_angle(eps)
    assert theta_b == pytest.approx(math.atan(math.sqrt(eps)))
    assert float(reflectance(theta_b, eps, "TM")) < 1e-25
    thetas = torch.linspace(0, 1.5, 1501, dtype=torch.float64)
    assert float(thetas[reflectance(thetas, eps, "TM").argmin()]) == pytest.approx(theta_b, abs=1e-3)


def test_pec_reflects_fully_at_every_angle():
    thetas = torch.linspace(0, 1.56, 20, dtype=torch.float64)
    for pol in ("TE", "TM", "mean"):
        torch.testing.assert_close(fresnel(thetas, math.inf, pol).abs(), torch.ones(20, dtype=torch.float64))
    assert get_material("metal").pec and math.isinf(get_material("metal").permittivity(79e9).real)


def test_grazing_incidence_reflects_fully_for_lossy_media():
    for pol in ("TE", "TM"):
        assert float(reflectance(math.pi / 2, 5.24 - 0.3j, pol)) == pytest.approx(1.0, abs=1e-12)


def test_lossy_reflectance_matches_independent_numpy_derivation():
    eps, theta = 5.24 - 0.32j, 0.6
    kz1, kz2 = np.cos(theta), np.sqrt(eps - np.sin(theta) ** 2 + 0j)
    te = (kz1 - kz2) / (kz1 + kz2)
    tm = (eps * kz1 - kz2) / (eps * kz1 + kz2)
    assert complex(fresnel(theta, eps, "TE")) == pytest.approx(te)
    assert complex(fresnel(theta, eps, "TM")) == pytest.approx(tm)
    assert kz2.imag < 0  # decaying branch for the exp(+j w t) convention


def test_itu_catalogue_values():
    concrete = get_material("concrete").permittivity(79e9)
    sigma = 0.0462 * 79**0.7822
    assert concrete.real == pytest.approx(5.24)
    assert -concrete.imag == pytest.approx(17.98 * sigma / 79, rel=1e-3)  # eps'' = 17.98 sigma / f_GHz
    assert get_material("drywall") is get_material("plasterboard")
    with pytest.raises(ValueError, match="outside"):
        get_material("brick").permittivity(79e9)  # ITU gives brick only up to 40 GHz
    with pytest.raises(ValueError, match="unknown material"):
        get_material("unobtainium")
    assert Material.from_permittivity("teflon", 2.1).permittivity(79e9) == 2.1


@pytest.mark.parametrize("pol", ["TE", "TM"])
def test_permittivity_recovered_from_synthetic_reflectances(pol):
    thetas = np.array([0.1, 0.5, 0.9])
    measured = reflectance(torch.as_tensor(thetas), 4.7, pol).numpy()
    result = estimate_permittivity(thetas, measured, pol)
    assert result.eps_real == pytest.approx(4.7, rel=1e-5)


def test_permittivity_estimate_rejects_inconsistent_data():
    with pytest.raises(ValueError, match="no permittivity"):
        estimate_permittivity([0.1, 0.8], [0.9, 0.01], "TE")  # TE reflectance grows with angle
    with pytest.raises(ValueError, match=">= 2 angles"):
        estimate_permittivity([0.1], [0.1])
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        estimate_permittivity([0.1, 0.2], [0.1, 1.5])


@pytest.mark.parametrize("pol", ["TE", "TM"])
def test_permittivity_with_an_unknown_gain_comes_from_the_shape_across_angles(pol):
    thetas = np.radians([20.0, 50.0])
    measured = 3.7 * reflectance(torch.as_tensor(thetas), 5.24, pol).numpy()  # an uncalibrated radar's scale
    result = estimate_permittivity(thetas, measured, pol, unknown_gain=True)
    assert result.eps_real == pytest.approx(5.24, rel=1e-5) and result.gain == pytest.approx(3.7, rel=1e-5)
    # With the gain assumed known, the same data fit nothing (or something else).
    with pytest.raises(ValueError, match="no permittivity|must be finite and in"):
        estimate_permittivity(thetas, measured, pol)


@pytest.mark.parametrize("polarization", ["TE", "TM", "mean"])
def test_fresnel_of_the_cosine_is_fresnel_and_differentiable_at_normal_incidence(polarization):
    """The renderer takes gradients through the incidence geometry; through arccos they are
    infinite at normal incidence (0 x inf = NaN), through the cosine they are finite and
    match finite differences, and d|Gamma|/dcos = 0 there (|Gamma| is even in theta)."""
    thetas = torch.linspace(0, 1.5, 31, dtype=torch.float64)
    eps = 6.31 - 0.29j
    torch.testing.assert_close(fresnel_of_cosine(torch.cos(thetas), eps, polarization), fresnel(thetas, eps, polarization))
    cos = torch.tensor([1.0, 0.9, 0.5], dtype=torch.float64, requires_grad=True)
    fresnel_of_cosine(cos, eps, polarization).abs().sum().backward()
    assert torch.isfinite(cos.grad).all()
    assert torch.autograd.gradcheck(lambda c: fresnel_of_cosine(c, eps, polarization).abs(), (cos[1:].detach().requires_grad_(),))


def test_a_mixture_of_classes_reflects_the_expected_coefficient():
    """sum_k p_k Gamma_k: a certain class gives its own coefficient, an even mixture the mean,
    and the gradient in p_k is Gamma_k."""
    cos = torch.tensor([1.0, 0.7], dtype=torch.float64)
    eps = torch.tensor([complex(math.inf, 0), 5.24 - 0.1j], dtype=torch.complex128)
    certain = torch.tensor([[1.0, 0.0], [0.0, 1.0]], dtype=torch.float64)
    torch.testing.assert_close(mixture_fresnel(cos, certain, eps),
                               torch.stack([fresnel_of_cosine(cos[0], eps[0], "mean"), fresnel_of_cosine(cos[1], eps[1], "mean")]))
    even = torch.full((2, 2), 0.5, dtype=torch.float64, requires_grad=True)
    mixed = mixture_fresnel(cos, even, eps)
    torch.testing.assert_close(mixed, 0.5 * (fresnel_of_cosine(cos, eps[0], "mean") + fresnel_of_cosine(cos, eps[1], "mean")))
    mixed.real.sum().backward()
    torch.testing.assert_close(even.grad[:, 1], fresnel_of_cosine(cos, eps[1], "mean").real)


def test_the_fresnel_table_reproduces_the_mixture_and_its_gradients():
    """The renderer's lookup against the closed form, for the catalogue's classes at every
    cosine (the ends included): values to 1e-6, the derivative in the cosine to 2e-3 of its
    largest value, the derivative in p_k exactly Gamma_k (up to the interpolation)."""
    eps = class_permittivities(MATERIAL_CLASSES, 79e9)
    generator = torch.Generator().manual_seed(0)
    cos = torch.cat([torch.tensor([0.0, 1.0]), torch.rand(5000, generator=generator)]).double()
    probabilities = torch.softmax(torch.randn(len(cos), len(eps), generator=generator, dtype=torch.float64), 1)
    table = FresnelTable(eps)
    exact_cos, table_cos = cos.clone().requires_grad_(), cos.clone().requires_grad_()
    exact_p, table_p = probabilities.clone().requires_grad_(), probabilities.clone().requires_grad_()
    exact, tabulated = mixture_fresnel(exact_cos, exact_p, eps), table.mixture(table_cos, table_p)
    assert float((exact - tabulated).detach().abs().max()) < 1e-6
    exact.abs().sum().backward()
    tabulated.abs().sum().backward()
    assert float((exact_cos.grad - table_cos.grad).abs().max()) < 2e-3 * float(exact_cos.grad.abs().max())
    torch.testing.assert_close(table_p.grad, exact_p.grad, atol=1e-6, rtol=0)
    assert table.mixture(cos.float(), probabilities.float()).dtype == torch.complex64


def test_the_mixture_of_a_metal_has_finite_gradients_at_grazing_incidence():
    """A facet turned edge-on to the radar (cos = 0, e.g. a box's side seen along an axis):
    the PEC's constant must not carry the dielectric formula's 0 / 0 into the gradient."""
    eps = class_permittivities(("metal", "glass"), 79e9)
    cos = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64, requires_grad=True)
    probabilities = torch.tensor([[1.0, 0.0], [0.5, 0.5], [1.0, 0.0]], dtype=torch.float64, requires_grad=True)
    mixture_fresnel(cos, probabilities, eps).abs().sum().backward()
    assert torch.isfinite(cos.grad).all() and torch.isfinite(probabilities.grad).all()
