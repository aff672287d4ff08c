"""The warm start's fragments read as primitives (rfsdf.recon.object_primitives)."""

import math
from dataclasses import replace

import pytest
import torch

from rfsdf import geometry as geo
from rfsdf.geometry import project_to_zero_set
from rfsdf.recon import object_primitives
from rfsdf.recon.glints import glint_caps
from rfsdf.recon.object_primitives import (ACCEPT_BETTER_M, ACCEPT_MEDIAN_M, ACCEPT_WITHIN, BRIDGE_MEDIAN_M,
                                           BRIDGE_MIN_PEAKS, FIT_LR, FRAGMENT_VOXEL_M, FREE_REACH_M, FREE_STEPS_M,
                                           JOIN_REACH_M, LINK_CLEAR_M, LINK_MIN_PEAKS, MIN_FRAGMENT_M3, MIN_PEAKS,
                                           ROTATION_LR_SCALE, SIZE_LR_SCALE, SPLIT_DEPTH_M, SURVIVORS, FramedPrimitive,
                                           Fragment, FragmentFit, _Evidence, candidates, bridged_peaks,
                                           explain_fragment, explain_linked, explain_split, explain_together,
                                           fit_fragment, fragments, free_space, joined, linked_pairs, near_groups,
                                           primitive_surface, primitive_target, split)

TURN = [0.2, -0.3, 0.4]  # a rotation vector [rad]
CENTRE = [0.01, -0.02, 0.005]


def _turned(shape: geo.SDF) -> geo.SDF:
    angle = math.sqrt(sum(c * c for c in TURN))
    return shape.rotate([c / angle for c in TURN], angle).translate(CENTRE)


@pytest.mark.parametrize("kind, sizes, reference", [
    ("sphere", [0.02], geo.Sphere(0.02)),
    ("box", [0.03, 0.02, 0.01], geo.Box([0.03, 0.02, 0.01])),
    ("cylinder", [0.015, 0.03], geo.CappedCylinder(0.015, 0.06)),
    ("capsule", [0.012, 0.02], geo.Capsule([0, 0, -0.02], [0, 0, 0.02], 0.012)),
    ("torus", [0.03, 0.01], geo.Torus(0.03, 0.01)),
])
def test_a_framed_primitive_is_the_library_shape_turned_and_moved(kind, sizes, reference, tmp_path):
    """... and its ``state`` through a ``weights_only`` file (a checkpoint) is the same shape."""
    points = torch.randn(200, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * 0.03
    framed = FramedPrimitive(kind, CENTRE, TURN, sizes)
    torch.testing.assert_close(framed(points).detach(), _turned(reference)(points))
    torch.save(framed.state(), tmp_path / "primitive.pt")
    held = FramedPrimitive.from_state(torch.load(tmp_path / "primitive.pt", weights_only=True))
    assert held.kind == kind
    torch.testing.assert_close(held(points).detach(), _turned(reference)(points))


def _on(sdf, count: int, seed: int) -> torch.Tensor:
    """Points on the zero set of ``sdf``: random points near it, projected (three Newton steps)."""
    points = (torch.rand(count, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(seed)) - 0.5) * 0.12
    points = project_to_zero_set(sdf, points)
    return points[sdf(points).abs() < 1e-6]


def _seen_from(truth, views: torch.Tensor, count: int = 200) -> tuple[torch.Tensor, torch.Tensor]:
    """``count`` points of ``truth``'s surface that face one of the unit ``views`` within 25
    degrees (its peaks) and the directions towards their views."""
    points = _on(truth, 4000, seed=1)
    facing = geo.normals(truth, points) @ views.T  # (N, V)
    best, view = facing.max(1)
    keep = torch.nonzero(best > math.cos(math.radians(25))).squeeze(1)[:count]
    return points[keep], views[view[keep]]


VIEWS = [[1.0, 0.2, 0.1], [-0.2, 1.0, 0.3], [0.1, -0.3, 1.0]]  # unit once normalised


def _explained(reference: geo.SDF, shrunk: geo.SDF, views=VIEWS) -> tuple[FragmentFit, geo.SDF]:
    """:func:`explain_fragment` of the turned ``reference`` seen from ``views`` (in its own frame,
    turned with it), its warm surface a rounded, 1 mm swollen version of it (``shrunk`` by 4 mm,
    swollen by 5: the warm start's shape errors); and the turned truth."""
    truth = _turned(reference)
    views = torch.tensor(views, dtype=torch.float64) @ geo.rotation_from_vector(torch.tensor(TURN)).T.double()
    peaks, towards = _seen_from(truth, views / views.norm(dim=1, keepdim=True))
    rounded = _turned(shrunk)
    warm = _on(lambda p: rounded(p) - 0.005, 400, seed=2)
    free = free_space(peaks, towards, [-0.2] * 3, [0.2] * 3)
    return explain_fragment(Fragment((1,), peaks, warm), free), truth


@pytest.mark.parametrize("kind, reference, shrunk", [
    ("box", geo.Box([0.03, 0.02, 0.015]), geo.Box([0.026, 0.016, 0.011])),
    ("sphere", geo.Sphere(0.025), geo.Sphere(0.021)),
    ("cylinder", geo.CappedCylinder(0.015, 0.05), geo.CappedCylinder(0.011, 0.042)),
])
def test_a_fragment_with_rounded_rims_is_read_as_its_sharp_primitive(kind, reference, shrunk):
    """A fragment seen on a few faces comes back as the true primitive: the peaks, the free
    space in front of them, and the rounded surface weakly."""
    fit, truth = _explained(reference, shrunk)
    assert fit.primitive.kind == kind and fit.explains
    assert fit.peaks_median_m < 2e-4 and fit.carved == 0
    true_surface = _on(truth, 2000, seed=3)
    assert float(fit.primitive(true_surface).detach().abs().median()) < 5e-4  # also where no view sees it


def test_a_capsule_is_read_where_the_views_see_its_ends_round_and_a_cylinder_where_they_do_not():
    """Seen on its sides and face-on at one end, where a cylinder's flat end lies within a tenth
    of a millimetre of the peaks too, a capsule is read as a cylinder (the fallback's margin);
    seen on one end from three sides, as a capsule."""
    def capsule(half_length: float) -> list[geo.SDF]:
        return [geo.Capsule([0, 0, -half_length], [0, 0, half_length], radius) for radius in (0.012, 0.008)]

    face_on, _ = _explained(*capsule(0.03))
    ends, truth = _explained(*capsule(0.02), views=[[0.0, 0.0, 1.0], [0.8, 0.0, 0.6], [-0.4, 0.7, 0.6], [0.0, -1.0, 0.0]])
    assert face_on.primitive.kind == "cylinder" and face_on.explains
    assert ends.primitive.kind == "capsule" and ends.explains and ends.peaks_median_m < 2e-4
    assert float(ends.primitive(_on(truth, 2000, seed=3)).detach().abs().median()) < 5e-4


def test_fragments_near_each_other_are_grouped_through_their_neighbours():
    """Surfaces 6 mm apart join (one group through the middle one), one 5 cm away does not."""
    points = _on(geo.Sphere(0.004), 50, seed=6)
    pieces = [Fragment((label,), torch.zeros(0, 3), points + torch.tensor([x, 0.0, 0.0], dtype=torch.float64))
              for label, x in enumerate([0.0, 0.014, 0.028, 0.078], start=1)]
    assert 0.006 < JOIN_REACH_M
    assert near_groups(pieces) == [[0, 1, 2]]
    assert near_groups(pieces, reach_m=0.005) == [] == near_groups([])


def test_a_torus_seen_as_two_arcs_is_read_as_one_torus():
    """A torus's peaks and its 1 mm swollen warm surface split into two arcs 8 mm apart (as the
    views break the demo's ring): the two fragments fitted as one give the torus, which stands for
    both, its radii within half a millimetre of the truth's (the swollen warm surface pulls it
    out by 0.3); the joined fragment carries the warm start's median over all its peaks' caps."""
    truth = _turned(geo.Torus(0.03, 0.01))
    frame = geo.rotation_from_vector(torch.tensor(TURN, dtype=torch.float64))
    views = torch.tensor(VIEWS, dtype=torch.float64) @ frame.T
    peaks, towards = _seen_from(truth, views / views.norm(dim=1, keepdim=True), count=400)
    swollen = lambda p: truth(p) - 0.001  # noqa: E731
    warm = _on(swollen, 1500, seed=2)
    side = lambda p: ((p - torch.tensor(CENTRE, dtype=torch.float64)) @ frame)[:, 0]  # noqa: E731  (local x)
    caps = glint_caps(peaks, towards, torch.full((len(peaks),), 0.3, dtype=torch.float64), math.radians(0.25))
    pieces = [Fragment((label,), peaks[keep(side(peaks))], warm[keep(side(warm))], caps[keep(side(peaks))])
              for label, keep in ((1, lambda x: x < -0.004), (2, lambda x: x > 0.004))]
    free = free_space(peaks, towards, [-0.2] * 3, [0.2] * 3)
    fits = explain_together([explain_fragment(piece, free) for piece in pieces], swollen, free)
    (fit,) = fits
    assert fit.fragment.labels == (1, 2) and fit.primitive.kind == "torus" and fit.explains
    torch.testing.assert_close(fit.primitive.log_sizes.detach().exp(), torch.tensor([0.03, 0.01], dtype=torch.float64),
                               rtol=0, atol=5e-4)
    both = joined(pieces, swollen)
    assert len(both.peaks) == sum(len(piece.peaks) for piece in pieces) == len(both.caps)
    assert both.warm_median_m == pytest.approx(float(both.gaps(swollen).abs().median()))
    assert both.warm_median_m > 1e-3


def test_fragments_are_linked_where_no_line_of_sight_passes_between_them():
    """Three patches of peaks on the x axis, 5 and 10 cm apart: linked nearest first while no free
    sample lies near the segment between their centroids; a line of sight crossing a segment cuts
    that link, and a patch of fewer than LINK_MIN_PEAKS peaks is linked to nothing."""
    patch = _on(geo.Sphere(0.005), 4 * LINK_MIN_PEAKS, seed=7)[:LINK_MIN_PEAKS]
    pieces = [Fragment((label,), patch + torch.tensor([x, 0.0, 0.0], dtype=torch.float64), patch)
              for label, x in enumerate([0.0, 0.05, 0.15], start=1)]
    aside = torch.tensor([[0.0, 0.05, 0.0]], dtype=torch.float64)  # free space well off the axis
    assert linked_pairs(pieces, aside) == [(0, 1), (1, 2), (0, 2)]
    middle = (pieces[1].peaks.mean(0) + pieces[2].peaks.mean(0)) / 2  # a line of sight between the second and third
    crossing = middle[None] + torch.tensor([0.0, 0.5 * LINK_CLEAR_M, 0.0], dtype=torch.float64)
    assert linked_pairs(pieces, torch.cat([aside, crossing])) == [(0, 1)]
    few = [pieces[0], Fragment((2,), pieces[1].peaks[1:], patch)] + pieces[2:]
    assert linked_pairs(few, aside) == [(0, 2)]
    assert linked_pairs(pieces, torch.empty(0, 3, dtype=torch.float64)) == []


@pytest.mark.parametrize("first_median, capsule_median, chosen", [
    (0.5e-3, 0.4e-3, "cylinder"),  # both explain: the capsule not under FALLBACK_MARGIN of the cylinder
    (0.5e-3, 0.2e-3, "capsule"),
    (0.61e-3, 0.554e-3, "cylinder"),  # the demo's jar on AVX-512: the cylinder within FALLBACK_TIE of the capsule
    (0.643e-3, 0.514e-3, "capsule"),  # garage's concrete post: the cylinder misses, 1.25x the capsule's median
    (0.7e-3, 0.65e-3, "cylinder"),  # neither explains: the first stays (and replaces nothing)
])
def test_a_capsule_replaces_the_other_kinds_where_they_miss_or_it_is_clearly_nearer(monkeypatch, first_median,
                                                                                    capsule_median, chosen):
    """The fallback's rule (``explain_fragment``): a capsule stands where it explains the fragment
    and the other kinds' fit does not, or where it lies under ``FALLBACK_MARGIN`` of their median
    gap; their fit otherwise, and a cylinder within ``FALLBACK_TIE`` of an explaining capsule's
    median explains the fragment (the data do not choose between the two)."""
    fragment = Fragment((1,), torch.zeros(2 * MIN_PEAKS, 3, dtype=torch.float64), torch.zeros(0, 3))
    medians = {"cylinder": first_median, "capsule": capsule_median}

    def fitted(piece, free, *, kinds):
        kind = "capsule" if list(kinds) == ["capsule"] else "cylinder"
        return FragmentFit(piece, FramedPrimitive(kind, [0.0] * 3, [0.0, 0.0, 1e-6], [0.01, 0.02]), 0.0,
                           medians[kind], 0.9, 0.0)

    monkeypatch.setattr(object_primitives, "fit_fragment", fitted)
    fit = explain_fragment(fragment, torch.zeros(0, 3))
    assert fit.primitive.kind == chosen
    assert fit.explains == (min(first_median, capsule_median) < ACCEPT_MEDIAN_M)


def test_a_capsule_seen_only_at_its_two_ends_is_read_as_one_capsule():
    """Views 60 degrees or less from its axis see a capsule's two round ends and not its body
    (counter's wood capsule): two fragments 6 cm apart, each its own fit; linked, one capsule stands
    for both, its radius and half length within 0.75 mm of the truth's (the 1 mm swollen warm
    surface pulls them out by 0.6)."""
    truth = _turned(geo.Capsule([0, 0, -0.03], [0, 0, 0.03], 0.012))
    frame = geo.rotation_from_vector(torch.tensor(TURN, dtype=torch.float64))
    sin, cos = math.sin(math.radians(60)), math.cos(math.radians(60))
    views = torch.tensor([[0, 0, 1], [sin, 0, cos], [0, sin, cos], [0, 0, -1], [-sin, 0, -cos], [0, -sin, -cos]],
                         dtype=torch.float64) @ frame.T
    peaks, towards = _seen_from(truth, views, count=300)
    warm = _on(lambda p: truth(p) - 0.001, 1500, seed=2)
    height = lambda p: ((p - torch.tensor(CENTRE, dtype=torch.float64)) @ frame)[:, 2]  # noqa: E731  (local z)
    pieces = [Fragment((label,), peaks[end(height(peaks))], warm[end(height(warm))])
              for label, end in ((1, lambda z: z > 0.025), (2, lambda z: z < -0.025))]
    free = free_space(peaks, towards, [-0.2] * 3, [0.2] * 3)
    assert linked_pairs(pieces, free) == [(0, 1)] and min(len(piece.peaks) for piece in pieces) >= LINK_MIN_PEAKS
    (fit,) = explain_linked([explain_fragment(piece, free) for piece in pieces], truth, free)
    assert fit.fragment.labels == (1, 2) and fit.primitive.kind == "capsule" and fit.explains
    torch.testing.assert_close(fit.primitive.log_sizes.detach().exp(), torch.tensor([0.012, 0.03], dtype=torch.float64),
                               rtol=0, atol=7.5e-4)


def test_a_box_seen_at_its_rims_is_bridged_across_its_unseen_middle(monkeypatch):
    """Pantry's concrete block: a box seen only near its two ends, each end two pieces (near each
    other: one unit), its peaks rim returns up to 2.4 mm off the surface. Linked across the middle, one
    box explains all four pieces, held to the bridge's median (the default's 0.6 mm reads no box
    through such peaks), its sizes within a millimetre of the truth's; with fewer than
    BRIDGE_MIN_PEAKS a side, held to the default, it replaces nothing."""
    half = torch.tensor([0.015, 0.03, 0.012], dtype=torch.float64)
    truth = _turned(geo.Box(half))
    frame = geo.rotation_from_vector(torch.tensor(TURN, dtype=torch.float64))
    local = lambda p: ((p - torch.tensor(CENTRE, dtype=torch.float64)) @ frame)[:, :2].T  # noqa: E731  (x, y)
    surface = _on(truth, 20000, seed=3)
    towards = geo.normals(truth, surface).detach()  # each seen along its normal
    on_face = truth(surface - 1e-3 * towards) < -0.9e-3  # not on a rim, where the projection gathers many
    surface, towards = surface[on_face], towards[on_face]
    off = (torch.rand(len(surface), generator=torch.Generator().manual_seed(4), dtype=torch.float64) - 0.5) * 4.8e-3
    peaks = surface + off[:, None] * towards
    warm = _on(lambda p: truth(p) - 0.001, 6000, seed=5)
    quarters = [lambda x, y, sx=sx, sy=sy: (sx * x > 0.004) & (sy * y > 0.02) for sx in (1, -1) for sy in (1, -1)]
    mine = [torch.nonzero(quarter(*local(surface))).squeeze(1)[:BRIDGE_MIN_PEAKS // 2 + 5] for quarter in quarters]
    pieces = [Fragment((label,), peaks[seen], warm[quarter(*local(warm))][::4])
              for label, (seen, quarter) in enumerate(zip(mine, quarters), start=1)]
    assert near_groups(pieces) == [[0, 2], [1, 3]]  # each end's two pieces
    seen = torch.cat(mine)
    free = free_space(peaks[seen], towards[seen], [-0.2] * 3, [0.2] * 3)[::4]
    unfitted = [FragmentFit(piece, FramedPrimitive("sphere", CENTRE, [1e-6] * 3, [0.01]), math.inf, math.inf, 0.0, 0.0)
                for piece in pieces]
    (fit,) = explain_linked(unfitted, truth, free)
    assert sorted(fit.fragment.labels) == [1, 2, 3, 4] and fit.primitive.kind == "box" and fit.explains
    assert ACCEPT_MEDIAN_M < fit.peaks_median_m < BRIDGE_MEDIAN_M
    torch.testing.assert_close(fit.primitive.log_sizes.detach().exp().sort().values, half.sort().values,
                               rtol=0, atol=1e-3)
    held = replace(fit, accept_median_m=ACCEPT_MEDIAN_M, accept_within=ACCEPT_WITHIN)  # the same box, by default
    monkeypatch.setattr(object_primitives, "explain_fragment", lambda fragment, free: held)
    monkeypatch.setattr(object_primitives, "BRIDGE_MIN_PEAKS", 2 * len(mine[0]) + 1)
    assert [fit.fragment.labels for fit in explain_linked(unfitted, truth, free)] == [(1,), (2,), (3,), (4,)]


def test_a_bridges_peaks_are_the_ones_the_fit_does_not_hold():
    """Of three fits, one explains its peaks by the default's acceptance, one only as a bridge (its
    median over ACCEPT_MEDIAN_M, its acceptance loosened) and one not at all: only the bridge's peaks
    are marked, found among all the peaks by their coordinates."""
    points = torch.rand(30, 3, generator=torch.Generator().manual_seed(0)) * 0.1  # float32, as the fit's peaks
    sphere = FramedPrimitive("sphere", CENTRE, [1e-6] * 3, [0.01])

    def fit(rows: slice, median_m: float, **acceptance) -> FragmentFit:
        piece = Fragment((rows.start,), points[rows].double(), points[rows].double())
        return FragmentFit(piece, sphere, 0.0, median_m, 0.5 if acceptance else 0.9, 0.0, **acceptance)

    near, bridge, missed = fit(slice(0, 10), 0.3e-3), fit(slice(10, 20), 1.2e-3, accept_median_m=BRIDGE_MEDIAN_M,
                                                            accept_within=0.4), fit(slice(20, 30), 1.2e-3)
    assert near.explains and not near.bridged and bridge.explains and bridge.bridged and not missed.explains
    assert bridged_peaks([near, bridge, missed], points).tolist() == [False] * 10 + [True] * 10 + [False] * 10
    assert not bridged_peaks([near, missed], points).any() and len(bridged_peaks([bridge], points[:0])) == 0


def _brick_and_ball():
    """Larder's glass ball and concrete brick, 8.5 mm apart (a sphere and a box, f [m] of float64
    points [m]), and their warm start (float32 points): both swollen by 1 mm and joined through a
    neck 3 mm deep, the brick 5.5 mm deep (larder's seed 1: 6.6 mm over 4.0)."""
    axis = [0.0015] * 2  # y, z on the labelling grid's centres, which sample the neck's depth along it
    ball, block = geo.Sphere(0.014, [-0.0165, *axis]), geo.Box([0.0045, 0.025, 0.014], [0.0105, *axis])
    neck = geo.Capsule([-0.0165, *axis], [0.0105, *axis], 0.002)

    def warm(p: torch.Tensor) -> torch.Tensor:
        swollen = torch.stack([shape(p.double()) for shape in (ball, block, neck)]).min(0).values - 0.001
        return swollen.to(p.dtype)

    return ball, block, warm


def test_a_ball_and_a_box_the_warm_start_joined_are_split_and_read_apart():
    """Larder's concrete brick and glass ball, which the warm start holds as one piece (:func:`_brick_and_ball`,
    the brick only 2.5 mm deeper than the neck) that no one primitive explains. Split at the neck, each part
    holds its own object's peaks and is read as its own primitive, the ball on its peaks; the piece's label
    gives way to the parts' (their voxels the piece's). A fit that explains its piece, and a piece of one
    maximum, stay whole."""
    ball, block, warm = _brick_and_ball()
    truth = lambda p: torch.minimum(ball(p), block(p))  # noqa: E731
    views = torch.tensor(VIEWS, dtype=torch.float64)
    peaks, towards = _seen_from(truth, views / views.norm(dim=1, keepdim=True), count=400)
    on_ball = ball(peaks).abs() < 1e-6
    labels, grid, (piece,) = fragments(warm, [-0.06] * 3, [0.06] * 3, peaks)
    free = free_space(peaks, towards, [-0.06] * 3, [0.06] * 3, occluder=warm)
    whole = FragmentFit(piece, FramedPrimitive("box", [0.0] * 3, [0.0, 0.0, 1e-6], [0.03, 0.03, 0.03]), math.inf,
                        2e-3, 0.3, 0.0)
    assert MIN_PEAKS <= int(on_ball.sum()) <= len(peaks) - MIN_PEAKS and not whole.explains
    split_labels, fits = explain_split([whole], warm, labels, grid, free)
    assert sorted(fit.primitive.kind for fit in fits) == ["box", "sphere"] and all(fit.explains for fit in fits)
    sphere = next(fit for fit in fits if fit.primitive.kind == "sphere")
    torch.testing.assert_close(sphere.fragment.peaks, peaks[on_ball])
    assert sphere.peaks_median_m < 2e-4  # its radius between the truth's and the swollen warm surface's:
    assert sphere.primitive.log_sizes.exp().item() == pytest.approx(0.0145, abs=5e-4)
    assert sorted(label for fit in fits for label in fit.fragment.labels) == [2, 3]  # after the piece's label, 1
    assert ((split_labels > 1) == (labels == 1)).all()
    assert explain_split([replace(whole, peaks_median_m=0.0, peaks_within=1.0)], warm, labels, grid, free)[1][0] \
        .fragment is piece
    alone = lambda p: (ball(p.double()) - 0.001).to(p.dtype)  # noqa: E731
    ball_labels, ball_grid, (ball_piece,) = fragments(alone, [-0.06] * 3, [0.06] * 3, peaks[on_ball])
    same, parts = split(ball_piece, alone, ball_labels, ball_grid)
    assert same is ball_labels and parts == []
    assert SPLIT_DEPTH_M < 0.0025  # the brick's depth over the neck's


def test_a_cut_stands_only_where_a_part_is_near_its_peaks(monkeypatch):
    """The brick and ball's piece (:func:`_brick_and_ball`) cut at its neck stays whole where each part's
    primitive is only nearer its peaks than the ragged warm surface (counter's concrete box, a thin piece cut
    at a dent: a box 1.0 mm off its part's peaks, 0.50 of them within 1 mm), and is cut where one part's is
    near them (the acceptance's median and share)."""
    ball, block, warm = _brick_and_ball()
    peaks = torch.cat([_on(ball, 400, seed=3)[:60], _on(block, 1000, seed=4)[:60]])
    labels, grid, (piece,) = fragments(warm, [-0.06] * 3, [0.06] * 3, peaks)
    primitive = FramedPrimitive("sphere", [0.0] * 3, [0.0, 0.0, 1e-6], [0.01])
    whole = FragmentFit(piece, primitive, math.inf, 2e-3, 0.3, 0.0)
    free = torch.zeros(0, 3, dtype=torch.float64)

    def fitted(median_m: float, within: float):
        def fit(part: Fragment, _free) -> FragmentFit:
            return FragmentFit(replace(part, warm_median_m=1.5e-3), primitive, 0.0, median_m, within, 0.0)
        return fit

    nearer = fitted(ACCEPT_BETTER_M - 1e-5, 0.5)
    assert nearer(piece, free).explains and not nearer(piece, free).near
    monkeypatch.setattr(object_primitives, "explain_fragment", nearer)
    same, (kept,) = explain_split([whole], warm, labels, grid, free)
    assert same is labels and kept is whole
    monkeypatch.setattr(object_primitives, "explain_fragment", fitted(ACCEPT_MEDIAN_M / 2, ACCEPT_WITHIN))
    cut, parts = explain_split([whole], warm, labels, grid, free)
    assert len(parts) == 2 and all(part.near for part in parts) and (cut != labels).any()


def test_a_near_group_no_primitive_explains_is_fitted_again_less_its_members_read_near(monkeypatch):
    """Larder's brick, two pieces of the warm start beside its glass ball's (:func:`_brick_and_ball`),
    all three one near group. No primitive explains the three, nor the brick's two by the default's
    acceptance (its true box stands 1.1 mm from its rim returns); without the ball, read near, the
    brick's two are fitted again and, with ``BRIDGE_MIN_PEAKS`` peaks each, held to a bridge's
    acceptance: one box stands for both, the ball's fit kept. With fewer peaks a side nothing is replaced."""
    ball, block, _ = _brick_and_ball()
    on_ball, on_block = _on(ball, 400, seed=3)[:60], _on(block, 2000, seed=4)
    halves = [on_block[on_block[:, 1] > 0][:60], on_block[on_block[:, 1] < 0][:60]]
    pieces = [Fragment((label,), points, points) for label, points in enumerate([on_ball, *halves], start=1)]
    assert near_groups(pieces) == [[0, 1, 2]]
    sphere = FramedPrimitive("sphere", [-0.0165, 0.0015, 0.0015], [1e-6] * 3, [0.014])
    box = FramedPrimitive("box", [0.0105, 0.0015, 0.0015], [1e-6] * 3, [0.0045, 0.025, 0.014])
    ball_fit = FragmentFit(pieces[0], sphere, 0.0, 2e-4, 0.9, 0.0)
    halves_fits = [FragmentFit(piece, box, 0.0, 1.2e-3, 0.45, 0.0) for piece in pieces[1:]]

    def fitted(fragment: Fragment, _free) -> FragmentFit:  # the box 1.1 mm off the brick's rim returns alone
        with_ball = bool((ball(fragment.peaks).abs() < 1e-6).any())
        return FragmentFit(fragment, box, 0.0, 2.1e-3 if with_ball else 1.1e-3, 0.27 if with_ball else 0.48, 0.0)

    monkeypatch.setattr(object_primitives, "explain_fragment", fitted)
    free = torch.zeros(0, 3, dtype=torch.float64)
    kept, brick = explain_together([ball_fit, *halves_fits], block, free)  # no caps: the sdf is not read
    assert kept is ball_fit and sorted(brick.fragment.labels) == [2, 3] and brick.explains and brick.bridged
    monkeypatch.setattr(object_primitives, "BRIDGE_MIN_PEAKS", len(halves[0]) + 1)
    assert explain_together([ball_fit, *halves_fits], block, free) == [ball_fit, *halves_fits]


def test_a_box_seen_on_its_two_ends_off_each_other_is_read_along_its_faces():
    """Seen only on its two end faces, each on a different half across it (the demo's wood block),
    a box's points spread along a diagonal: a box along their principal axes stops turned, and a
    cylinder wins; started along the faces' normal, a box explains them, its end faces within a
    degree and its length within 0.2 mm of the truth's."""
    truth = _turned(geo.Box([0.04, 0.025, 0.02]))
    frame = geo.rotation_from_vector(torch.tensor(TURN, dtype=torch.float64))
    peaks, towards = _seen_from(truth, torch.tensor([[1.0, 0, 0], [-1.0, 0, 0]], dtype=torch.float64) @ frame.T, 400)
    warm = _on(lambda p: truth(p) - 0.001, 4000, seed=2)

    def ends(points: torch.Tensor) -> torch.Tensor:
        x, y = ((points - torch.tensor(CENTRE, dtype=torch.float64)) @ frame)[:, :2].T
        return ((x > 0.035) & (y > 0)) | ((x < -0.035) & (y < 0))

    keep = ends(peaks)
    fit = explain_fragment(Fragment((1,), peaks[keep], warm[ends(warm)]),
                           free_space(peaks[keep], towards[keep], [-0.2] * 3, [0.2] * 3))
    assert fit.primitive.kind == "box" and fit.explains
    axes = fit.primitive.describe()["axes"]
    along = torch.tensor(axes, dtype=torch.float64) @ frame[:, 0]  # each axis's cosine to the truth's long one
    assert float(along.abs().max()) > math.cos(math.radians(1))
    assert abs(fit.primitive.log_sizes.detach().exp()[int(along.abs().argmax())] - 0.04) < 2e-4


def _fitted_alone(fragment: Fragment, free: torch.Tensor, steps: int) -> FramedPrimitive:
    """The slow reference: each candidate by its own Adam for a third of the steps, the two lowest
    on for the rest, one at a time."""
    points = torch.cat([fragment.surface, fragment.peaks])
    free = free[((free > points.min(0).values - FREE_REACH_M) & (free < points.max(0).values + FREE_REACH_M)).all(1)]
    evidence = _Evidence(torch.cat([points, free]), (len(fragment.surface), len(fragment.peaks), len(free)))
    runs = []
    for primitive in candidates(points.numpy()):
        optimizer = torch.optim.Adam([{"params": [primitive.centre], "lr": FIT_LR},
                                      {"params": [primitive.rotation], "lr": ROTATION_LR_SCALE * FIT_LR},
                                      {"params": [primitive.log_sizes], "lr": SIZE_LR_SCALE * FIT_LR}])
        schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps)
        runs.append([primitive, optimizer, schedule])
    for phase, part in enumerate((steps // 3, steps - steps // 3)):
        for run in runs:
            for _ in range(part):
                run[1].zero_grad()
                evidence.loss(run[0]).backward()
                run[1].step()
                run[2].step()
        with torch.no_grad():
            runs = sorted(runs, key=lambda run: float(evidence.loss(run[0])))[:SURVIVORS if phase == 0 else 1]
    return runs[0][0]


def test_the_candidates_fitted_together_end_where_each_fitted_alone_ends():
    truth = _turned(geo.Box([0.03, 0.02, 0.015]))
    views = torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], dtype=torch.float64)
    peaks, towards = _seen_from(truth, views, count=60)
    fragment = Fragment((1,), peaks, _on(lambda p: truth(p) - 0.002, 300, seed=5))
    free = free_space(peaks, towards, [-0.2] * 3, [0.2] * 3)
    together = fit_fragment(fragment, free, steps=30).primitive
    alone = _fitted_alone(fragment, free, 30)
    assert together.kind == alone.kind
    for name in ("centre", "rotation", "log_sizes"):
        torch.testing.assert_close(getattr(together, name), getattr(alone, name), rtol=1e-9, atol=1e-12)


def test_free_space_follows_each_line_of_sight_inside_the_box():
    points = torch.tensor([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]], dtype=torch.float64)
    towards = torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], dtype=torch.float64)
    samples = free_space(points, towards, [-0.1] * 3, [0.1] * 3)
    along_z = samples[samples[:, 0] == 0.0]
    assert along_z[:, 2].min() == pytest.approx(0.004) and along_z[:, 2].max() < 0.1
    assert (samples.abs() < 0.1).all() and len(samples) < 80  # the second line leaves the box at 5 cm


def test_a_line_of_sight_the_occluder_holds_is_not_free_space():
    """Of three lines, the one through a ball 6 cm up (19 mm deep) is dropped; one that grazes it
    (half a millimetre inside) and one beside it stay."""
    points = torch.tensor([[0.0, 0.0, 0.0], [0.0195, 0.0, 0.0], [0.05, 0.0, 0.0]], dtype=torch.float64)
    towards = torch.tensor([[0.0, 0.0, 1.0]] * 3, dtype=torch.float64)
    ball = geo.Sphere(0.02, [0.0, 0.0, 0.06])
    occluder = lambda p: ball(p.double()).float()  # noqa: E731  (float32 in and out, as the warm start)
    clear = free_space(points, towards, [-0.3] * 3, [0.3] * 3, occluder=occluder)
    every = free_space(points, towards, [-0.3] * 3, [0.3] * 3)
    assert len(every) == 3 * FREE_STEPS_M[2] and len(clear) == 2 * FREE_STEPS_M[2]
    assert set(clear[:, 0].tolist()) == {0.0195, 0.05}


def test_a_ball_with_peaks_behind_it_is_read_as_a_ball_on_the_lines_the_warm_start_leaves_clear():
    """Peaks 6 cm behind a ball, their lines running through it (returns placed beyond the surface
    a view saw), carve any primitive where the ball is: on every line the sphere is refused; on
    the lines the warm start (the ball 1 mm swollen) leaves clear it is read, on its peaks."""
    truth = _turned(geo.Sphere(0.025))
    views = torch.tensor(VIEWS, dtype=torch.float64)
    peaks, towards = _seen_from(truth, views / views.norm(dim=1, keepdim=True))
    behind, behind_towards = peaks[::5] - 0.06 * towards[::5], towards[::5]
    swollen = lambda p: truth(p) - 0.001  # noqa: E731
    fragment = Fragment((1,), peaks, _on(swollen, 400, seed=2))
    lines = torch.cat([peaks, behind]), torch.cat([towards, behind_towards])
    every = explain_fragment(fragment, free_space(*lines, [-0.2] * 3, [0.2] * 3))
    occluder = lambda p: swollen(p.double()).float()  # noqa: E731
    clear = explain_fragment(fragment, free_space(*lines, [-0.2] * 3, [0.2] * 3, occluder=occluder))
    assert not (every.primitive.kind == "sphere" and every.explains)
    assert clear.primitive.kind == "sphere" and clear.explains and clear.carved == 0
    assert clear.peaks_median_m < 2e-4


def test_the_target_replaces_the_explained_fragments_and_cuts_the_unplaced_ones():
    """Three fragments, a lumpy ball, a far box and a 7 mm blob 6 cm off both with 3 peaks: with
    the ball explained by its sphere and the blob unplaced (fewer than ``MIN_PEAKS`` peaks) the
    target is that sphere near the ball, the warm start near the box, and where the blob was the
    distance to what is left (within two voxels), not a few millimetres: no surface to keep."""
    ball = lambda p: (p - torch.tensor([0.05, 0.0, 0.0], dtype=p.dtype)).norm(dim=1) - 0.02 \
        + 0.002 * torch.sin(200 * p[:, 0])  # noqa: E731
    box = geo.Box([0.015, 0.015, 0.015], [-0.06, 0.0, 0.0])
    blob = geo.Sphere(0.007).translate([0.0, 0.06, 0.0])
    parts = (ball, box, blob)
    warm = lambda p: torch.stack([part(p.double()) for part in parts]).min(0).values.to(p.dtype)  # noqa: E731
    on_ball = _on(lambda p: ball(p).double(), 100, seed=3)[:MIN_PEAKS]  # the ball's peaks; none on the box
    on_blob = _on(lambda p: blob(p), 20, seed=5)[:3]
    labels, grid, pieces = fragments(warm, [-0.1] * 3, [0.1] * 3, torch.cat([on_ball, on_blob]))
    assert sorted(len(piece.peaks) for piece in pieces) == [0, 3, MIN_PEAKS]
    ball_piece, blob_piece, box_piece = (next(piece for piece in pieces if len(piece.peaks) == count)
                                         for count in (MIN_PEAKS, 3, 0))
    sphere = FramedPrimitive("sphere", [0.05, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.02])
    cube = FramedPrimitive("box", [-0.06, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.02, 0.02, 0.02])
    fits = [FragmentFit(ball_piece, sphere, 0.0, 0.0, 1.0, 0.0), FragmentFit(box_piece, cube, 1.0, 0.01, 0.0, 0.0)]
    assert [fit.explains for fit in fits] == [True, False]
    target = primitive_target(warm, labels, grid, fits, (blob_piece,))
    near_ball = _on(lambda p: sphere(p), 500, seed=4).float()
    near_box = box_piece.surface.float()
    assert target(near_ball).abs().max() < 1e-4  # the sphere's surface, not the lumps'
    torch.testing.assert_close(target(near_box), warm(near_box))
    at_blob = torch.cat([torch.tensor([[0.0, 0.06, 0.0]]), blob_piece.surface.float()])
    nearest_left = torch.minimum(sphere(at_blob.double()), box(at_blob.double())).float()  # 58 mm and more
    assert (target(at_blob) - nearest_left).abs().max() < 2 * FRAGMENT_VOXEL_M, (target(at_blob), nearest_left)
    alone = primitive_target(warm, labels, grid, [], (blob_piece,))  # only cut: the warm start elsewhere
    torch.testing.assert_close(alone(near_box), warm(near_box))
    assert alone(at_blob).min() > 0.05
    assert primitive_target(warm, labels, grid, fits[1:]) is warm


def test_a_few_bright_peaks_place_a_surface_and_a_few_faint_ones_are_cut(monkeypatch):
    """Two 7 mm blobs of 3 peaks each beside a ball of ``MIN_PEAKS``: the blob whose peaks stand at
    0.05 of the median amplitude (the demo's seed-1 floater: a double bounce) is cut from the
    target, the one at twice the median (larder's thin panel, seen in a strip of 8 peaks) stays
    the warm start; without amplitudes every piece of fewer than ``MIN_PEAKS`` peaks is cut."""
    ball = geo.Sphere(0.02).translate([0.05, 0.0, 0.0])
    faint, bright = geo.Sphere(0.007).translate([0.0, 0.06, 0.0]), geo.Sphere(0.007).translate([-0.05, -0.04, 0.0])
    parts = (ball, faint, bright)
    warm = lambda p: torch.stack([part(p.double()) for part in parts]).min(0).values.to(p.dtype)  # noqa: E731
    peaks = torch.cat([_on(ball, 100, seed=3)[:MIN_PEAKS], _on(faint, 20, seed=5)[:3], _on(bright, 20, seed=6)[:3]])
    amplitude = torch.cat([torch.linspace(0.5, 1.5, MIN_PEAKS), torch.full((3,), 0.05), torch.full((3,), 2.0)])
    along_x = lambda piece: float(piece.peaks[:, 0].mean())  # noqa: E731  (bright, faint, ball)
    by_centre = sorted(fragments(warm, [-0.1] * 3, [0.1] * 3, peaks, amplitude=amplitude)[2], key=along_x)
    torch.testing.assert_close(torch.cat([piece.brightness for piece in by_centre[::-1]]),
                               amplitude.double() / amplitude.double().median())
    assert [piece.placed for piece in by_centre] == [True, False, True]
    assert joined(by_centre[:2], warm).brightness.tolist() == [*by_centre[0].brightness, *by_centre[1].brightness]
    assert [piece.placed for piece in sorted(fragments(warm, [-0.1] * 3, [0.1] * 3, peaks)[2], key=along_x)] == [
        False, False, True]

    # primitive_start cuts the faint blob from the target it regresses onto and keeps the bright one
    targets = []
    monkeypatch.setattr(object_primitives, "explain_all", lambda pieces, sdf, labels, *a, **k: (labels, []))
    monkeypatch.setattr(object_primitives, "regress_to_primitives",
                        lambda field, frozen, target, *a, **k: targets.append(target))
    field = torch.nn.Module()
    field.sdf = warm
    object_primitives.primitive_start(field, peaks, -peaks / peaks.norm(dim=1, keepdim=True), [-0.1] * 3, [0.1] * 3,
                                      lr=1e-3, batch=64, eikonal_weight=0.1, near_share=0.5,
                                      generator=torch.Generator(), amplitude=amplitude)
    at = torch.tensor([[0.0, 0.06, 0.0], [-0.05, -0.04, 0.0]])
    assert targets[0](at)[0] > 0.02 and targets[0](at)[1] == warm(at)[1]


def test_a_sliver_is_a_fragment_when_it_holds_enough_peaks():
    """A warm start's piece smaller than ``MIN_FRAGMENT_M3`` is a floater, left as it is, unless
    the views placed ``MIN_PEAKS`` peaks on it: the demo's wood block, its far face a sliver of
    the warm start, was otherwise fitted from its near face alone."""
    ball = geo.Sphere(0.02).translate([0.04, 0.0, 0.0])
    sliver = geo.Box([0.008, 0.008, 0.002], [-0.04, 0.0, 0.0])
    warm = lambda p: torch.minimum(ball(p.double()), sliver(p.double())).to(p.dtype)  # noqa: E731
    on_sliver = _on(sliver, 400, seed=1)
    labels, grid, pieces = fragments(warm, [-0.08] * 3, [0.08] * 3, on_sliver[:MIN_PEAKS])
    volumes = sorted(int((labels == label).sum()) * FRAGMENT_VOXEL_M ** 3 for label in range(1, labels.max() + 1))
    assert len(volumes) == 2 and volumes[0] < MIN_FRAGMENT_M3 < volumes[1]  # the sliver is below the volume
    assert sorted(len(piece.peaks) for piece in pieces) == [0, MIN_PEAKS]
    assert [len(piece.peaks) for piece in fragments(warm, [-0.08] * 3, [0.08] * 3, on_sliver[:MIN_PEAKS - 1])[2]] == [0]


def test_a_primitive_nearer_the_glints_than_the_warm_start_replaces_it():
    """Read as glints, each fragment carries the warm start's median |least f| over its peaks'
    caps; a primitive whose own median is below it and below ``ACCEPT_BETTER_M`` replaces the
    fragment though fewer than ``ACCEPT_WITHIN`` of its peaks lie within 1 mm, unless it carves;
    none replaces a fragment of fewer than ``MIN_PEAKS`` peaks, however near them it lies."""
    warm = lambda p: (p.norm(dim=1) - 0.0215).to(p.dtype)  # noqa: E731  (1.5 mm too large)
    directions = torch.nn.functional.normalize(torch.randn(60, 3, generator=torch.Generator().manual_seed(3),
                                                           dtype=torch.float64), dim=1)
    peaks = 0.02 * directions
    caps = glint_caps(peaks, directions, torch.full((60,), 0.3, dtype=torch.float64), math.radians(0.25))
    (piece,) = fragments(warm, [-0.05] * 3, [0.05] * 3, peaks, caps)[2]
    assert piece.warm_median_m == pytest.approx(1.5e-3, abs=2e-5)
    assert fragments(warm, [-0.05] * 3, [0.05] * 3, peaks)[2][0].warm_median_m == 0  # on the lines: not read
    ball = FramedPrimitive("sphere", [0.0, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.02])
    for median, within, carved, warm_median, explains in (
            (0.8e-3, 0.5, 0.0, 1.5e-3, True), (0.8e-3, 0.5, 0.0, 0.7e-3, False),
            (1.1e-3, 0.3, 0.0, 1.5e-3, False), (0.8e-3, 0.5, 0.05, 1.5e-3, False),
            (0.5e-3, 0.8, 0.0, 0.4e-3, True)):
        fragment = Fragment((1,), peaks, piece.surface, caps, warm_median)
        assert FragmentFit(fragment, ball, 0.0, median, within, carved).explains is explains
    assert ACCEPT_BETTER_M > ACCEPT_MEDIAN_M
    few = Fragment((1,), peaks[:MIN_PEAKS - 1], piece.surface, caps[:MIN_PEAKS - 1], warm_median)
    assert not FragmentFit(few, ball, 0.0, 0.0, 1.0, 0.0).explains  # fewer peaks than it has parameters
    assert MIN_PEAKS > 9  # a box's centre, rotation and three half extents


def test_the_pins_lie_on_the_primitive_where_it_is_the_target_surface():
    """A sphere half sunk in a box: the pins are the sphere's surface outside the box only, and
    their normals the sphere's, radial."""
    sphere = FramedPrimitive("sphere", [0.0, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.02])
    box = geo.Box([0.02, 0.04, 0.04], [-0.02, 0.0, 0.0])  # covers the ball's x < 0 half
    target = lambda p: torch.minimum(sphere(p), box(p.double()).to(p.dtype)).detach()  # noqa: E731
    near = (torch.rand(2000, 3, generator=torch.Generator().manual_seed(1)) - 0.5) * 0.05
    pins, normals = primitive_surface(target, [sphere], near)
    assert pins.dtype == normals.dtype == torch.float32 and len(pins) > 500 and normals.shape == pins.shape
    assert (normals - torch.nn.functional.normalize(pins, dim=1)).norm(dim=1).max() < 1e-5
    assert (pins.double().norm(dim=1) - 0.02).abs().max() < 1e-6  # on the sphere
    assert (pins[:, 0] > -1e-4).all()  # none where the box covers it
    assert (pins[:, 0] > 0.01).sum() > len(pins) / 4  # and the free half kept


def test_peaks_read_as_glints_give_a_ball_its_radius():
    """Three views 0.3 m from a 25 mm ball, each with peaks at its glint's range on lines up to 0.8
    degrees off the ball's centre (the array's main lobe): read on their lines they stand up to
    0.3 mm outside the ball and swell its sphere (by 0.07 mm, the true warm surface holding it);
    read on glint caps within 1 degree of their lines (Fragment.caps, recon.glints) they give the
    radius to 0.01 mm."""
    generator = torch.Generator().manual_seed(4)
    views = torch.nn.functional.normalize(torch.tensor([[1.0, 0.2, 0.1], [-0.2, 1.0, 0.3], [0.1, -0.3, 1.0]],
                                                       dtype=torch.float64), dim=1)
    centres = 0.3 * views.repeat_interleave(40, 0)
    axis = -views.repeat_interleave(40, 0)
    across = torch.nn.functional.normalize(torch.linalg.cross(axis, torch.randn(120, 3, generator=generator,
                                                                                dtype=torch.float64)), dim=1)
    off = torch.deg2rad(0.8 * torch.rand(120, 1, generator=generator, dtype=torch.float64).sqrt())
    line = torch.cos(off) * axis + torch.sin(off) * across
    peaks, towards = centres + (0.3 - 0.025) * line, -line
    ranges = torch.full((120,), 0.3 - 0.025, dtype=torch.float64)
    warm = _on(lambda p: p.norm(dim=1) - 0.025, 400, seed=2)
    free = free_space(peaks, towards, [-0.2] * 3, [0.2] * 3)
    radius = {}
    for caps in (None, glint_caps(peaks, towards, ranges, math.radians(1.0), rings=4)):
        fit = fit_fragment(Fragment((1,), peaks, warm, caps), free)
        assert fit.primitive.kind == "sphere" and fit.explains
        radius[caps is None] = float(fit.primitive.log_sizes.detach().exp()[0])
    assert abs(radius[False] - 0.025) < 1e-5 < 5e-5 < radius[True] - 0.025, radius
