"""Slab reflection and transmission (rfsdf.slab) against closed forms and a boundary-value solve."""

import math

import numpy as np
import pytest
import torch

from rfsdf.materials import MATERIALS, fresnel
from rfsdf.slab import excess_path, slab_coefficients

C = 299_792_458.0
F = 79e9


def boundary_value_slab(cos_inc: float, eps: complex, d: float, f: float, polarization: str) -> tuple[complex, complex]:
    """The slow, obviously-right reference: a plane wave from z < 0 on a layer 0 < z < d.

    TE: the field is E_y; E_y and dE_y/dz are continuous. TM: H_y and (1/eps) dH_y/dz are.
    Fields (convention exp(+j omega t), so a wave along +z is exp(-j kz z)):
    air in front exp(-j k0z z) + r exp(+j k0z z); slab a exp(-j k1z z) + b exp(+j k1z z);
    air behind t exp(-j k0z z), so t is the field behind the slab over the field without it.
    Four continuity equations in (r, a, b, t), solved by numpy."""
    k0 = 2 * math.pi * f / C
    k0z = k0 * cos_inc
    k1z = k0 * np.sqrt(complex(eps) - 1 + cos_inc**2)
    if k1z.imag > 0:
        k1z = -k1z  # the root that decays along +z
    w = 1.0 if polarization == "TE" else 1 / complex(eps)  # weight of the derivative in the slab
    e1, e2 = np.exp(-1j * k1z * d), np.exp(1j * k1z * d)
    e0 = np.exp(-1j * k0z * d)
    # unknowns x = (r, a, b, t)
    m = np.array([
        [-1, 1, 1, 0],                                                # field at z = 0
        [1j * k0z, 1j * k1z * w, -1j * k1z * w, 0],                   # derivative at z = 0 (rhs: +j k0z)
        [0, e1, e2, -e0],                                             # field at z = d
        [0, -1j * k1z * w * e1, 1j * k1z * w * e2, 1j * k0z * e0],    # derivative at z = d
    ], dtype=complex)
    rhs = np.array([1, 1j * k0z, 0, 0], dtype=complex)
    r, _, _, t = np.linalg.solve(m, rhs)
    return complex(r), complex(t)


@pytest.mark.parametrize("name", [n for n, m in MATERIALS.items() if not m.pec and m.in_band(F)])
@pytest.mark.parametrize("polarization", ["TE", "TM"])
@pytest.mark.parametrize("degrees", [0.0, 30.0, 60.0])
def test_slab_coefficients_match_a_boundary_value_solve_for_every_catalogue_material(name, polarization, degrees):
    eps = MATERIALS[name].permittivity(F)
    cos_inc = math.cos(math.radians(degrees))
    for d in (0.5e-3, 3e-3, 2e-2):
        r, t = slab_coefficients(cos_inc, eps, d, F, polarization)
        r_ref, t_ref = boundary_value_slab(cos_inc, eps, d, F, polarization)
        assert abs(complex(r) - r_ref) <= 1e-9 * max(1.0, abs(r_ref)), (name, d)
        assert abs(complex(t) - t_ref) <= 1e-9, (name, d)


def test_a_lossless_slab_conserves_power_and_a_quarter_wave_one_reflects_the_most():
    eps = 4.0
    quarter = C / F / 4 / math.sqrt(eps)
    for cos_inc in (1.0, 0.8, 0.3):
        for polarization in ("TE", "TM"):
            r, t = slab_coefficients(cos_inc, eps, torch.linspace(0, 5e-3, 11), F, polarization)
            assert torch.allclose(r.abs() ** 2 + t.abs() ** 2, torch.ones(11, dtype=torch.float64), atol=1e-12)
    # at normal incidence a quarter-wave slab reflects 2 R' / (1 + R'^2) (R' = -1/3 for eps = 4)
    r, _ = slab_coefficients(1.0, eps, quarter, F)
    assert float(r.abs()) == pytest.approx(2 * (1 / 3) / (1 + 1 / 9), rel=1e-12)


def test_thin_and_thick_limits_and_the_pec():
    glass = MATERIALS["glass"].permittivity(F)
    r, t = slab_coefficients(1.0, glass, 0.0, F)
    assert float(r.abs()) < 1e-15 and complex(t) == pytest.approx(1.0)
    r, t = slab_coefficients(0.7, glass, 0.5, F)  # 50 cm of lossy glass: the half space, nothing through
    assert complex(r) == pytest.approx(complex(fresnel(math.acos(0.7), glass)), abs=1e-12)
    assert float(t.abs()) < 1e-12
    r, t = slab_coefficients(0.7, float("inf"), 1e-3, F, "TM")
    assert complex(r) == 1.0 and complex(t) == 0.0


def test_the_transmission_phase_is_the_excess_electrical_path():
    """Over a band the phase of a matched slab (eps near 1: no internal reflections) turns as
    the excess path: d (sqrt(eps - sin^2) - cos) per unit wavenumber."""
    eps, d, cos_inc = 1.02, 0.05, 0.6
    f = torch.linspace(77e9, 81e9, 5)
    phase = torch.stack([torch.angle(slab_coefficients(cos_inc, eps, d, float(fk))[1]) for fk in f])
    k = 2 * math.pi * f.double() / C
    slope = -float(np.polyfit(k.numpy(), np.unwrap(phase.numpy()), 1)[0])
    assert slope == pytest.approx(float(excess_path(cos_inc, eps, d)), rel=1e-3)
    assert float(excess_path(1.0, 4.0, 3e-3)) == pytest.approx(3e-3, rel=1e-12)  # d (sqrt(4) - 1)


def test_slab_coefficients_refuse_a_negative_thickness_and_an_unknown_polarization():
    with pytest.raises(ValueError, match="thickness"):
        slab_coefficients(1.0, 4.0, -1e-3, F)
    with pytest.raises(ValueError, match="polarization"):
        slab_coefficients(1.0, 4.0, 1e-3, F, "circular")


@pytest.mark.parametrize("name, thickness_m", [("glass", 0.005), ("glass", 0.02), ("plasterboard", 0.01), ("wood", 0.04)])
def test_a_range_profile_through_a_slab_peaks_at_its_band_delay(name, thickness_m):
    """The round trip through a slab at normal incidence over room-28g's band (26.5-29.5 GHz,
    Hann window): the power profile |sum_k w_k T(f_k)^2 exp(j 2 pi f_k p / c)|^2, summed on a
    0.01 mm grid of path p (the slow reference), peaks at twice the band delay within 0.5 mm
    of path (0.25 mm a way), which 2 cm of glass's internal reflections put 3 mm (a way)
    short of its excess path."""
    from rfsdf.materials import get_material
    from rfsdf.slab import band_delay, slab_over_band

    material, c = get_material(name), 299_792_458.0
    f = torch.linspace(26.5e9, 29.5e9, 400, dtype=torch.float64)
    window = torch.hann_window(400, periodic=False, dtype=torch.float64)
    permittivity = lambda hz: torch.as_tensor(material.permittivity(hz))  # noqa: E731
    t = torch.stack([tr for _, tr in slab_over_band(1.0, permittivity, thickness_m, 28e9, f, "mean")])
    path = torch.arange(-0.02, 0.2, 1e-5, dtype=torch.float64)
    profile = ((window * t**2)[None] * torch.exp(2j * math.pi * f[None] * path[:, None] / c)).sum(1).abs()
    peak = float(path[profile.argmax()])
    delay = float(band_delay(torch.tensor(1.0, dtype=torch.float64), permittivity, thickness_m, 28e9,
                             torch.linspace(26.5e9, 29.5e9, 17, dtype=torch.float64),
                             torch.hann_window(17, periodic=False, dtype=torch.float64)))  # as the profiles' model
    assert peak == pytest.approx(2 * delay, abs=5e-4)
    if (name, thickness_m) == ("glass", 0.02):
        excess = float(excess_path(1.0, complex(material.permittivity(28e9)).real, thickness_m))
        assert 2 * excess - peak > 5e-3
