"""Materials in the fit: the loss terms, the head's fit of a two-object scene, the estimates."""

import dataclasses
import math

import numpy as np
import pytest
import torch
import trimesh

from rfsdf.geometry import Grid
from rfsdf.material_estimates import (
    MIN_OBSERVED_FRACTION, READOUT_CEILING, MaterialEstimate, MaterialReport, class_accuracy, component_materials,
    eps_of_reflectivity, fit_materials, materials_table, object_materials, read_materials, readout_classes,
    counts, scene_reference, with_readout,
)
from rfsdf.materials import class_reflectivities, point_reflectivity, reflectivity_class
from rfsdf.radar import simulate
from rfsdf.radar.simulate import SIMULATED_GAIN
from rfsdf.recon import CoherentRenderer, Problem, ReconConfig, Trainer, amplitude_loss
from rfsdf.recon.calibration import check_reference, fitted_gain
from rfsdf.recon.config import CalibrationConfig
from rfsdf.recon.losses import material_cross_entropy, material_entropy
from rfsdf.recon.material_readout import primitive_union, read_brightness, read_surface, with_primitives
from rfsdf.recon.object_primitives import FramedPrimitive
from rfsdf.recon.trainer import initial_field
from rfsdf.recon.warm_start import fit_to_image
from test_recon import _two_balls


def test_the_entropy_term_falls_as_the_classes_become_decisive():
    """0 for certain points, log K for undecided ones; its gradient pushes a point's leading
    class up (the sign a decisive-class term must have)."""
    logits = torch.tensor([[0.5, 0.2, 0.1], [2.0, 0.0, 0.0]], requires_grad=True)
    probabilities = torch.softmax(logits, dim=1)
    entropy = material_entropy(probabilities, torch.tensor([1.0, 3.0]))
    entropy.backward()
    assert float(logits.grad[0, 0]) < 0 and float(logits.grad[1, 0]) < 0  # descending raises the leader
    assert float(material_entropy(torch.eye(3))) == pytest.approx(0.0, abs=1e-9)
    assert float(material_entropy(torch.full((4, 3), 1 / 3))) == pytest.approx(math.log(3))


def test_the_cross_entropy_term_pulls_towards_the_labels_and_ignores_unknown_points():
    logits = torch.zeros(3, 2, requires_grad=True)
    loss = material_cross_entropy(torch.softmax(logits, dim=1), torch.tensor([1, -1, 0]))
    loss.backward()
    assert float(loss.detach()) == pytest.approx(math.log(2))
    assert float(logits.grad[0, 1]) < 0 < float(logits.grad[0, 0])  # label 1: raise class 1
    assert float(logits.grad[2, 0]) < 0 < float(logits.grad[2, 1])
    assert torch.all(logits.grad[1] == 0)  # unlabelled
    none = material_cross_entropy(torch.softmax(logits, dim=1), torch.tensor([-1, -1, -1]))
    assert float(none.detach()) == 0.0 and none.requires_grad


def test_the_reflectivity_readout_inverts_fresnel():
    """A class's own |Gamma| reads that class; a lossless dielectric's normal-incidence
    |Gamma| = (sqrt(eps) - 1) / (sqrt(eps) + 1) gives back its eps'; a point half metal,
    half wood reflects the mean of their coefficients (both TE, the same sign at normal
    incidence), which is what the renderer reflects it by."""
    classes, frequency_hz = ("metal", "glass", "concrete", "plasterboard", "wood"), 79e9
    levels = class_reflectivities(classes, frequency_hz)
    assert float(levels[0]) == pytest.approx(1.0) and bool((levels[1:] < 0.5).all())
    assert list(reflectivity_class(levels.numpy(), classes, frequency_hz)) == list(classes)
    for eps in (2.0, 4.0, 6.3):
        r = (math.sqrt(eps) - 1) / (math.sqrt(eps) + 1)
        assert float(eps_of_reflectivity(r)) == pytest.approx(eps, rel=1e-9)
    mixed = point_reflectivity(torch.tensor([[0.5, 0, 0, 0, 0.5]]), classes, frequency_hz)
    assert mixed[0] == pytest.approx((1 + float(levels[4])) / 2, rel=1e-3)
    assert str(reflectivity_class(mixed[0], classes, frequency_hz)) == "glass"  # 0.59: nearer 0.43 than 1


def test_a_known_gain_makes_absolute_brightness_data():
    """With the gain fitted, a prediction twice too bright fits perfectly (only ratios are
    data); with the gain known it misfits by (2 - 1)^2 = 1 of the observed energy."""
    observed = torch.tensor([[1.0, 0.5, 0.25]])
    assert float(amplitude_loss(2 * observed.to(torch.complex64), observed)) == pytest.approx(0.0, abs=1e-7)
    assert float(amplitude_loss(2 * observed.to(torch.complex64), observed, fit_gain=False)) == pytest.approx(1.0)


def _fit_two_balls(tiny_radar, tmp_path, *, gain, steps: int):
    """A field regressed onto the two balls' true SDF, then ``steps`` with f held (the head
    learns the materials from the data alone)."""
    scene = _two_balls()
    data = simulate(scene, tiny_radar, seed=0, spacing_m=tiny_radar.acquisition().wavelength_m / 6)
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (16,) * 3)
    config = ReconConfig.model_validate({
        "field": {"width": 32, "depth": 4, "levels": 2}, "init": {"method": "sphere"},
        "render": {"element_step": 1, "refresh_every": 5},
        "sampling": {"views_per_step": 6, "data_batch": 1024, "eikonal_batch": 512},
        "train": {"steps": steps, "checkpoint_every": steps, "lr": 1e-3, "lr_end": 1e-4, "geometry_delay": 0.99,
                  "material_lr_scale": 10.0}})
    trainer = Trainer(Problem(data, grid, gain=gain), config, tmp_path / "run")
    fit_to_image(trainer.field, grid.lower_m, grid.upper_m, scene.sdf, None, steps=300, lr=3e-3, batch=2048,
                 eikonal_weight=0.1, generator=torch.Generator().manual_seed(0))
    return scene, data, trainer.fit()


def test_the_material_head_tells_a_metal_ball_from_a_wooden_one(tiny_radar, tmp_path):
    """From the data alone, with the gain fitted at each step (only ratios of |Gamma| are
    data): the metal ball reads metal, the wooden one a dielectric whose reflectivity
    relative to the metal ball's is the wood's 0.17 within a factor 2. Measured at 60 steps
    (1 thread): reflectivities 0.87 and 0.25 (ratio 0.29: plasterboard, wood's neighbour;
    the head's probabilities favour metal 0.83 and wood 0.60). Not with the gain known: the
    neural surface's glints are dimmer than the true one's, and the head makes up for it
    with brighter classes (the wooden ball reads metal, 0.42)."""
    scene, data, fit = _fit_two_balls(tiny_radar, tmp_path, gain=None, steps=60)
    estimates = {e.name: e for e in object_materials(fit.field, scene, data.acquisition)}
    assert estimates["metal_ball"].predicted == "metal" and estimates["metal_ball"].eps_real is None
    assert estimates["metal_ball"].probabilities["metal"] > 0.5
    wood = estimates["wood_ball"]
    assert wood.eps_real is not None and wood.true == "wood", wood
    assert 0.17 / 2 < wood.reflectivity / estimates["metal_ball"].reflectivity < 0.17 * 2, estimates
    assert wood.eps_real_interval[0] <= wood.eps_real <= wood.eps_real_interval[1]
    assert sum(wood.probabilities.values()) == pytest.approx(1.0)
    assert 0 < wood.observed_fraction < MIN_OBSERVED_FRACTION  # six views of a 4 cm array see little of it
    assert class_accuracy(list(estimates.values())) is None  # so neither counts in the accuracy


@pytest.fixture(scope="module")
def two_balls_start(tiny_radar, tmp_path_factory):
    """The two balls' scene, their data and the field's state regressed onto the true SDF:
    simulated and regressed once for every calibrated fit below (each would redo the same)."""
    scene = _two_balls()
    data = simulate(scene, tiny_radar, seed=0, spacing_m=tiny_radar.acquisition().wavelength_m / 6)
    grid = Grid((-0.06,) * 3, (0.06,) * 3, (16,) * 3)
    trainer = Trainer(Problem(data, grid), _calibrated_config("metal_ball=metal"), tmp_path_factory.mktemp("start"))
    fit_to_image(trainer.field, grid.lower_m, grid.upper_m, scene.sdf, None, steps=300, lr=3e-3, batch=2048,
                 eikonal_weight=0.1, generator=torch.Generator().manual_seed(0))
    return scene, data, grid, {k: v.clone() for k, v in trainer.field.state_dict().items()}


def _calibrated_config(reference: str) -> ReconConfig:
    return ReconConfig.model_validate({
        "field": {"width": 32, "depth": 4, "levels": 2}, "init": {"method": "sphere"},
        "render": {"element_step": 1, "refresh_every": 5},
        "sampling": {"views_per_step": 6, "data_batch": 1024, "eikonal_batch": 512},
        "train": {"steps": 40, "checkpoint_every": 40, "lr": 1e-3, "lr_end": 1e-4, "geometry_delay": 0.99,
                  "material_lr_scale": 10.0}, "calibration": {"reference": reference}})


def _calibrated_two_balls(two_balls_start, tmp_path, reference: str, *, scale: float = 1.0):
    """The two balls' data (times ``scale``, a radar gain), fitted as in
    :func:`_fit_two_balls` with the gain unknown and ``reference`` (NAME=MATERIAL) rendered
    as stated, from the regressed start; returns the reference's Calibration and the wooden
    ball's estimate."""
    scene, data, grid, start = two_balls_start
    data = dataclasses.replace(data, data=data.data * scale)
    config = _calibrated_config(reference)
    reference = scene_reference(scene, config.calibration, data.acquisition)
    problem = Problem(data, grid, known_materials=reference.labels(tuple(config.field.materials)))
    trainer = Trainer(problem, config, tmp_path / f"run-{reference.name}-{reference.material}-{scale}")
    trainer.field.load_state_dict(start)
    fit = trainer.fit()
    estimates = {e.name: e for e in object_materials(fit.field, scene, data.acquisition)}
    return check_reference(trainer, reference), estimates["wood_ball"], trainer


@pytest.fixture(scope="module")
def metal_referenced(two_balls_start, tmp_path_factory):
    """:func:`_calibrated_two_balls` with the metal ball the reference, as it is."""
    return _calibrated_two_balls(two_balls_start, tmp_path_factory.mktemp("metal"), "metal_ball=metal")


def test_a_metal_reference_calibrates_the_gain_and_a_wrong_one_is_flagged(two_balls_start, metal_referenced,
                                                                           tmp_path):
    """The metal ball named as the reference: the gain fitted to the data follows the radar's
    (data 3 x brighter: 3 x the gain, to 1 %), is the simulator's within 30 % (measured 1.28:
    the regressed glints are dimmer), and the wooden ball reads wood; the data want 0.89 x
    the reference's |Gamma|. The wooden ball called metal, or the metal one wood, disagree
    with the rest of the scene by more than AGREEMENT (measured 0.23 and 3.8)."""
    right, wood, _ = metal_referenced
    brighter, _, _ = _calibrated_two_balls(two_balls_start, tmp_path, "metal_ball=metal", scale=3.0)
    assert brighter.gain / right.gain == pytest.approx(3.0, rel=0.01)
    assert right.gain == pytest.approx(SIMULATED_GAIN, rel=0.3)
    assert right.warning() is None, right
    assert wood.predicted == "wood", wood
    for wrong in ("wood_ball=metal", "metal_ball=wood"):
        calibration, _, _ = _calibrated_two_balls(two_balls_start, tmp_path, wrong)
        assert calibration.warning() is not None and wrong in calibration.warning(), calibration



def test_the_report_reads_each_ball_in_closed_form_by_object_and_by_component(two_balls_start, metal_referenced):
    """``read_materials`` on the metal-referenced fit: the reference reads its stated |Gamma| (1)
    and the wooden ball wood's 0.171 within a factor 1.5 (measured 0.190); a mesh of the two balls
    (the true surfaces as two components) reads the same per component as per object within 2 %
    (in either order: their areas are equal), the reference with no spread over the views and the
    wooden ball with one. Relative (no reference, no known gain), scaled by
    the gain the finished fit wants: the metal ball within 10 % of 1 (measured 0.966), the ratio
    of the two as with the reference; in the simulator's gain, given after the fit, the relative
    readings times the fitted gain, the metal ball within 20 % of 1 (measured 1.15: a unit
    reflector on the fitted surface renders dimmer than the true ball)."""
    scene, data, _, _ = two_balls_start
    *_, trainer = metal_referenced
    mesh = trimesh.util.concatenate([trimesh.creation.icosphere(subdivisions=3, radius=0.015)
                                     .apply_translation([x, 0.0, 0.0]) for x in (-0.025, 0.025)])
    (objects, spread), (components, _) = read_materials(trainer, mesh, scene=scene, reference=("metal_ball", "metal"))
    wood = float(class_reflectivities(("wood",), data.acquisition.center_frequency_hz)[0])
    assert objects[0] == pytest.approx(1.0) and wood / 1.5 < objects[1] < wood * 1.5, objects
    # the reference reads 1 in every split with a view left out: no spread of its own; the wooden
    # ball's (measured 0.13) is that of six views of a 4 cm array, each a glint of its own
    assert spread[0] == pytest.approx(0.0, abs=1e-9) and 0.01 < spread[1] < 0.3, spread
    np.testing.assert_allclose(np.sort(components), np.sort(objects), rtol=0.02)
    (relative, _), _ = read_materials(trainer, mesh, scene=scene)
    assert relative[0] == pytest.approx(1.0, rel=0.1), relative
    assert relative[1] / relative[0] == pytest.approx(objects[1], rel=0.02)
    # the relative fit in the radar's gain
    (known, _), _ = read_materials(trainer, mesh, scene=scene, gain=SIMULATED_GAIN)
    np.testing.assert_allclose(known, relative * fitted_gain(trainer) / SIMULATED_GAIN, rtol=1e-5)
    assert known[0] == pytest.approx(1.0, rel=0.2), known


def test_a_known_gain_given_after_the_fit_scales_the_head_and_the_readout_alike(two_balls_start, metal_referenced,
                                                                               monkeypatch):
    """``fit_materials`` with the config's ``calibration.gain`` (and no reference): every
    reflectivity, the head's and the readout's, is the relative fit's times the fitted gain over the
    known one, and the calibration line says the gain came after the fit."""
    scene, *_ = two_balls_start
    *_, trainer = metal_referenced
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.015).apply_translation([-0.025, 0.0, 0.0])
    relative = fit_materials(trainer, mesh, scene=scene)
    monkeypatch.setattr(trainer, "config", trainer.config.model_copy(
        update={"calibration": CalibrationConfig(gain=SIMULATED_GAIN)}))
    known = fit_materials(trainer, mesh, scene=scene)
    scale = fitted_gain(trainer) / SIMULATED_GAIN
    assert known.head_scale == pytest.approx(scale) and "given after the relative fit" in known.calibration
    assert relative.head_scale == 1 and relative.calibration.startswith("relative")
    for before, after in zip(relative.objects + relative.components, known.objects + known.components):
        assert after.reflectivity == pytest.approx(before.reflectivity * scale, rel=1e-6)
        assert after.readout == pytest.approx(before.readout * scale, rel=1e-4)


def test_the_accuracy_and_the_tables_count_take_the_same_objects():
    """An object counts when observed at least the minimum share and not the calibration
    reference: in :func:`class_accuracy` and in the table's count of objects the interval tells apart."""
    assert counts(MIN_OBSERVED_FRACTION, False) and not counts(0.99 * MIN_OBSERVED_FRACTION, False)
    assert not counts(1.0, True) and counts(0.1, False, minimum=0.1)
    seen = MaterialEstimate("seen", "wood", {"wood": 1.0}, 2.0, (1.8, 2.2), 0.5, 0.17, (0.15, 0.19), "wood",
                            readout=0.17, readout_spread=0.01, readout_classes=["wood"])
    glimpsed = dataclasses.replace(seen, name="glimpsed", observed_fraction=0.1, true="metal")
    reference = dataclasses.replace(seen, name="plate", reference=True, true="metal")
    report = MaterialReport([seen, glimpsed, reference], [], class_accuracy([seen, glimpsed, reference]), "relative")
    assert report.accuracy == 1.0  # the wrong two do not count
    assert "(1 of 1 told from every other class" in materials_table(report.as_dict())


def test_the_table_keeps_the_components_classes_under_the_predicted_column():
    """With objects (a true column) the components' rows leave that column blank, so every row's
    predicted class stands under "predicted"."""
    ball = MaterialEstimate("ball", "wood", {"wood": 1.0}, 2.0, (1.8, 2.2), 0.5, 0.17, (0.15, 0.19), "wood")
    part = dataclasses.replace(ball, name="component 0 (3.0 cm^2)", predicted="glass", true=None)
    table = materials_table(MaterialReport([ball], [part], 1.0, "relative").as_dict()).splitlines()
    column = table[1].index("predicted")
    assert table[2][column:].startswith("wood ") and table[3][column:].startswith("glass "), table
    alone = materials_table(MaterialReport([], [part], None, "relative").as_dict()).splitlines()
    assert alone[2][alone[1].index("predicted"):].startswith("glass "), alone


def test_the_table_gives_the_readout_s_interval_and_the_classes_it_cannot_tell_apart():
    """A row read from the data shows its interval's half width (2 spreads) and, where that reaches
    another class, "or" it; the accuracy line counts the objects the interval tells from every other
    class, where some reading has one (not in a report from before the interval)."""
    ball = MaterialEstimate("ball", "wood", {"wood": 1.0}, 2.0, (1.8, 2.2), 0.5, 0.17, (0.15, 0.19), "wood")
    told = dataclasses.replace(ball, name="told", readout=0.17, source="data", readout_spread=0.01,
                               readout_classes=["wood"])
    undecided = dataclasses.replace(told, name="undecided", predicted="plasterboard", readout=0.22,
                                    readout_classes=["plasterboard", "wood"])
    table = materials_table(MaterialReport([told, undecided, ball], [], 2 / 3, "known radar gain 1").as_dict())
    lines = table.splitlines()
    column = lines[1].index("+-")  # right-aligned under it
    assert [line[column - 2:column + 2] for line in lines[2:5]] == ["0.02", "0.02", "   -"], table
    assert lines[3].endswith("or wood") and "or " not in lines[2] and lines[4].split()[-1] == "50%", table
    assert "(1 of 3 told from every other class by the readout's interval)" in lines[-1], table
    unread = materials_table(MaterialReport([ball], [], 1.0, "relative").as_dict())  # no interval: no count of them
    assert "told from" not in unread, unread


def test_a_readout_of_a_passive_surface_names_the_class_and_any_other_leaves_the_head_s():
    """``with_readout``: 0.45 reads glass (eps' from it, no interval), 0.98 metal (no eps'); above
    READOUT_CEILING (the surface is wrong), at 0 or NaN (the data show nothing) the head's class
    stands, the readout kept beside it where there is one."""
    head = MaterialEstimate("ball", "wood", {"wood": 1.0}, 2.0, (1.8, 2.2), 0.5, 0.17, (0.15, 0.19))
    classes = ("metal", "glass", "wood")

    def read(value):
        return with_readout(head, value, classes, 79e9)

    glass = read(0.45)
    assert (glass.predicted, glass.source, glass.readout, glass.eps_real_interval) == ("glass", "data", 0.45, None)
    assert glass.eps_real == pytest.approx(float(eps_of_reflectivity(0.45)))
    assert (read(0.98).predicted, read(0.98).eps_real) == ("metal", None)
    for value in (READOUT_CEILING + 0.05, 0.0):
        assert read(value) == dataclasses.replace(head, readout=value)
    assert read(float("nan")) == head


def test_a_mesh_component_without_area_is_not_read(tiny_radar):
    """Marching cubes can leave a component of degenerate faces: it has no surface to sample,
    and read, its area weights were 0/0 (NaN probabilities, which metrics.json refuses). Only
    the ball is read, its probabilities a distribution."""
    grid = Grid.from_voxel((-0.1,) * 3, (0.1,) * 3, 0.01)
    field = initial_field(grid, ReconConfig(), "cpu")
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.03)
    sliver = trimesh.Trimesh([[0.06, 0, 0], [0.07, 0, 0], [0.08, 0, 0]], [[0, 1, 2]], process=False)
    mesh = trimesh.util.concatenate([ball, sliver])
    assert len(mesh.split(only_watertight=False)) == 2
    (estimate,) = component_materials(field, mesh, tiny_radar.acquisition())
    assert f"({ball.area * 1e4:.1f} cm^2)" in estimate.name
    probabilities = np.array(list(estimate.probabilities.values()))
    assert np.isfinite(probabilities).all() and probabilities.sum() == pytest.approx(1.0, abs=1e-6)


def test_the_closed_form_readout_reads_each_ball_on_the_true_surface(tiny_radar):
    """On the two balls' true surface (metal and glass), the data's powers split over the balls
    read |Gamma| at normal incidence: with the simulator's gain known, the metal ball 1 within 3 %
    and the glass one glass (0.431; measured 1.019 and 0.485: the balls 5 cm apart share voxels,
    which the split in powers leaves); with the metal ball as the reference, the glass one the
    same within 1 %; a segment with no surface reads NaN, and without a scale only ratios are read."""
    scene = _two_balls("glass")
    data = simulate(scene, tiny_radar, seed=0, spacing_m=tiny_radar.acquisition().wavelength_m / 6)
    renderer = CoherentRenderer(data, Grid((-0.06,) * 3, (0.06,) * 3, (16,) * 3))
    ball = scene.object_index
    known, whole = read_surface(renderer, scene.sdf, [(ball, 3), (lambda anchors: torch.zeros(len(anchors)), 1)],
                                gain=SIMULATED_GAIN)
    metal, glass, empty = known.reflectivity
    truth = class_reflectivities(("metal", "glass"), data.acquisition.center_frequency_hz)
    assert metal == pytest.approx(1.0, rel=0.03) and np.isnan(empty)
    assert reflectivity_class(float(glass), ("metal", "glass", "concrete", "wood"), 79e9) == "glass", known
    assert glass == pytest.approx(float(truth[1]), rel=0.15)
    assert metal > whole.reflectivity[0] > glass  # the balls together: between the two
    labels = ball(renderer.candidates.anchors.double())
    referenced, again = read_brightness(renderer, [(labels, 2), (labels, 3)], reference=(0, 1.0))
    assert referenced.reflectivity[1] == pytest.approx(glass / metal, rel=0.01)
    np.testing.assert_array_equal(again.brightness[:2], referenced.brightness)  # the same segments, the same split
    assert read_brightness(renderer, [(labels, 2)])[0].reflectivity is None
    glass_ball = labels == 1  # its candidates alone, as if the rest reflected 0
    unit = type("Unit", (), {"material_head": None, "reflectivity": lambda self, anchors: glass_ball.float()})()
    views, voxels = torch.arange(renderer.num_views), torch.arange(len(renderer.voxels))
    alone = renderer(unit, views, voxels, geometry=False, only=glass_ball)
    torch.testing.assert_close(alone, renderer(unit, views, voxels, geometry=False))
    ones = type("Ones", (), {"material_head": None, "reflectivity": lambda self, anchors: torch.ones(len(anchors))})()
    segments = torch.stack([labels == 0, glass_ball, labels == 2])  # the segment images against one render each
    together = renderer.segment_images(ones, views, voxels, segments)
    for image, mine in zip(together, segments):
        torch.testing.assert_close(image, renderer(ones, views, voxels, geometry=False, only=mine))
    assert together[2].abs().max() == 0 and together[1].abs().max() > 0


class _SegmentRenderer:
    """A renderer of S segments (candidate i is segment i) whose unit images are ``parts`` (S, V, N)
    complex: what ``read_brightness`` asks of a CoherentRenderer, with the data ``observed`` (V, N)."""

    device = torch.device("cpu")

    def __init__(self, parts: torch.Tensor, observed: torch.Tensor):
        self.parts, self.num_views = parts, parts.shape[1]
        self.observed_peak = float(observed.abs().max())
        self.observed = observed / self.observed_peak

    def segment_images(self, unit, views, index, masks):
        return torch.stack([self.parts[mask].sum(0)[views][:, index] for mask in masks])


def test_the_readout_s_spread_is_the_jackknife_over_views_and_none_where_every_view_agrees():
    """Two segments seen by five views, the data's powers sum_i a_iv^2 |p_i|^2 exactly: where each
    segment's a is the same in every view, every view left out reads the same (spread 0); where the
    second's grows from view to view (0.3, 0.35, ... 0.5), the spread is the jackknife's
    sqrt((V-1)/V sum_v (x_v - mean)^2) over the leave-one-out least-squares splits (here
    unconstrained: every a > 0), computed by numpy, of the brightness and, with the first segment
    the reference (|Gamma| 1), of the ratio. One view: no spread."""
    generator = torch.Generator().manual_seed(0)
    parts = torch.randn(2, 5, 400, dtype=torch.complex128, generator=generator)
    labels = torch.arange(2)

    def observed(second):  # (V, N) amplitudes of the data, segment 0 at 1, segment 1 at ``second`` (V,)
        return (parts[0].abs() ** 2 + (second[:, None] * parts[1].abs()) ** 2).sqrt().to(torch.complex128)

    steady = read_brightness(_SegmentRenderer(parts, observed(torch.full((5,), 0.4, dtype=torch.float64))),
                             [(labels, 2)], gain=1.0)[0]
    np.testing.assert_allclose(steady.brightness * steady.scale, [1.0, 0.4], rtol=1e-9)
    np.testing.assert_allclose(steady.spread, 0.0, atol=1e-9)

    second = torch.linspace(0.3, 0.5, 5, dtype=torch.float64)
    renderer = _SegmentRenderer(parts, observed(second))
    gained, referenced = (read_brightness(renderer, [(labels, 2)], **scale)[0]
                          for scale in ({"gain": 1.0}, {"reference": (0, 1.0)}))
    design = (parts.abs() ** 2).numpy()  # (S, V, N)
    target = (renderer.observed.abs() ** 2).numpy() * renderer.observed_peak ** 2
    left_out = np.array([np.sqrt(np.linalg.lstsq(np.delete(design, v, 1).reshape(2, -1).T,
                                                 np.delete(target, v, 0).ravel(), rcond=None)[0]) for v in range(5)])

    def jackknife(x):
        return np.sqrt(4 / 5 * ((x - x.mean(0)) ** 2).sum(0))

    np.testing.assert_allclose(gained.spread, jackknife(left_out), rtol=1e-6)
    np.testing.assert_allclose(referenced.spread, jackknife(left_out / left_out[:, :1]), rtol=1e-6, atol=1e-12)
    assert referenced.spread[0] == pytest.approx(0.0, abs=1e-12) and gained.spread[1] > 0.01
    alone = read_brightness(_SegmentRenderer(parts[:, :1], observed(second)[:1]), [(labels, 2)], gain=1.0)[0]
    assert np.isnan(alone.spread).all() and np.isfinite(alone.brightness).all()


def test_a_readout_names_every_class_its_interval_reaches():
    """``readout_classes``: the classes nearest some |Gamma| within the reading +- 2 spreads. Wood
    0.171 and plasterboard 0.246 at 79 GHz meet at their mean, 0.209: 0.22 +- 2 x 0.01 reaches both,
    0.23 +- 2 x 0.01 plasterboard alone; wood +- 0.4 reaches glass (0.431), and plasterboard, whose
    whole range lies between, is named too. ``with_readout`` keeps the list and the spread beside
    the reading; without a spread there is no interval and no list."""
    classes = ("metal", "glass", "plasterboard", "wood")
    wood, plasterboard = (float(v) for v in class_reflectivities(("wood", "plasterboard"), 79e9))
    middle = (wood + plasterboard) / 2
    assert readout_classes(middle + 0.01, 0.01, classes, 79e9) == ["plasterboard", "wood"]
    assert readout_classes(middle + 0.03, 0.01, classes, 79e9) == ["plasterboard"]
    assert readout_classes(wood, 0.2, classes, 79e9) == ["glass", "plasterboard", "wood"]
    head = MaterialEstimate("box", "wood", {"wood": 1.0}, 2.0, (1.8, 2.2), 0.5, 0.17, (0.15, 0.19))
    read = with_readout(head, middle + 0.01, classes, 79e9, spread=0.01)
    assert (read.predicted, read.readout_spread) == ("plasterboard", 0.01)
    assert read.readout_classes == ["plasterboard", "wood"]
    assert with_readout(head, middle + 0.01, classes, 79e9).readout_classes is None  # no spread: no interval


def test_the_surface_read_is_the_primitives_near_them_and_the_network_elsewhere():
    """``with_primitives``: within PRIMITIVE_BAND_M of a primitive its SDF (a 1 cm sphere's exact
    distance), farther the network's (here a plane's, in float32 as a network takes it)."""
    sphere = FramedPrimitive("sphere", [0.0, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.01])
    plane = lambda points: points[:, 2] - 0.05  # noqa: E731
    surface = with_primitives(plane, [sphere])
    points = torch.tensor([[0.0, 0.0, 0.011], [0.0, 0.0, 0.009], [0.0, 0.04, 0.0], [0.0, 0.0, 0.2]],
                          dtype=torch.float64)
    assert surface(points).tolist() == pytest.approx([0.001, -0.001, -0.05, 0.15], abs=1e-7)
    assert with_primitives(plane, [])(points).tolist() == pytest.approx((points[:, 2] - 0.05).tolist(), abs=1e-7)
    above = FramedPrimitive("sphere", [0.0, 0.0, 0.03], [0.0, 0.0, 1e-6], [0.01])  # the union: the nearer's
    assert primitive_union(points.float(), [sphere, above]).tolist() == pytest.approx([0.001, -0.001, 0.03, 0.16],
                                                                                        abs=1e-7)
