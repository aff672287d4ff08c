"""Surface roughness: the height field's statistics against its definition, the Kirchhoff sum
over a rough plate (study `roughness`'s plate) against the Rayleigh (Ament) factor, and the
simulator's use of it."""

import math

import pytest
import torch

from rfsdf.radar import load_radar, simulate
from rfsdf.roughness import Roughness
from rfsdf.scene import Scene
from rfsdf.scene_spec import SceneSpec
from rfsdf.studies.roughness import WAVELENGTH_M, Settings, plate_return, run

K = 2 * math.pi / WAVELENGTH_M


def _points(count, extent_m, seed):
    generator = torch.Generator().manual_seed(seed)
    return (torch.rand(count, 3, dtype=torch.float64, generator=generator) - 0.5) * extent_m


def test_height_field_has_the_stated_rms_correlation_and_phase_statistics():
    rms, correlation = 0.4e-3, 3e-3
    points = _points(40_000, 0.3, 0)
    lag = torch.tensor([correlation, 0.0, 0.0], dtype=torch.float64)
    correlations, factors = [], []
    for seed in range(4):
        rough = Roughness(rms, correlation, seed)
        h = rough.height(points, "plate")
        assert abs(float(h.mean())) < 0.05 * rms
        assert float(h.std()) == pytest.approx(rms, rel=0.05)
        correlations.append(float((h * rough.height(points + lag, "plate")).mean() / h.var()))
        factors.append(abs(complex(torch.exp(2j * K * h).mean())))
    assert sum(correlations) / 4 == pytest.approx(math.exp(-1), abs=0.05)  # exp(-d^2 / l^2) at d = l
    assert sum(factors) / 4 == pytest.approx(math.exp(-2 * K**2 * rms**2), abs=0.03)  # Gaussian heights
    rough = Roughness(rms, correlation)
    torch.testing.assert_close(rough.height(points[:100], "a"), rough.height(points[:100], "a"))  # a fixed surface
    other = rough.height(points, "b")
    assert abs(float((other * rough.height(points, "a")).mean())) < 0.05 * rms**2  # another surface: independent
    assert rough.rms_slope == pytest.approx(math.sqrt(2) * rms / correlation)


@pytest.mark.parametrize("bad", [dict(rms_m=-1e-4, correlation_m=1e-3), dict(rms_m=1e-4, correlation_m=0.0),
                                 dict(rms_m=math.nan, correlation_m=1e-3)])
def test_bad_roughness_is_refused(bad):
    with pytest.raises(ValueError, match="roughness"):
        Roughness(**bad)


def test_rough_plate_mean_return_falls_by_the_rayleigh_factor():
    result = run(Settings(rms_wavelengths=(1 / 20,), realisations=12, tilts_deg=()))
    expected = math.exp(-2 * K**2 * (WAVELENGTH_M / 20) ** 2)  # 0.82
    assert result.rayleigh_factor == [pytest.approx(expected)]
    assert result.mean_return_factor[0] == pytest.approx(expected, abs=0.06)


def test_rough_oblique_return_is_the_surface_s_not_the_sampling_s():
    """A plate tilted away from the radar returns, when smooth, only its edges and the chance
    of its random samples: two samplings disagree by more than the return. Rough, it returns
    diffusely: two samplings agree and the return is many times larger."""
    tilt, rough, spacing = math.radians(25), Roughness(0.6e-3, 2.5e-3), WAVELENGTH_M / 6
    smooth = [plate_return(spacing, tilt, None, seed=seed) for seed in (0, 1)]
    rough_data = [plate_return(spacing, tilt, rough, seed=seed) for seed in (0, 1)]
    energy = lambda y: float((y.abs() ** 2).sum())  # noqa: E731
    assert energy(rough_data[0] - rough_data[1]) < 0.05 * energy(rough_data[0])
    assert energy(smooth[0] - smooth[1]) > energy(smooth[0])
    assert energy(rough_data[0]) > 4 * energy(smooth[0])


SPEC = {"name": "rough", "bounds": {"lower_m": [-0.06, -0.06, -0.06], "upper_m": [0.06, 0.06, 0.06]},
        "objects": [{"name": "ball", "material": "metal", "shape": {"type": "sphere", "radius_m": 0.02},
                     "roughness": {"rms_m": 3e-4, "correlation_m": 3e-3}},
                    {"name": "block", "material": "wood",
                     "shape": {"type": "box", "half_extents_m": [0.01, 0.01, 0.01], "center_m": [0.0, 0.04, 0.0]}}]}


def test_scene_moves_rough_samples_along_their_normals_only():
    scene = Scene(SceneSpec.model_validate(SPEC))
    samples = scene.sample_surface(1e-3, seed=0)
    moved = scene.rough_points(samples)
    ball = samples.object_index == 0
    torch.testing.assert_close(moved[~ball], samples.points[~ball])  # the smooth block stays
    shift = moved[ball] - samples.points[ball]
    along = (shift * samples.normals[ball]).sum(1)
    torch.testing.assert_close(shift, along[:, None] * samples.normals[ball], atol=1e-7, rtol=0)
    assert float(along.std()) == pytest.approx(3e-4, rel=0.15)
    assert "rough: 0.3 mm rms, 3 mm correlation" in scene.summary()


def test_simulate_refuses_heights_its_samples_cannot_resolve():
    spec = {**SPEC, "objects": [{**SPEC["objects"][0], "roughness": {"rms_m": 3e-4, "correlation_m": 1e-3}}]}
    with pytest.raises(ValueError, match="'ball': roughness correlation_m 1 mm needs surface samples at most 0.5 mm"):
        simulate(Scene(SceneSpec.model_validate(spec)), load_radar("near-77g"))
