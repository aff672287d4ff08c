"""Every study at --quick size: its JSON keys, and the sign of each claim it makes."""

import json

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from rfsdf.cli import main
from rfsdf.materials import MATERIAL_CLASSES, get_material
from rfsdf.studies import STUDIES, basin
from rfsdf.studies.ball_fit import small_radar


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Each study run once through the CLI at --quick size: its JSON."""
    out = tmp_path_factory.mktemp("studies")
    found = {}
    for name in STUDIES:
        result = CliRunner().invoke(main, ["study", name, "--quick", "--out", str(out)])
        assert result.exit_code == 0, result.output
        assert (out / f"{name}.png").stat().st_size > 0
        found[name] = json.loads((out / f"{name}.json").read_text())
    return found


def test_every_study_writes_its_settings_and_documented_result(results):
    for name, data in results.items():
        assert data["study"] == name and data["quick"] is True and data["settings"]
        assert set(data["result"]) == {f.name for f in STUDIES[name].Result.__dataclass_fields__.values()}


def test_sphere_tracing_centre_ray_one_step_grazing_slow_and_history_closed_form(results):
    r = results["sphere-tracing"]["result"]
    assert set(r["centre_ray_steps"].values()) == {1} and r["every_ray_below_radius_hits"]
    for steps in r["steps"].values():
        assert steps[-1] > 10 * steps[1]  # 89.9 deg against the first oblique angle
    assert r["worked_max_difference_m"] < 1e-12 and len(r["worked_traced_m"]) > 3


def test_eikonal_exact_shapes_and_where_csg_stops_being_a_distance(results):
    r = results["eikonal"]["result"]
    assert max(r["residual_max"].values()) < 1e-9  # float64: every primitive and transform
    assert r["union"]["residual_max"] < 1e-9  # min() keeps |grad f| = 1 ...
    assert r["union"]["error_inside_max_mm"] > 10 > 1 > r["union"]["error_outside_max_mm"]  # ... but not the distance
    assert r["smooth_union"]["residual_max"] > 0.1


def test_eikonal_1d_fit_is_a_signed_distance_to_the_point(results):
    r = results["eikonal-1d"]["result"]
    assert r["max_error_away"] < 5e-3 and r["zeros"] == 1 and r["sign"] in (-1, 1)


def test_study_list_and_unknown_name():
    listed = CliRunner().invoke(main, ["study", "--list"])
    assert listed.exit_code == 0 and all(name in listed.output for name in STUDIES)
    unknown = CliRunner().invoke(main, ["study", "marching"])
    assert unknown.exit_code == 2 and unknown.output.startswith("error: unknown study 'marching'; known: ")


def test_permittivity_needs_separated_angles_and_tm_beyond_brewster_is_ambiguous(results):
    r = results["permittivity"]["result"]
    noise, separation = r["noise_levels"], r["separations_deg"]
    assert noise == [0.001, 0.1] and separation == [2.0, 50.0]
    te = r["relative_rms_error"]["TE"]
    assert te[0][1] < 0.01 < 0.05 < te[0][0]  # at 0.1 % noise: 50 deg apart recovers eps', 2 deg barely
    assert te[1][0] > 1 > 0.5 > te[1][1]  # at 10 % noise 2 deg apart is hopeless, 50 deg is not
    assert r["noiseless_estimate"]["TE"] == pytest.approx(5.24, rel=1e-5)
    assert abs(r["noiseless_estimate"]["TM"] / 5.24 - 1) > 0.5  # 20 and 70 deg straddle a Brewster angle


def test_marching_cubes_error_falls_as_h_squared_on_an_exact_sdf_and_plateaus_on_a_fitted_one(results):
    r = results["marching-cubes"]["result"]
    assert r["error_order"] < -1.6  # about -2
    assert r["exact"]["evaluations"] == [n**3 for n in r["resolutions"]]
    fitted, exact = r["fitted"]["mean_mm"], r["exact"]["mean_mm"]
    assert fitted[-1] > 0.7 * fitted[1] and fitted[-1] > 5 * exact[-1]  # the fit's error, not the mesher's


def test_loss_gradient_autograd_matches_finite_differences_in_every_layer(results):
    r = results["loss-gradient"]["result"]
    geometry = [e for name, e in zip(r["layers"], r["relative_error"]) if name.startswith("geometry")]
    assert len(geometry) >= 6 and max(geometry) < 1e-5  # through the projection, scatter, A and A^H
    assert max(r["relative_error"]) < 1e-3  # the reflectivity layers' derivatives are small, FD noisier


def test_geometric_init_gives_one_component_where_random_init_gives_any_number(results):
    r = results["geometric-init"]["result"]
    assert set(r["components_at_init"]["geometric"]) == {1} == set(r["components_after_fit"]["geometric"])
    assert set(r["components_at_init"]["random"]) != {1}  # several, or none, depending on the seed
    assert max(r["residual_mm"]["geometric"]) < min(r["residual_mm"]["random"])


def test_encoding_levels_quick_run_is_sane(results):
    r = results["encoding-levels"]["result"]
    assert r["suggested_levels"] == 4  # ceil(log2(120 mm / 8 mm))
    assert all(0 < e < 20 for e in r["small_error_mm"] + r["large_error_mm"])


def test_ambiguity_one_view_cannot_tell_the_family_apart_and_more_views_can(results):
    r = results["ambiguity"]["result"]
    assert r["view_counts"] == [1, 4]
    one, four = r["contrast"]
    assert one < 3 and four > 4 * one  # one view: the family is about as good as the truth


def test_sdf_normals_beat_occupancy_normals_on_the_same_budget(results):
    r = results["occupancy-vs-sdf"]["result"]
    assert r["sdf_normal_error_deg"][0] < r["occupancy_normal_error_deg"][0]
    assert r["sdf_chamfer_mm"][0] < 1  # both learn the ball; the SDF's normals are the better
    assert r["occupancy_chamfer_mm"][0] < 2


def test_eikonal_sampling_uniform_points_keep_the_box_a_distance(results):
    r = results["eikonal-sampling"]["result"]
    assert r["near_shares"] == [0.0, 1.0]
    uniform, near = r["eikonal_box"]
    assert uniform < near  # near-surface points alone leave the rest of the box free
    assert all(0 < s < 5 for s in r["seconds_per_step"])


def test_sigma_annealing_fits_move_the_ball_towards_the_truth(results):
    r = results["sigma-annealing"]["result"]
    for name, curves in r["radius_error_mm"].items():
        start = r["start_errors_mm"][0]
        assert curves[0][-1] < start, name  # every schedule shrinks a ball started too large


def test_super_resolution_psf_follows_c_over_2b_and_the_fit_beats_the_threshold(results):
    points = results["super-resolution"]["result"]["sweeps"]["bandwidth_ghz"]
    assert [p["bandwidth_ghz"] for p in points] == [1.0, 4.0]
    for p in points:
        assert 0.7 < p["range_psf_mm"] / p["range_resolution_mm"] < 1.0  # -3 dB of sinc^2: 0.886 c/2B
        assert 0.6 < p["cross_psf_mm"] / p["cross_resolution_mm"] < 1.3
        assert p["fit_chamfer_mm"] < p["start_chamfer_mm"] and 2 * p["fit_chamfer_mm"] < p["mf_chamfer_mm"]
    assert points[0]["range_psf_mm"] > 3 * points[1]["range_psf_mm"]


def test_roughness_rayleigh_factor_and_diffuse_return_of_the_surface_not_the_sampling(results):
    r = results["roughness"]["result"]
    assert r["mean_return_factor"][0] == pytest.approx(r["rayleigh_factor"][0], abs=0.1)  # 6 realisations
    row = {(o["surface"], o["placement"], o["samples_per_wavelength"]): o for o in r["oblique"]}
    noisy, fine = row[("smooth", "random", 3)], row[("smooth", "random", 12)]
    assert noisy["sampling_difference_db"] > noisy["return_db"] - 3  # at lambda/3 the smooth return is the sampling's
    assert noisy["return_db"] > fine["return_db"] + 6  # ... and far above what it converges to
    assert row[("smooth", "stratified", 3)]["sampling_difference_db"] < noisy["sampling_difference_db"] - 10
    rough, smooth = row[("rms 0.5 mm", "stratified", 12)], row[("smooth", "stratified", 12)]
    assert rough["return_db"] > smooth["return_db"] + 6 and rough["sampling_difference_db"] < rough["return_db"] - 20


def test_basin_each_loss_is_lowest_at_the_truth_and_rises_with_the_error(results):
    r = results["basin"]["result"]
    for name, at_starts in r["start_loss"].items():
        assert r["truth_loss"][name] < min(at_starts)
        assert at_starts == sorted(at_starts)  # 1 mm, then 4 mm
    assert r["start_observed_mm"][0] < r["start_observed_mm"][1]
    for schedule, ends in r["end_objects_mm"].items():
        assert len(ends) == len(r["errors_mm"]) and all(set(end) == set(r["start_objects_mm"][0]) for end in ends)


def test_basin_losses_read_each_facet_as_told():
    """``SurfaceLosses(reading=...)``: the true classes read back give the same losses, and a
    metal sphere read as glass renders every image |Gamma_glass| as bright, so its relative
    amplitude loss is (1 - |Gamma_glass|)^2."""
    scene, losses = basin.surface_losses(basin.QUICK)
    assert [obj.material.name for obj in scene.objects] == ["metal"]
    as_class = lambda index: (lambda classes: torch.nn.functional.one_hot(  # noqa: E731
        torch.full_like(classes, index) if index is not None else classes, len(MATERIAL_CLASSES)).float())
    truth = losses(scene.sdf)
    assert losses(scene.sdf, reading=as_class(None)) == truth and truth["amplitude"] < 1e-3
    eps = complex(get_material("glass").permittivity(small_radar().acquisition().center_frequency_hz))
    gamma = abs((1 - np.sqrt(eps)) / (1 + np.sqrt(eps)))
    as_glass = losses(scene.sdf, reading=as_class(MATERIAL_CLASSES.index("glass")))
    assert as_glass["amplitude"] == pytest.approx((1 - gamma) ** 2, rel=0.03)
