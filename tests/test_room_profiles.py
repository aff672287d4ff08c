"""The primitive fit at room scale: range profiles of the data against ray votes of a model."""

import dataclasses
import json
import math
import tomllib

import pytest
import tomli_w
import torch
import trimesh
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.geometry.differential import gradient
from rfsdf.radar import SPEED_OF_LIGHT, load_radar, simulate, write_measurements
from rfsdf.recon.hybrid import fit_hybrid_profiles, residual_amplitude_m
from rfsdf.recon.neural_profiles import NeuralProfileSettings, distil_start, fit_neural_profiles
from rfsdf.recon.primitive import RELATIVE_GAIN, PrimitiveField
from rfsdf.recon.range_profile import (ProfileSettings, _blur, _window, data_profiles, fit_primitive_profiles, model_profiles,
                                      noise_floor, path_axis, profile_loss, view_beams)
from rfsdf.scene import Scene
from rfsdf.scene_model import SceneModel
from rfsdf.scene_spec import SceneSpec


def _room(east, south) -> dict:
    """Two 30 x 30 cm walls 2 cm thick around room-60g's views (at 0.3 m about (0, 0, 1.5)):
    concrete facing -x with its centre at ``east``, metal facing +y at ``south`` (either a
    parameter table)."""
    wall = lambda name, material, half, centre: {  # noqa: E731
        "name": name, "material": material, "shape": {"type": "box", "half_extents_m": half, "center_m": centre}}
    return {"name": "two-room-walls", "bounds": {"lower_m": [-1.6, -1.6, 0.8], "upper_m": [1.6, 1.6, 2.2]},
            "objects": [wall("east", "concrete", [0.01, 0.15, 0.15], east),
                        wall("south", "metal", [0.15, 0.01, 0.15], south)]}


@pytest.fixture(scope="module")
def room_data():
    radar = load_radar("room-60g")
    truth = Scene(SceneSpec.model_validate(_room([1.2, 0.0, 1.5], [0.0, -0.9, 1.5])))
    return truth, simulate(truth, radar, seed=0, max_samples=40_000)  # facets: faster than 136 k points


def test_a_walls_profile_peaks_at_its_image_source_in_data_and_model(room_data):
    """The view facing the east wall: the data's range profile peaks at the round-trip path
    of the wall's face (x = 1.19 m less the array's x), and so does the model's profile of
    the true walls, within 5 mm of range; the model's south wall, 0.89 m from the origin,
    peaks in the view facing it."""
    truth, data = room_data
    path = path_axis(data, 0.0025, 0.5)
    measured = data_profiles(data, path)
    field = PrimitiveField(SceneModel.from_table(_room({"start": [1.2, 0.0, 1.5]}, {"start": [0.0, -0.9, 1.5]}), "m"))
    modelled = model_profiles(field, data, path, rays_per_side=32, half_angle_rad=math.radians(70), sigma_m=0.0)
    acq = data.acquisition
    centres = torch.cat([acq.tx_m, acq.rx_m], dim=1).mean(1)
    east = int(acq.boresight[:, 0].argmax())
    south = int((-acq.boresight[:, 1]).argmax())
    expected_east = 2 * (1.19 - float(centres[east, 0]))
    expected_south = 2 * (float(centres[south, 1]) + 0.89)
    for profiles in (measured, modelled.detach()):
        assert float(path[profiles[east].argmax()]) == pytest.approx(expected_east, abs=0.01)
        assert float(path[profiles[south].argmax()]) == pytest.approx(expected_south, abs=0.01)
    assert SPEED_OF_LIGHT / acq.bandwidth_hz / 2 == pytest.approx(0.0214, abs=1e-4)  # room-60g's range resolution


def test_a_return_nearer_than_the_profiles_start_does_not_wrap_into_their_end(room_data):
    """A profile repeats every c / delta f: a return at 4 cm of path (a sheet the array
    stands by) would peak again at c / delta f + 4 cm. The axis stops 2 near_m short of the
    period, so it holds only a wall's own peak at 3 m, not the near return 30 dB over it."""
    data = room_data[1]
    f = data.acquisition.frequencies_hz.double()
    unambiguous = SPEED_OF_LIGHT / float(f[1] - f[0])
    path = path_axis(data, 0.0025, 0.5)
    assert float(path[0]) == 1.0 and unambiguous - 1.0 - 0.0025 <= float(path[-1]) < unambiguous - 1.0
    def echo(path_m):  # a point's spectrum at this round-trip path, every channel alike
        return torch.exp(-2j * math.pi * f * path_m / SPEED_OF_LIGHT).expand(data.data.shape)
    y = dataclasses.replace(data, data=(31.6 * echo(0.04) + echo(3.0)).to(data.data.dtype))
    profile = data_profiles(y, path)[0]
    assert abs(float(path[profile.argmax()]) - 3.0) < 0.005
    assert float(profile[path > unambiguous - 1.2].max()) < 1e-3 * float(profile.max())


def test_the_profile_path_gradient_is_the_sdfs_parameter_derivative(room_data):
    """Moving the east wall's centre by dx moves its votes' distance by dx: the loss's
    derivative by autograd equals a central difference of 0.1 mm of the same loss with the
    same rays (the weights held)."""
    _, data = room_data
    path = path_axis(data, 0.0025, 0.5)
    target = data_profiles(data, path)
    table = _room({"start": [1.23, 0.0, 1.5]}, [0.0, -0.9, 1.5])

    def loss(x: float | None = None) -> tuple[torch.Tensor, PrimitiveField]:
        field = PrimitiveField(SceneModel.from_table(table, "m"))
        if x is not None:
            with torch.no_grad():
                field.values[0][0] = x
        p = model_profiles(field, data, path, rays_per_side=32, half_angle_rad=math.radians(70), sigma_m=0.1)
        return profile_loss(p, target), field

    value, field = loss()
    value.backward()
    h = 1e-4
    numeric = (float(loss(1.23 + h)[0].detach()) - float(loss(1.23 - h)[0].detach())) / (2 * h)
    assert float(field.values[0].grad[0]) == pytest.approx(numeric, rel=0.05), (field.values[0].grad, numeric)
    assert abs(numeric) > 1e-3  # the wall's distance is in the loss



def _with_noise(data, sigma: float, seed: int):
    """``data`` with complex Gaussian noise of E|n|^2 = sigma^2 added (its noise_std set to match)."""
    g = torch.Generator().manual_seed(seed)
    draw = torch.complex(*(torch.randn(data.data.shape, generator=g, dtype=torch.float64) for _ in range(2)))
    return dataclasses.replace(data, data=data.data + (sigma / math.sqrt(2) * draw).to(data.data.dtype),
                               noise_std=math.hypot(sigma, data.noise_std or 0.0))


def test_the_noise_floor_is_the_power_noise_alone_leaves_in_a_profile(room_data):
    """Noise alone of E|n|^2 = sigma^2 gives every profile bin sigma^2 sum(w_k^2) in the mean
    (w the Hann window over frequency): the floor where the noise is known equals it, and
    the data's mean profile over 2-40 m of path does within 2 %; where it is not known (real
    captures), each view's median bin stands in for it, within 8 %."""
    _, data = room_data
    sigma = 0.3
    noise = _with_noise(dataclasses.replace(data, data=torch.zeros_like(data.data), noise_std=None), sigma, seed=1)
    path = path_axis(noise, 0.005, 0.5)
    profiles = data_profiles(noise, path)
    expected = sigma**2 * float((_window(len(data.acquisition.frequencies_hz)) ** 2).sum())
    assert torch.allclose(noise_floor(noise, profiles), torch.full((len(profiles), 1), expected, dtype=profiles.dtype))
    assert float(profiles.mean()) == pytest.approx(expected, rel=0.02)
    unknown = noise_floor(dataclasses.replace(noise, noise_std=None), profiles)
    assert torch.allclose(unknown, torch.full_like(unknown, expected), rtol=0.08), unknown.flatten() / expected


def test_a_beam_sums_its_arrays_channels_coherently_towards_its_direction(room_data):
    """room-60g's 3Tx/4Rx array: unit-norm beams, one at boresight; a plane wave from a beam's
    direction (channel phases exp(+j k u . (p_tx + p_rx - 2 c))) gives that beam T R times a
    channel's power and its neighbours (a Rayleigh step off) under a tenth of it; noise alone
    leaves a beam's bins the floor a channel's have (unit norm), within 2 %. So the east
    wall, at its view's boresight, peaks T R = 12 times higher (10.8 dB) in the boresight
    beam than in the channels' mean, in the data and in the model alike, and the model's beam
    profiles correlate with the data's as the channels' mean does (>= 0.98)."""
    truth, data = room_data
    acq = data.acquisition
    beams = view_beams(acq, math.radians(70))
    channels = acq.tx_m.shape[1] * acq.rx_m.shape[1]
    assert beams.shape[0] == acq.tx_m.shape[0] and beams.shape[2] == channels
    assert torch.allclose(beams.abs().pow(2).sum(-1), torch.ones(beams.shape[:2], dtype=torch.float64))
    centre = (len(beams[0]) - 1) // 2
    gains = (beams[0].conj() @ (beams[0, centre] * math.sqrt(channels))).abs() ** 2
    assert float(gains[centre]) == pytest.approx(channels)
    assert float(gains[centre - 1]) < 0.1 * channels and float(gains[centre + 1]) < 0.1 * channels
    sigma = 0.3
    noise = _with_noise(dataclasses.replace(data, data=torch.zeros_like(data.data), noise_std=None), sigma, seed=1)
    path = path_axis(noise, 0.005, 0.5)
    beamed = data_profiles(noise, path, beams)
    assert float(beamed.mean()) == pytest.approx(float(noise_floor(noise, beamed).mean()), rel=0.02)
    east = int(acq.boresight[:, 0].argmax())
    field = PrimitiveField(SceneModel.from_table(_room({"start": [1.2, 0.0, 1.5]}, {"start": [0.0, -0.9, 1.5]}), "m"))
    for beam_set in (None, beams):
        measured = data_profiles(data, path, beam_set)
        with torch.no_grad():
            modelled = model_profiles(field, data, path, rays_per_side=32, half_angle_rad=math.radians(70), sigma_m=0.0,
                                      beams=beam_set)
        if beam_set is None:
            mean_peaks = (float(measured[east].max()), float(modelled[east].max()))
        else:
            assert float(measured[east, centre].max()) == pytest.approx(channels * mean_peaks[0], rel=0.03)
            assert float(modelled[east, centre].max()) == pytest.approx(channels * mean_peaks[1], rel=0.03)
        seen = modelled.flatten(1).amax(1) > 0  # the views a wall faces (the others see only edges)
        for m, d in zip(modelled.flatten(1)[seen].sqrt(), measured.flatten(1)[seen].sqrt()):
            assert float(torch.nn.functional.cosine_similarity(m, d, dim=0)) >= 0.98


def test_the_blur_by_fft_is_the_direct_convolution():
    """The beams' blur by FFT against the direct convolution (zero outside the axis): the
    same values within 1e-12 over narrow to wide kernels, on (V, B, P) profiles."""
    profiles = torch.rand(3, 4, 2000, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    for sigma in (0.002, 0.05, 0.4):
        assert torch.allclose(_blur(profiles, sigma, 0.005, fft=True), _blur(profiles, sigma, 0.005), atol=1e-12)


def test_with_the_noise_floor_the_true_walls_explain_a_profile_a_few_db_over_the_noise(room_data):
    """The east wall's clean peak 5 dB over the noise of its view: the true walls' profile plus
    the floor explains the data (the loss a tenth of the model's without it, which the noise
    dominates), and over the wall moved by up to 10 cm the loss with the floor is least at the truth."""
    truth, data = room_data
    path = path_axis(data, 0.005, 0.5)
    east = int(data.acquisition.boresight[:, 0].argmax())
    peak = float(data_profiles(data, path)[east].max())
    window = float((_window(len(data.acquisition.frequencies_hz)) ** 2).sum())
    noisy = _with_noise(data, math.sqrt(peak / 10 ** 0.5 / window), seed=3)  # the clean peak 5 dB over it
    target = data_profiles(noisy, path)
    floor = noise_floor(noisy, target)
    assert 4.0 < 10 * math.log10(float(target[east].max() / floor[east])) < 9.0

    def losses(offset_m: float) -> tuple[float, float]:
        field = PrimitiveField(SceneModel.from_table(_room({"start": [1.2 + offset_m, 0.0, 1.5]}, [0.0, -0.9, 1.5]), "m"))
        with torch.no_grad():
            model = model_profiles(field, noisy, path, rays_per_side=32, half_angle_rad=math.radians(70), sigma_m=0.0)
        return float(profile_loss(model, target)), float(profile_loss(model, target, floor))

    offsets = (-0.1, -0.05, -0.02, 0.0, 0.02, 0.05, 0.1)
    scan = {offset: losses(offset) for offset in offsets}
    without, with_floor = scan[0.0]
    assert with_floor < 0.1 * without
    assert min(offsets, key=lambda offset: scan[offset][1]) == 0.0, scan


def _behind_glass(east) -> dict:
    """The two walls of :func:`_room`, the east one metal, and a 1 cm glass sheet 24 x 24 cm at
    x = 0.8 m before it (every ray from the view facing it to the wall crosses it)."""
    table = _room(east, [0.0, -0.9, 1.5])
    table["objects"][0]["material"] = "metal"
    table["objects"].append({"name": "pane", "material": "glass",
                             "shape": {"type": "box", "half_extents_m": [0.005, 0.12, 0.12], "center_m": [0.8, 0.0, 1.5]}})
    return table


def test_with_transmission_a_wall_behind_glass_votes_through_it(room_data):
    """A metal wall behind a 1 cm glass sheet, seen by the view facing it: opaque, the
    model's profile has the sheet alone and the wall nothing; with transmission the wall's
    vote stands farther by twice the slab's delay over the band (where a profile through
    P.2040's T(f)^2 peaks, tests/test_slab.py, as the simulator's data do), with |T|^4 of the bare
    wall's power, and the wall's distance carries its gradient through the sheet (a central
    difference of the loss against the profile of the wall where it is)."""
    from rfsdf.materials import get_material
    from rfsdf.recon.range_profile import DELAY_FREQUENCIES
    from rfsdf.slab import band_delay, slab_coefficients

    acquisition_of = room_data[1]  # the model's profiles read only the acquisition
    glass_table = _behind_glass([1.2, 0.0, 1.5])
    bare_table = {**glass_table, "objects": glass_table["objects"][:2]}
    path = path_axis(acquisition_of, 0.0025, 0.5)
    acq = acquisition_of.acquisition
    east = int(acq.boresight[:, 0].argmax())
    centre_x = float(torch.cat([acq.tx_m, acq.rx_m], dim=1).mean(1)[east, 0])
    eps = complex(get_material("glass").permittivity(acq.center_frequency_hz))
    t = complex(slab_coefficients(1.0, eps, 0.01, acq.center_frequency_hz, "mean")[1])
    f = acq.frequencies_hz.double()
    band = torch.linspace(float(f.min()), float(f.max()), DELAY_FREQUENCIES, dtype=torch.float64)
    delay = band_delay(torch.tensor(1.0, dtype=torch.float64), lambda hz: get_material("glass").permittivity(hz), 0.01,
                       acq.center_frequency_hz, band, torch.hann_window(len(band), periodic=False, dtype=torch.float64))
    wall = 2 * (1.19 - centre_x) + 2 * float(delay)
    near = (path - wall).abs() < 0.03

    def profile(scene_table, transmission, x=None):
        field = PrimitiveField(SceneModel.from_table(scene_table, "m"))
        if x is not None:
            with torch.no_grad():
                field.values[0][0] = x
        return model_profiles(field, acquisition_of, path, rays_per_side=32, half_angle_rad=math.radians(70),
                              sigma_m=0.0, transmission=transmission), field

    opaque, _ = profile(glass_table, False)
    through, _ = profile(glass_table, True)
    bare, _ = profile(bare_table, True)
    assert float(opaque[east, near].max()) < 1e-6 * float(opaque[east].max())  # hidden by the sheet
    assert float(path[near][through[east, near].argmax()]) == pytest.approx(wall, abs=0.003)
    assert float(through[east, near].max()) / float(bare[east, near].max()) == pytest.approx(abs(t) ** 4, rel=0.02)
    target = through.detach()
    free = json.loads(json.dumps(glass_table))
    free["objects"][0]["shape"]["center_m"] = {"start": [1.21, 0.0, 1.5]}

    def loss(x=None):
        p, field = profile(free, True, x)
        return profile_loss(p, target), field

    value, field = loss()
    value.backward()
    h = 1e-4
    numeric = (float(loss(1.21 + h)[0].detach()) - float(loss(1.21 - h)[0].detach())) / (2 * h)
    assert abs(numeric) > 1e-3 and float(field.values[0].grad[0]) == pytest.approx(numeric, rel=0.05)


def test_specular_feet_through_glass_reach_the_wall_behind_it():
    """The seen surface a model demo scores: opaque, the view facing the east wall finds its
    foot on the glass sheet only; with transmission also on the wall behind it (x = 1.19 m)."""
    from rfsdf.metrics import specular_feet

    scene = Scene(SceneSpec.model_validate(_behind_glass([1.2, 0.0, 1.5])))
    acq = load_radar("room-60g").acquisition()
    opaque = specular_feet(scene, acq, rays_per_side=61)
    through = specular_feet(scene, acq, rays_per_side=61, transmission=True)
    assert not (opaque[:, 0] > 1.0).any()
    assert ((through[:, 0] - 1.19).abs() < 1e-3).sum() == 1 and len(through) == len(opaque) + 1


def _reconstruct(room_data, tmp_path, model_kind: str, steps: int, south, east_start: float, *more: str) -> dict:
    """`rfsdf reconstruct --model KIND --fit-to profiles [MORE]` of the two walls, the east
    wall's x started at ``east_start``: each free parameter's fitted value by name."""
    write_measurements(tmp_path / "room.h5", room_data[1])
    model = tmp_path / "model.toml"
    model.write_text(tomli_w.dumps(_room({"start": [east_start, 0.0, 1.5], "bounds_m": [[1.0, 0, 1.5], [1.4, 0, 1.5]]},
                                         south)))
    result = CliRunner().invoke(main, ["reconstruct", str(tmp_path / "room.h5"), "--out", str(tmp_path / "run"),
                                       "--model", model_kind, "--fit-to", "profiles", "--scene-model", str(model),
                                       "--steps", str(steps), *more])
    assert result.exit_code == 0, result.output
    return {row["name"]: row["fitted"] for row in json.loads((tmp_path / "run" / "primitive.json").read_text())["free"]}


@pytest.mark.parametrize("more", [(), ("--beams",)])
def test_reconstruct_fits_two_room_walls_to_their_range_profiles(room_data, tmp_path, more):
    """`rfsdf reconstruct --model primitive --fit-to profiles [--beams]`: the walls started 12
    and 9 cm off (six range resolutions) come back within 1 cm (measured: 0.2 and 0.7 mm), the
    run writes primitive.json, fitted-scene.toml and mesh.ply."""
    fitted = _reconstruct(room_data, tmp_path, "primitive", 40,
                          {"start": [0.0, -0.81, 1.5], "bounds_m": [[0, -1.1, 1.5], [0, -0.7, 1.5]]}, 1.32, *more)
    assert fitted["east.center_m"][0] == pytest.approx(1.2, abs=0.01), fitted
    assert fitted["south.center_m"][1] == pytest.approx(-0.9, abs=0.01), fitted
    assert (tmp_path / "run" / "fitted-scene.toml").is_file() and (tmp_path / "run" / "mesh.ply").is_file()


def test_reconstruct_reaches_a_wall_behind_glass_with_transmission_only(room_data, tmp_path):
    """`rfsdf reconstruct --model primitive --fit-to profiles --transmission`: a model that
    holds a 3 mm glass sheet before the east wall, the wall started 3 cm off. Opaque, the
    sheet hides the wall from the model's rays and it stays where it started; seen through,
    it comes back within 1 cm of the data's wall (nearer by the sheet's excess path, about
    5 mm, which the data, simulated without the sheet, do not have)."""
    write_measurements(tmp_path / "room.h5", room_data[1])
    table = _behind_glass({"start": [1.23, 0.0, 1.5], "bounds_m": [[1.0, 0, 1.5], [1.4, 0, 1.5]]})
    table["objects"][-1]["shape"]["half_extents_m"][0] = 0.0015
    model = tmp_path / "model.toml"
    model.write_text(tomli_w.dumps(table))
    east = {}
    for more in ((), ("--transmission",)):
        run = tmp_path / f"run{len(more)}"
        result = CliRunner().invoke(main, ["reconstruct", str(tmp_path / "room.h5"), "--out", str(run), "--model",
                                           "primitive", "--fit-to", "profiles", "--scene-model", str(model),
                                           "--steps", "16", *more])
        assert result.exit_code == 0, result.output
        east[more] = json.loads((run / "primitive.json").read_text())["free"][0]["fitted"][0]
    assert east[("--transmission",)] == pytest.approx(1.2, abs=0.01), east
    assert east[()] == pytest.approx(1.23, abs=0.003), east


def test_reconstruct_fits_a_hybrid_model_and_its_residual_stays_within_two_range_resolutions(room_data, tmp_path):
    """`rfsdf reconstruct --model hybrid --fit-to profiles`: the primitives come back as with
    --model primitive, then the residual's steps; the fitted mesh lies within the residual's
    amplitude (2 c / 2B = 4.3 cm) of the fitted primitive scene."""
    fitted = _reconstruct(room_data, tmp_path, "hybrid", 30, [0.0, -0.9, 1.5], east_start=1.25)
    assert fitted["east.center_m"][0] == pytest.approx(1.2, abs=0.01), fitted
    mesh = trimesh.load(tmp_path / "run" / "mesh.ply")
    primitive = Scene(SceneSpec.model_validate(tomllib.loads((tmp_path / "run" / "fitted-scene.toml").read_text())))
    distance = primitive.sdf(torch.as_tensor(mesh.vertices)).abs()
    assert float(distance.max()) < 2 * SPEED_OF_LIGHT / (2 * 7e9)


@pytest.mark.parametrize("joint", [False, True])
def test_the_hybrid_fits_its_residual_after_its_primitives_or_jointly(room_data, joint):
    """With no residual steps, the hybrid fitted after its primitives keeps its residual at
    exactly zero (the primitives alone were fitted); fitted jointly, the residual moved
    with them, within its amplitude, and the east wall came back within 1 cm all the same."""
    _, data = room_data
    model = SceneModel.from_table(_room({"start": [1.25, 0.0, 1.5], "bounds_m": [[1.0, 0, 1.5], [1.4, 0, 1.5]]},
                                        [0.0, -0.9, 1.5]), "m")
    amplitude = residual_amplitude_m(data.acquisition.bandwidth_hz)
    fit = fit_hybrid_profiles(data, model, amplitude_m=amplitude, lower_m=[-1.6, -1.6, 0.8], upper_m=[1.6, 1.6, 2.2],
                              steps=30 if joint else 2, residual_steps=0, joint=joint)
    with torch.no_grad():
        residual = fit.field.residual(torch.rand(4096, 3, dtype=torch.float64) * 3.2 - 1.6 + torch.tensor([0, 0, 1.5]))
    if not joint:
        assert float(residual.abs().max()) == 0.0
        return
    assert 0 < float(residual.abs().max()) < amplitude
    assert float(fit.field.values[0].detach()[0]) == pytest.approx(1.2, abs=0.01)


def test_hybrid_needs_the_range_profiles(room_data, tmp_path):
    result = CliRunner().invoke(main, ["reconstruct", str(tmp_path / "x.h5"), "--out", str(tmp_path / "run"),
                                       "--model", "hybrid", "--scene", "l-room"])
    assert result.exit_code == 2 and "--model hybrid fits range profiles only" in result.output, result.output


def test_free_materials_are_read_from_each_walls_return_over_its_image_source(room_data):
    """The walls at their true places, materials free (undecided among metal, glass,
    concrete, plasterboard and wood): with the metal south wall held as the reference, east
    reads concrete's |Gamma(0)| (0.39 at 60.5 GHz) within 20 % and so concrete (measured:
    0.33; the walls are 30 cm, under three Fresnel zones sqrt(lambda R / 2) across, and their
    edges move the return off the image source's, metal's to 0.98); with both free the
    simulated data's gain of 1 reads both (concrete, metal); a wrong reference (south held as
    wood, |Gamma| 0.17) scales east down by as much, as a radar engineer's calibration would;
    with neither (a capture), they are relative to the brightest and no class is read."""
    _, data = room_data
    truth = SceneSpec.model_validate(_room([1.2, 0.0, 1.5], [0.0, -0.9, 1.5]))

    def read(east, south) -> dict:
        table = _room([1.2, 0.0, 1.5], [0.0, -0.9, 1.5])
        table["objects"][0]["material"], table["objects"][1]["material"] = east, south
        fit = fit_primitive_profiles(data, SceneModel.from_table(table, "m"))
        return {row["name"]: row for row in fit.material_table(truth)}

    referenced = read({"free": True}, "metal")["east"]
    assert referenced["start"] is None and referenced["truth"] == "concrete" and referenced["probabilities"] is None
    assert referenced["reflectivity"] == pytest.approx(0.39, rel=0.2), referenced
    assert referenced["fitted"] == "concrete" and referenced["calibration"] == "the held materials' returns"
    both = read({"free": True}, {"free": True})
    assert [both["east"]["fitted"], both["south"]["fitted"]] == ["concrete", "metal"], both
    assert both["east"]["calibration"].startswith("1 (rfsdf's simulated data")
    wrong = read({"free": True}, "wood")["east"]
    assert wrong["reflectivity"] == pytest.approx(referenced["reflectivity"] * 0.17, rel=0.1), wrong
    data = dataclasses.replace(data, metadata={})  # a capture: no gain known, no reference held
    relative = read({"free": True}, {"free": True})
    assert relative["south"]["reflectivity"] == 1.0 and relative["south"]["calibration"] == RELATIVE_GAIN
    assert relative["east"]["reflectivity"] == pytest.approx(both["east"]["reflectivity"]
                                                            / both["south"]["reflectivity"], rel=1e-6)
    assert relative["east"]["fitted"] is None  # no class from a relative reflectivity


def _face_x(sdf, lower: float = 1.0, upper: float = 1.4) -> float:
    """Where f first turns negative along the east view's boresight (y = 0, z = 1.5) [m]."""
    x = torch.linspace(lower, upper, 4001, dtype=torch.float64)
    with torch.no_grad():
        values = sdf(torch.stack([x, torch.zeros_like(x), torch.full_like(x, 1.5)], dim=1))
    return float(x[int((values < 0).nonzero()[0])])


def test_the_neural_model_starts_at_its_start_model_and_the_profiles_move_a_seen_wall(room_data):
    """The neural model at room scale (rfsdf.recon.neural_profiles), started from walls whose
    east one is 10 cm thick with its face 4 cm too far (x = 1.23 m; the truth's, 2 cm thick,
    at 1.19): distilled in 400 steps with the gradient term, its face on the east view's
    boresight is within 6 mm of the start's, its normals within 10 deg of the start's at the
    median (L1 on f alone left 40 deg, and the ray votes read normals), and the room's air
    is outside (f > 0 at every view, which a sphere's initialisation got wrong); 30 profile
    steps then move that face at least 1.5 cm towards the truth, and do not lose it: it ends
    within 3.5 cm of the truth. At lr 1e-3 the path is chaotic in the float rounding: the
    same code ended at 1.207 m on one machine and 1.161 (past the truth) on another, where
    7e-4 and 5e-4 ended at 1.224 and 1.212; at 3e-3 the wall is lost."""
    _, data = room_data
    table = _room([1.28, 0.0, 1.5], [0.0, -0.9, 1.5])
    table["objects"][0]["shape"]["half_extents_m"] = [0.05, 0.15, 0.15]
    start = SceneModel.from_table(table, "m")
    settings = NeuralProfileSettings(distil_steps=400, batch=4096, gradient_weight=0.01, steps=30, lr=1e-3)
    acq = data.acquisition
    field = distil_start(start, [-1.6, -1.6, 0.8], [1.6, 1.6, 2.2], acq.bandwidth_hz, settings=settings)
    distilled = _face_x(field.frozen_sdf())
    assert distilled == pytest.approx(1.23, abs=0.006)
    surface = field.near_points[:5000].double()
    normal = lambda sdf: torch.nn.functional.normalize(gradient(sdf, surface), dim=1)  # noqa: E731
    cosines = (normal(field.frozen_sdf()) * normal(PrimitiveField(start).frozen_sdf())).sum(1)
    assert float(cosines.median()) > math.cos(math.radians(10))
    with torch.no_grad():
        assert bool((field.frozen_sdf()(torch.cat([acq.tx_m, acq.rx_m], dim=1).double().mean(1)) > 0).all())
    fit = fit_neural_profiles(data, field, settings=settings, profile=ProfileSettings(rays_per_side=24))
    assert len(fit.losses) == 30
    assert 1.19 - 0.035 < _face_x(field.frozen_sdf()) < distilled - 0.015


def test_reconstruct_fits_the_neural_model_to_the_profiles_and_refuses_what_it_does_not_take(room_data, tmp_path,
                                                                                              monkeypatch):
    """`rfsdf reconstruct --model neural --fit-to profiles` from a start model: neural.json
    (the network's weights, its levels from the range resolution, one loss per step, the
    start) and a mesh near the walls; the image fit's options are one line each, and so is
    a start that is missing."""
    from rfsdf.recon import neural_profiles

    small = NeuralProfileSettings(width=32, depth=3, distil_steps=300, batch=2048)
    monkeypatch.setattr(neural_profiles, "NeuralProfileSettings", lambda: small)  # the suite's seconds
    write_measurements(tmp_path / "room.h5", room_data[1])
    model = tmp_path / "model.toml"
    model.write_text(tomli_w.dumps(_room([1.23, 0.0, 1.5], [0.0, -0.9, 1.5])))
    args = ["reconstruct", str(tmp_path / "room.h5"), "--model", "neural", "--fit-to", "profiles"]
    result = CliRunner().invoke(main, [*args, "--scene-model", str(model), "--steps", "3", "--out",
                                       str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    row = json.loads((tmp_path / "run" / "neural.json").read_text())
    assert row["steps"] == 3 and len(row["losses"]) == 3 and row["start"] == {"scene_model": str(model)}
    assert row["levels"] == 8 and row["parameters"] > 0 and row["settings"]["width"] == 32  # 3.2 m box, 2.1 cm
    mesh = trimesh.load(tmp_path / "run" / "mesh.ply")
    truth = Scene(SceneSpec.model_validate(_room([1.2, 0.0, 1.5], [0.0, -0.9, 1.5])))
    assert len(mesh.faces) > 0 and float(truth.sdf(torch.as_tensor(mesh.vertices)).abs().median()) < 0.1
    for extra, message in ((["--scene-model", str(model), "--gain", "g.json"], "--gain: not for --model neural"),
                           ([], "needs --scene-model, or --scene")):
        result = CliRunner().invoke(main, [*args, *extra, "--out", str(tmp_path / "other")])
        assert result.exit_code == 2 and message in result.output and result.output.count("\n") == 1, result.output
        assert not (tmp_path / "other").exists()
