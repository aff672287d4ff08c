"""The warm start's fragments replaced by the primitives that explain their range peaks.

The warm start is a regression onto a thresholded image: its seen faces lie within a
millimetre or two, but its rims are rounded and its faces lumpy, and those errors are shapes,
not offsets, which neither the loss's phase nor a glint's own phase can read
(docs/results/demo-quality.md, "Each glint's carrier phase, read line by line"). Most objects
people image are, or are made of, spheres, boxes, cylinders, capsules and tori, which have sharp
rims, flat faces and even curvatures. So each connected piece of the warm start's interior (a
*fragment*: an object, or the part of one the views saw) is fitted by each primitive in turn, in a
local frame (a centre, a rotation vector and log sizes, all differentiable), by Adam on three
terms:

- the range peaks in the fragment lie on the surface (a Huber loss of f there, 1 mm knee; read
  as glints, ``[init] peak_cone_deg``, of the least f over each one's cap, recon/glints.py);
- the warm start's own surface near the fragment lies on it too, weakly (``SURFACE_WEIGHT``):
  it bounds the extents the peaks leave open;
- every peak's line of sight, from 4 mm in front of the peak to 20 cm towards its view, is
  free space (``FREE_WEIGHT`` * mean max(-f - 0.5 mm, 0)): a view saw the peak through it. Not
  a line the warm start itself holds (more than ``CLEAR_DEPTH_M`` inside): its peak lies behind
  the surface the views saw or beyond another object, and says nothing of the space in front
  (pantry: 120 of 1248 peaks, more than half held from 4 mm in front of the peak; counted in, a
  sphere 0.12 mm from the true wood ball carves 2.1 % of the samples near it and is refused;
  docs/results/demo-quality.md, "The lines of sight the warm start holds").

The lowest loss wins (a capsule, ``FALLBACK_KINDS``, only where no other kind explains the fragment
or it explains it clearly better; a cylinder about as near as a capsule that explains the peaks
explains them too: ``FALLBACK_TIE``). It replaces its fragment where it *explains* the fragment's
peaks (their median |f| below ``ACCEPT_MEDIAN_M``, at least ``ACCEPT_WITHIN`` of them within 1 mm;
or, with the peaks read as glints, their median below ``ACCEPT_BETTER_M`` and below the warm
start's own: a better account of them than the surface it replaces), has more peaks than a
primitive has parameters (``MIN_PEAKS``) and hardly carves the lines of sight (fewer than
``ACCEPT_CARVED`` of the free-space samples near it more than 1 mm inside). A fragment no primitive
explains may be two objects the warm start joined through a neck: it is split where its interior
narrows (the watershed of its depth) and each part fitted alone, the cut kept where one part's
primitive stands near its peaks (the acceptance's median and share). Elsewhere (an object no primitive
is) the warm start stays. The views often see one object as several fragments (a torus's
arcs, a box's faces): fragments whose surfaces come within ``JOIN_REACH_M`` of each other are
fitted again as one, and a primitive that explains them all stands for their own fits; so are two
farther ones (or near groups no primitive explained) with nothing the views saw between them and
enough peaks each (``LINK_MIN_PEAKS``: the two ends of a capsule whose body no view sees). Such a
bridge with many peaks a side is held to a looser median (``BRIDGE_MEDIAN_M``): where the views see
a box only at its rims and edges, their returns stand a millimetre or more off any surface. So is a
near group no primitive explains fitted again less its members a primitive stands near (an object
beside it), where each member left has as many peaks. A
fragment of fewer than ``MIN_PEAKS`` peaks, and those faint, is no surface the views place: a glint's
sidelobe or a double bounce the detection kept (the demo's seed-1 floater); a few bright ones are a
surface seen at a few places (larder's thin panel, ``PLACED_AMPLITUDE``). The new target is the warm start with
the replaced fragments and those cut out, united with the primitives; where a fragment is cut, the
target is the distance to the interior left, so no trace of it stays a surface. The network is
regressed onto it with f = 0 pinned at points of those primitives' surfaces, sampled near the
target's zero set and the warm start's (the cut surfaces too), its rate decayed to zero so that it
ends where the target is, not where the last batches left it.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import torch
from scipy import ndimage
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from skimage.morphology import h_maxima
from skimage.segmentation import watershed

from .. import geometry as geo
from ..geometry import Grid, interpolated_sdf, project_to_zero_set
from ..progress import progress_bar
from .glints import cap_minimum
from .warm_start import fit_to_image

__all__ = ["PRIMITIVE_KINDS", "FALLBACK_KINDS", "FALLBACK_MARGIN", "FALLBACK_TIE", "MIN_PEAKS", "FramedPrimitive",
           "Fragment", "FragmentFit", "candidates", "fragments", "joined", "free_space", "fit_fragment", "split",
           "explain_fragment", "explain_split", "near_groups", "explain_together", "linked_pairs", "explain_linked",
           "explain_all", "bridged_peaks", "primitive_target", "primitive_surface", "regress_to_primitives",
           "primitive_start"]

PRIMITIVE_KINDS = ("sphere", "box", "cylinder", "capsule", "torus")
# a capsule's rounded ends differ from a cylinder's flat ones only where the views see the ends, so
# between the two the data seldom choose: the demo's glass jar, a cylinder, fits a capsule 0.56 mm off
# its peaks against the cylinder's 0.60, and its whole surface then stands 1.15 mm off against 0.53.
# So a capsule replaces the other kinds' fit only where that fit does not explain the fragment
# (tabletop's metal capsule: a cylinder 1.11 mm off its peaks, a capsule 0.76) or where the capsule
# stands clearly nearer the peaks, its median under this share of theirs (a capsule seen on its
# ends in the tests: 0.09 mm against a cylinder's 0.35; docs/results/demo-quality.md, sixtieth session)
FALLBACK_KINDS, FALLBACK_MARGIN = ("capsule",), 0.5
# and where a cylinder misses the acceptance but lies within this factor of an explaining capsule's
# median, the data do not choose between the two either: the cylinder stands, held to the capsule's
# account. The demo's jar, a cylinder 0.599-0.610 mm off its peaks against the 0.6 mm acceptance on two
# CPUs (1.07-1.09x its capsule's), was a cylinder on one and a capsule 9 mm too long at each end on the
# other; the true capsules whose other kinds miss stand 1.25x (garage's concrete post) and 1.37-1.47x
# (tabletop's metal capsule) nearer as capsules (docs/results/demo-quality.md, "A cylinder as near as a
# capsule"). The medians' ratio is a weak witness (the ends, where the two differ, would be a better one)
FALLBACK_TIE = 1.15
FRAGMENT_VOXEL_M = 0.003  # the grid the warm start's interior is labelled on [m]
# smaller pieces (floaters) are left as they are, unless they hold MIN_PEAKS peaks: the views placed a
# surface there. The demo's wood block is seen on its two end faces; at seed 0 on an AVX-512 CPU the warm
# start holds the far one as two slivers of 0.86 and 0.65 cm^3 with 22 and 12 peaks (2.84 cm^3, 29 peaks
# where ATen runs its AVX2 kernels), and without them a cylinder took the near face alone, 11 mm off
# the block (docs/results/demo-quality.md, "The same code on another CPU")
MIN_FRAGMENT_M3 = 1e-6
# fragments whose surfaces come this near are also fitted as one: the demo's torus, seen as three
# pieces (two tori and a cylinder, the last not explained), is one torus 0.28 mm off all 150 peaks;
# its whole surface then stands 0.42 mm from the truth against 1.28 (docs/results/demo-quality.md)
JOIN_REACH_M = 0.01
# farther fragments are fitted as one too where no clear line of sight passes within LINK_CLEAR_M of
# the segment between their peaks' centroids (its middle 80 %: the views saw nothing between them)
# and each has at least LINK_MIN_PEAKS peaks. Counter's wood capsule is seen as its two ends, 86 mm
# apart, which one capsule explains (0.47 mm median, its length within 1 mm of the truth); on the
# demo (seeds 0 and 1) one box explained four pairs of two objects that passed the segment's test,
# each pair with a side of 16 peaks or fewer (a box passes through any two small patches); at 20 a side
# none of those is tried, nor two of the notched block's own pairs (sides of 16), while the wood block's
# (59 and 29) and counter's (71 and 74; 94 and 125) are (docs/results/demo-quality.md, "Fragments
# linked across a gap")
LINK_CLEAR_M, LINK_MIN_PEAKS = 3e-3, 20
# a near group that no primitive explains is still one side of a link: pantry's concrete block is seen
# as four pieces, two near groups at its two ends 50 mm apart whose middle no view sees. Its pieces'
# peaks are rim and edge returns (the 12 cm array sees only a 13 mm strip of its long faces), and the
# true box stands 1.37 mm from them (median): no acceptance of 0.6 mm reads it. So a linked pair with
# at least BRIDGE_MIN_PEAKS a side is explained by a primitive within BRIDGE_MEDIAN_M of its peaks
# (median; BRIDGE_WITHIN of them within 1 mm) that carves no more than ACCEPT_CARVED. Read off every
# linked pair of the eight scenes' seed-0 warm starts: pantry's block and cut glass box, one box each,
# 1.17 and 1.26 mm (0.44-0.45 within; its fit 1.85 -> 0.85 mm observed, their peaks let go:
# bridged_peaks); workbench's metal cylinder as a box 1.55 (0.37), which taken made its fit worse
# (3.44 -> 3.60 mm); every pair of two objects with 50 peaks a side 2.16 mm or more, 0.33 or fewer
# within; one of 30 and 27 peaks, 1.26 (workshop's corner and bottle; docs/results/demo-quality.md,
# "Bridges of rim returns"). So is a near group less its members a primitive stands near: larder's
# brick, two pieces beside its glass ball, one box 1.04-1.10 mm off their 194 peaks, the true box 1.11
# (larder 37 / 21 / 37 -> 34 / 26 / 40 % over seeds 0-2; "A near group less its near members")
BRIDGE_MIN_PEAKS, BRIDGE_MEDIAN_M, BRIDGE_WITHIN = 50, 1.5e-3, 0.4
# a piece no primitive explains may be two objects the warm start joined through a neck: larder's concrete
# brick and glass ball, 9 mm apart, are one piece of 222 peaks, a box 1.66 mm off them. Such a piece is
# split where its interior narrows, the watershed of its depth (-f) from the depths' maxima that stand
# SPLIT_DEPTH_M above the saddle between them (h-maxima), and each part with peaks fitted alone; a part
# a primitive explains replaces that part, the rest stays the warm start. The cut stands only where one
# part's primitive is near its peaks (the acceptance's median and share, not merely nearer than its warm
# start): a primitive fitted to a part of one object is nearer than the ragged warm surface the cut leaves.
# Larder's seed-1 warm start holds the brick 6.6 mm deep over a 4.0 mm neck to the ball (2.6 mm): at 2 mm
# the ball's part is a sphere 0.21 mm off its 80 peaks (0.88 within 1 mm); counter's concrete box, a thin
# piece 3.4-4.4 mm deep, is cut at 2 mm into parts whose best, a box 1.0 mm off its peaks (0.50), is only
# nearer, and taken it moved counter's fit 1.16 -> 1.32 mm observed. Every cut at 3 mm on the nine scenes'
# seed-0 warm starts has a near part (docs/results/demo-quality.md, "A shallower neck")
SPLIT_DEPTH_M = 2e-3
OWNER_REACH_M = 0.012  # a peak or surface point belongs to a fragment within this [m]
HUBER_M = 1e-3  # the knee of the Huber loss on f at the points [m]
SURFACE_WEIGHT = 0.1
FREE_WEIGHT = 10.0
FREE_MARGIN_M = 5e-4  # f may go this far negative on a line of sight before it costs [m]
FREE_STEPS_M = (0.004, 0.2, 40)  # a line of sight's samples: from, to [m], count
CLEAR_DEPTH_M = 1e-3  # a line of sight the warm start holds deeper than this inside is not free space [m]
FIT_STEPS, FIT_LR = 300, 1e-3  # Adam's steps, and its rate for the centre [m per step, about]
ROTATION_LR_SCALE, SIZE_LR_SCALE = 3.0, 10.0  # the rotation's [rad] and the log sizes' rates, over FIT_LR
SURVIVORS = 2  # the candidates fitted to the end, the lowest after a third of the steps
# a box seen on two opposite faces starts along its faces' normal, not the points' spread: the demo's
# wood block, seen on its two end faces whose peaks lie off each other across it, has principal
# axes 8 degrees off its own, where a box stops 1.02 mm from the peaks and a cylinder (0.44) wins;
# along the faces, the box 0.31 mm (docs/results/demo-quality.md, "Boxes along their faces")
FACE_NEIGHBOURS = 16
FREE_REACH_M = 0.02  # a fragment's fit sees the free space within this of its points' box [m]
# a few lines of sight of peaks not exactly on the surface cross it: 0.1 % of the clear lines' samples
# near the demo's metal ball (0.6 % of every line's), whose sphere scores 0.18 mm against the truth
ACCEPT_MEDIAN_M, ACCEPT_WITHIN, ACCEPT_CARVED = 6e-4, 0.7, 0.02
# read as glints, a primitive nearer the peaks than the warm start is (median) also replaces it
# below this: tabletop's glass brick, a box 0.68 mm off its peaks (the warm start 1.32 mm), whose
# seen faces stand 0.33 mm from the truth against the warm start's 1.42 (docs/results/demo-quality.md)
ACCEPT_BETTER_M = 1e-3
# and only a fragment with at least this many peaks, more than a primitive has parameters (a box's
# nine): fewer, any primitive passes through them. The demo's warm start at seed 1 holds a floater
# 21 mm over the metal ball with 4 peaks, which a capsule passed within 0.01 mm of and replaced
# (docs/results/demo-quality.md, "Fragments of few peaks")
MIN_PEAKS = 10
# such a fragment is cut from the target as no surface the views place, unless its peaks are as bright as
# surfaces' are: their median amplitude at least this share of every peak's. The demo's seed-1 floater, 4
# peaks 30-33 mm above its metal ball (a double bounce), stands at 0.05-0.08 of the median; larder's thin
# panel is a strip of 30 peaks and one of 8 at 1.4-3.2 of it (0-3.6 mm off the panel), and the strip cut,
# the panel's whole surface stood 16.2 mm off the truth, kept 10.3 (the start 3.11 -> 2.31 mm observed).
# A quarter (-12 dB) lies between the two in log; the seed-0 warm starts of nine scenes hold no other such
# fragment with peaks (docs/results/demo-quality.md, "A few bright peaks are a surface")
PLACED_AMPLITUDE = 0.25
# the network's regression onto the target also pins f = 0 at points on the replaced fragments'
# primitives (L1, this weight): on the demo (seed 0) the regressed network's observed surface
# 1.68 -> 1.57 mm (its target's 1.61; weight 3: 1.55; docs/results/demo-quality.md)
PIN_WEIGHT, PIN_TOLERANCE_M = 1.0, 1e-4
# and turns grad f along the primitives' normals there (1 - cos, this weight; Hermite data): the
# network holds their curvature (demo, 400 steps, draws 0/1/2: 1.16/1.09/1.11 mm observed without,
# 1.01/0.99 at 0.3, the target's 0.99; 0.1: 1.03/1.00/1.02; 1.0: 1.08/1.05; the metal ball 0.30-0.35
# -> 0.15-0.20 mm, its target 0.18; a pin weight of 5 or 20 instead holds the ball but loses
# elsewhere, 1.21-1.69; docs/results/demo-quality.md, "Hermite pins")
PIN_NORMAL_WEIGHT = 0.3
# the regression's steps, its rate cosine-decayed from the warm start's: at a constant rate the
# network stops wherever the last batches leave it (demo, seed 0, 300 steps: 1.62 and 2.01 mm
# observed over two draws, the target 1.57); decayed, 1.55 and 1.53, and 1.50 in 100 steps. At
# 100 the replaced sphere's glints stay flat (its power 1.70x the truth's, every material read
# through a gain of 0.62); at 400, 1.24x and 0.85, the fits' surfaces where 100's end
# (docs/results/demo-quality.md, "The regression's length and the materials")
REGRESSION_STEPS = 400


class FramedPrimitive(torch.nn.Module):
    """A primitive of ``kind`` in its own frame: ``centre`` (3,) [m], ``rotation`` (3,) a rotation
    vector [rad] taking the frame's axes to the scene's, and ``sizes`` [m] (sphere: radius; box:
    three half extents; cylinder: radius and half height, along the frame's z; capsule: radius and
    the half length of its axis segment, along z; torus: major and minor radius, about z). Float64
    parameters; the shape is the geometry library's."""

    def __init__(self, kind: str, centre, rotation, sizes):
        super().__init__()
        if kind not in PRIMITIVE_KINDS:
            raise ValueError(f"kind must be one of {PRIMITIVE_KINDS}, got {kind!r}")
        self.kind = kind
        self.centre = torch.nn.Parameter(torch.as_tensor(centre, dtype=torch.float64).clone())
        self.rotation = torch.nn.Parameter(torch.as_tensor(rotation, dtype=torch.float64).clone())
        self.log_sizes = torch.nn.Parameter(torch.log(torch.as_tensor(sizes, dtype=torch.float64)).clone())

    def shape(self) -> geo.SDF:
        """The primitive about the origin, axis z, at the current sizes (differentiable in them)."""
        s = self.log_sizes.exp()
        if self.kind == "sphere":
            return geo.Sphere(s[0])
        if self.kind == "box":
            return geo.Box(s)
        if self.kind == "cylinder":
            return geo.CappedCylinder(s[0], 2 * s[1])
        if self.kind == "capsule":
            end = torch.stack([torch.zeros_like(s[1]), torch.zeros_like(s[1]), s[1]])
            return geo.Capsule(-end, end, s[0])
        return geo.Torus(s[0], torch.minimum(s[1], 0.95 * s[0]))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """f (N,) [m] at points (N, 3) [m], float64."""
        local = (points.to(torch.float64) - self.centre) @ geo.rotation_from_vector(self.rotation)
        return self.shape()(local)

    def state(self) -> dict:
        """The primitive as a checkpoint holds it (a string and tensors: ``weights_only`` loads it)."""
        return {"kind": self.kind, "centre": self.centre.detach().clone(), "rotation": self.rotation.detach().clone(),
                "sizes": self.log_sizes.detach().exp()}

    @classmethod
    def from_state(cls, state: dict) -> FramedPrimitive:
        """The primitive that :meth:`state` describes."""
        return cls(state["kind"], state["centre"], state["rotation"], state["sizes"])

    def describe(self) -> dict:
        """kind, centre [m], sizes [m] and the frame's axes (rows) in the scene, as plain lists."""
        axes = geo.rotation_from_vector(self.rotation.detach()).T
        return {"kind": self.kind, "centre_m": self.centre.detach().tolist(),
                "sizes_m": self.log_sizes.detach().exp().tolist(), "axes": axes.tolist()}


def _rotation_vector(frame: np.ndarray) -> np.ndarray:
    """The rotation vector of an orthonormal frame (columns), its last axis flipped if it is
    left-handed."""
    from scipy.spatial.transform import Rotation

    frame = np.array(frame, dtype=float)
    if np.linalg.det(frame) < 0:
        frame[:, 2] *= -1
    return Rotation.from_matrix(frame).as_rotvec()


def _principal_axes(points: np.ndarray) -> np.ndarray:
    """(3, 3) the principal axes (columns, largest variance first) of points (N, 3)."""
    spread = points - points.mean(0)
    return np.linalg.eigh(spread.T @ spread / len(points))[1][:, ::-1]


def _face_axes(points: np.ndarray) -> np.ndarray:
    """(3, 3) a box's axes (columns) read off points (N, 3) [m] on its faces: first the normal most
    of them share (the top eigenvector of the sum of n n^T over their normals, each the least
    principal axis of its ``FACE_NEIGHBOURS`` nearest points), then the points' principal axes
    across it."""
    _, near = cKDTree(points).query(points, min(FACE_NEIGHBOURS, len(points)))
    patches = points[near] - points[near].mean(1, keepdims=True)
    normals = np.linalg.eigh(np.einsum("nki,nkj->nij", patches, patches))[1][:, :, 0]
    first = np.linalg.eigh(normals.T @ normals)[1][:, -1]
    across = np.linalg.svd(np.eye(3) - np.outer(first, first))[0][:, :2]  # an orthonormal basis of the plane
    return np.column_stack([first, across @ _principal_axes(points @ across)])


def _extent(points: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The middle (3,) [m] of points' (N, 3) [m] 2-98 % range along ``axes`` (3, 3) (columns) and
    its half widths (3,) [m], at least 2 mm (a fragment seen on one side has its centroid there, not
    at its middle)."""
    low, high = np.percentile(points @ axes, [2, 98], axis=0)
    return axes @ ((low + high) / 2), np.maximum((high - low) / 2, 2e-3)


def candidates(points: np.ndarray, kinds=PRIMITIVE_KINDS) -> list[FramedPrimitive]:
    """Starting primitives of ``kinds`` for a fragment's points (N, 3) [m], over their
    :func:`_extent`: a sphere; a box along their principal axes and one along the faces they lie on
    (:func:`_face_axes`); and a cylinder, a capsule (its axis at least a voxel long) and a torus
    about each principal axis."""
    axes, faces = _principal_axes(points), _face_axes(points)
    (centre, half), (face_centre, face_half) = _extent(points, axes), _extent(points, faces)
    starts = [FramedPrimitive("sphere", centre, np.full(3, 1e-6), [half.max()]),
              FramedPrimitive("box", centre, _rotation_vector(axes), half),
              FramedPrimitive("box", face_centre, _rotation_vector(faces), face_half)]
    for a in range(3):
        across = [(a + 1) % 3, (a + 2) % 3]
        rotation = _rotation_vector(axes[:, across + [a]])
        radius = half[across].max()
        starts += [FramedPrimitive("cylinder", centre, rotation, [radius, half[a]]),
                   FramedPrimitive("capsule", centre, rotation, [radius, max(half[a] - radius, FRAGMENT_VOXEL_M)]),
                   FramedPrimitive("torus", centre, rotation, [0.7 * radius, 0.3 * radius])]
    return [start for start in starts if start.kind in kinds]


@dataclass(frozen=True)
class Fragment:
    """A connected piece of the warm start's interior (or several near ones, :func:`joined`): its
    ``labels`` on the labelled grid, its range ``peaks`` (P, 3) and its warm ``surface`` points
    (S, 3) [m], float64; with ``caps`` (P, K, 3) [m], each peak's glint cap
    (:func:`~rfsdf.recon.glints.glint_caps`): a peak lies on a surface where the least f over its
    cap is 0 (None: f at the peak itself), ``warm_median_m``, the warm start's own median |f|
    over them [m] (0: not measured), and ``brightness`` (P,), each peak's amplitude over the median
    of every peak's (None: not given)."""

    labels: tuple[int, ...]
    peaks: torch.Tensor
    surface: torch.Tensor
    caps: torch.Tensor | None = None
    warm_median_m: float = 0.0
    brightness: torch.Tensor | None = None

    @property
    def placed(self) -> bool:
        """Whether the views place a surface on it: ``MIN_PEAKS`` peaks, or fewer whose median
        brightness is at least ``PLACED_AMPLITUDE``."""
        if len(self.peaks) >= MIN_PEAKS:
            return True
        bright = self.brightness is not None and len(self.peaks) > 0
        return bright and float(self.brightness.median()) >= PLACED_AMPLITUDE

    def gaps(self, sdf) -> torch.Tensor:
        """(P,) the least ``sdf`` over each peak's cap [m] (:func:`~rfsdf.recon.glints.glint_gap`)."""
        return cap_minimum(sdf, self.peaks[:, None] if self.caps is None else self.caps)


@dataclass(frozen=True)
class FragmentFit:
    """A fragment's best primitive, its loss, the median |f| at its peaks [m], the share of them
    within 1 mm, and the share of the free-space samples it carves (more than 1 mm inside)."""

    fragment: Fragment
    primitive: FramedPrimitive
    loss: float
    peaks_median_m: float
    peaks_within: float
    carved: float
    accept_median_m: float = ACCEPT_MEDIAN_M  # the median the acceptance holds it to [m] (FALLBACK_TIE)
    accept_within: float = ACCEPT_WITHIN  # the share within 1 mm it holds it to (a bridge's: BRIDGE_WITHIN)

    @property
    def near(self) -> bool:
        """Whether its peaks stand within its acceptance: their median under ``accept_median_m`` and
        ``accept_within`` of them within 1 mm."""
        return self.peaks_median_m < self.accept_median_m and self.peaks_within >= self.accept_within

    @property
    def explains(self) -> bool:
        """Whether the primitive replaces its fragment (the module docstring's rule)."""
        nearer = self.peaks_median_m < min(self.fragment.warm_median_m, ACCEPT_BETTER_M)
        return (self.near or nearer) and self.carved < ACCEPT_CARVED and len(self.fragment.peaks) >= MIN_PEAKS

    @property
    def bridged(self) -> bool:
        """Whether it explains its peaks only under a bridge's looser acceptance (``BRIDGE_MEDIAN_M``):
        they are rim returns standing a millimetre or more off its surface."""
        held_to_default = replace(self, accept_median_m=ACCEPT_MEDIAN_M, accept_within=ACCEPT_WITHIN)
        return self.explains and not held_to_default.explains


def fragments(sdf, lower_m, upper_m, peaks: torch.Tensor, caps: torch.Tensor | None = None,
              amplitude: torch.Tensor | None = None) -> tuple[np.ndarray, Grid, list[Fragment]]:
    """The labelled interior of ``sdf`` (float32 points -> f [m]) on a ``FRAGMENT_VOXEL_M`` grid
    over the box, that grid, and its fragments, the pieces of at least ``MIN_FRAGMENT_M3`` or
    nearest to ``MIN_PEAKS`` of the ``peaks`` (P, 3) [m], each with its peaks (and their ``caps``
    (P, K, 3) with ``sdf``'s median |f| over them, and their ``amplitude`` (P,) over the median's,
    see :class:`Fragment`) and the zero-set points within ``OWNER_REACH_M`` of its voxels."""
    grid = Grid.from_voxel(lower_m, upper_m, FRAGMENT_VOXEL_M)
    points = grid.points()
    with torch.no_grad():
        values = torch.cat([sdf(chunk) for chunk in points.split(1 << 16)])
    labels, count = ndimage.label((values < 0).reshape(grid.shape).numpy())
    volumes = ndimage.sum(np.ones(grid.shape), labels, range(1, count + 1)) * float(np.prod(grid.voxel_m))
    peaks = peaks.double()
    held = np.bincount(_owners(points, labels, range(1, count + 1))(peaks).numpy(), minlength=count + 1)[1:]
    kept = [label for label, volume, n in zip(range(1, count + 1), volumes, held)
            if volume >= MIN_FRAGMENT_M3 or n >= MIN_PEAKS]
    owner = _owners(points, labels, kept)
    surface = project_to_zero_set(sdf, points[values.abs() < FRAGMENT_VOXEL_M]).double()
    surface_owner, peak_owner = owner(surface), owner(peaks)
    caps = None if caps is None else caps.double()
    brightness = None if amplitude is None else amplitude.double() / amplitude.double().median()
    return labels, grid, [_owned(sdf, label, peak_owner == label, peaks, caps, brightness,
                                 surface[surface_owner == label]) for label in kept]


def _owned(sdf, label: int, held: torch.Tensor, peaks: torch.Tensor, caps: torch.Tensor | None,
           brightness: torch.Tensor | None, surface: torch.Tensor) -> Fragment:
    """The fragment ``label`` of the ``peaks`` (P, 3) [m] selected by ``held`` (P,) bool, with their
    ``caps`` and ``brightness`` where given, and its ``surface`` points (S, 3) [m]."""
    def pick(values: torch.Tensor | None) -> torch.Tensor | None:
        return None if values is None else values[held]

    return Fragment((label,), peaks[held], surface, pick(caps), _warm_median(sdf, caps, held), pick(brightness))


def _owners(points: torch.Tensor, labels: np.ndarray, kept) -> Callable[[torch.Tensor], torch.Tensor]:
    """A map from points (N, 3) [m] to the label (N,) int of the nearest voxel of ``points`` (the
    grid's, (V, 3) [m]) whose ``labels`` (the grid's shape) is one of ``kept``, within
    ``OWNER_REACH_M``; 0 where there is none."""
    inside = np.isin(labels, list(kept)).reshape(-1)
    voxels = cKDTree(points[torch.from_numpy(inside)].numpy())
    owners = np.append(labels.reshape(-1)[inside], 0)  # no voxel in reach: index len(voxels), label 0

    def owner(x: torch.Tensor) -> torch.Tensor:
        return torch.from_numpy(owners[voxels.query(x.numpy(), distance_upper_bound=OWNER_REACH_M)[1]])

    return owner


def _warm_median(sdf, caps: torch.Tensor | None, mine: torch.Tensor) -> float:
    """``sdf``'s median |least f| [m] over the ``caps`` (P, K, 3) [m] selected by ``mine`` (P,)
    bool; 0 without caps or peaks (:class:`Fragment`'s ``warm_median_m``)."""
    if caps is None or not mine.any():
        return 0.0
    with torch.no_grad():
        return float(cap_minimum(lambda x: sdf(x.float()).double(), caps[mine]).abs().median())


def joined(pieces: list[Fragment], sdf) -> Fragment:
    """The ``pieces`` (of one ``sdf``, float32 points -> f [m]) as one fragment: their labels,
    peaks, caps, brightness and surfaces together, and ``sdf``'s median |least f| over all their caps."""
    caps = None if pieces[0].caps is None else torch.cat([piece.caps for piece in pieces])
    brightness = None if pieces[0].brightness is None else torch.cat([piece.brightness for piece in pieces])
    peaks = torch.cat([piece.peaks for piece in pieces])
    return Fragment(tuple(label for piece in pieces for label in piece.labels), peaks,
                    torch.cat([piece.surface for piece in pieces]), caps,
                    _warm_median(sdf, caps, torch.ones(len(peaks), dtype=torch.bool)), brightness)


def free_space(points: torch.Tensor, towards: torch.Tensor, lower_m, upper_m, occluder=None) -> torch.Tensor:
    """(M, 3) float64 samples [m] of each peak's line of sight (peaks (N, 3), unit directions
    towards their views (N, 3)), ``FREE_STEPS_M`` along it, inside the box; with an ``occluder``
    (float32 points -> f [m], the warm start), only the lines it leaves clear (nowhere more than
    ``CLEAR_DEPTH_M`` inside; the module docstring says why)."""
    steps = torch.linspace(*FREE_STEPS_M[:2], FREE_STEPS_M[2], dtype=torch.float64)
    lines = points.double()[:, None] + steps[None, :, None] * towards.double()[:, None]
    if occluder is not None:
        with torch.no_grad():
            depth = occluder(lines.reshape(-1, 3).float()).reshape(lines.shape[:2])
        lines = lines[(depth > -CLEAR_DEPTH_M).all(1)]
    samples = lines.reshape(-1, 3)
    lower, upper = torch.as_tensor(lower_m, dtype=torch.float64), torch.as_tensor(upper_m, dtype=torch.float64)
    return samples[((samples > lower) & (samples < upper)).all(1)]


def _huber(values: torch.Tensor) -> torch.Tensor:
    return torch.nn.functional.huber_loss(values, torch.zeros_like(values), delta=HUBER_M) / HUBER_M


@dataclass(frozen=True)
class _Evidence:
    """A fragment's points for the loss, in one tensor (N, 3) float64 [m] so that a primitive is
    evaluated once a step: its warm surface points, then its peaks' caps (``cap`` samples each),
    then the free-space samples near it; ``counts`` of each."""

    points: torch.Tensor
    counts: tuple[int, int, int]
    cap: int = 1

    def loss(self, primitive: FramedPrimitive) -> torch.Tensor:
        """The module docstring's three terms."""
        surface, caps, free = primitive(self.points).split(self.counts)
        loss = SURFACE_WEIGHT * _huber(surface)
        if len(caps):
            loss = loss + _huber(caps.reshape(-1, self.cap).min(1).values)
        if len(free):
            loss = loss + FREE_WEIGHT * torch.relu(-free - FREE_MARGIN_M).mean()
        return loss


def _descend(primitives: list[FramedPrimitive], optimizer, schedule, steps: int, evidence: _Evidence) -> list[float]:
    """``steps`` of Adam on the sum of the ``primitives``' losses (each has its own parameters,
    so each descends as it would alone; one backward pass a step); each one's loss after them."""
    for _ in range(steps):
        loss = sum(evidence.loss(primitive) for primitive in primitives)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()  # a primitive left out has no gradient: Adam leaves it and its moments alone
        schedule.step()
    with torch.no_grad():
        return [float(evidence.loss(primitive)) for primitive in primitives]


def fit_fragment(fragment: Fragment, free: torch.Tensor, *, kinds=PRIMITIVE_KINDS, steps: int = FIT_STEPS,
                 lr: float = FIT_LR) -> FragmentFit:
    """Each of :func:`candidates` of ``kinds`` fitted to ``fragment`` with the free-space samples
    ``free`` (M, 3) near it by Adam (the centre at ``lr``, the rotation and log sizes faster,
    cosine decay over ``steps``): all for a third of the steps, the ``SURVIVORS`` lowest for the
    rest; the lowest loss, scored."""
    points = torch.cat([fragment.surface, fragment.peaks])
    reach = ((free > points.min(0).values - FREE_REACH_M) & (free < points.max(0).values + FREE_REACH_M)).all(1)
    free = free[reach]  # the lines of sight a primitive near these points could cross
    caps = fragment.peaks[:, None] if fragment.caps is None else fragment.caps
    evidence = _Evidence(torch.cat([fragment.surface, caps.reshape(-1, 3), free]),
                         (len(fragment.surface), caps.shape[0] * caps.shape[1], len(free)), caps.shape[1])
    starts = candidates(points.numpy(), kinds)
    optimizer = torch.optim.Adam([group for primitive in starts for group in (
        {"params": [primitive.centre], "lr": lr}, {"params": [primitive.rotation], "lr": ROTATION_LR_SCALE * lr},
        {"params": [primitive.log_sizes], "lr": SIZE_LR_SCALE * lr})])
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps)
    losses = _descend(starts, optimizer, schedule, steps // 3, evidence)
    survivors = [starts[i] for i in np.argsort(losses, kind="stable")[:SURVIVORS]]
    losses = _descend(survivors, optimizer, schedule, steps - steps // 3, evidence)
    loss, primitive = min(zip(losses, survivors), key=lambda run: run[0])
    with torch.no_grad():
        at_peaks = fragment.gaps(primitive).abs() if len(fragment.peaks) else torch.full((1,), torch.inf)
        carved = float((primitive(free) < -1e-3).double().mean()) if len(free) else 0.0
    return FragmentFit(fragment, primitive, loss, float(at_peaks.median()), float((at_peaks < 1e-3).double().mean()),
                       carved)


def split(piece: Fragment, sdf, labels: np.ndarray, grid: Grid) -> tuple[np.ndarray, list[Fragment]]:
    """A one-label ``piece`` of ``sdf``'s interior (float32 points -> f [m]) labelled on ``grid``
    cut into the watershed basins of its depth -f from maxima ``SPLIT_DEPTH_M`` above their saddles
    (the module docstring's split): ``labels`` with each basin given a new label after the largest,
    and one fragment a basin (its peaks, caps, brightness and surface points those nearest its voxels; see
    :func:`fragments`); ``labels`` and no parts where the piece has one maximum."""
    (label,) = piece.labels
    inside = labels == label
    where = np.argwhere(inside)
    box = tuple(slice(a, b + 1) for a, b in zip(where.min(0), where.max(0)))
    mine = inside[box]
    centres = grid.points()
    with torch.no_grad():
        depth = np.zeros(mine.shape)
        depth[mine] = -sdf(centres.reshape(*grid.shape, 3)[box][mine]).double().numpy()
    markers, count = ndimage.label(h_maxima(depth, SPLIT_DEPTH_M) & mine)
    if count < 2:
        return labels, []
    basins = watershed(-depth, markers, mask=mine)
    labels = labels.copy()
    labels[box][mine] = basins[mine] + labels.max()
    names = np.unique(labels[box][mine])
    owner = _owners(centres, labels, names)
    peak_owner, surface_owner = owner(piece.peaks), owner(piece.surface)
    return labels, [_owned(sdf, int(name), peak_owner == name, piece.peaks, piece.caps, piece.brightness,
                           piece.surface[surface_owner == name]) for name in names]


def explain_fragment(fragment: Fragment, free: torch.Tensor) -> FragmentFit:
    """:func:`fit_fragment` over the kinds but ``FALLBACK_KINDS`` and over those apart: the
    fallback's fit where it explains the fragment and the first does not, or where its median
    gap is under ``FALLBACK_MARGIN`` of the first's; the first otherwise, a cylinder held to
    ``FALLBACK_TIE`` times an explaining fallback's median."""
    fit = fit_fragment(fragment, free, kinds=[k for k in PRIMITIVE_KINDS if k not in FALLBACK_KINDS])
    fallback = fit_fragment(fragment, free, kinds=FALLBACK_KINDS)
    if not fallback.explains:
        return fit
    if fit.primitive.kind == "cylinder":
        fit = replace(fit, accept_median_m=max(ACCEPT_MEDIAN_M, FALLBACK_TIE * fallback.peaks_median_m))
    clearly = fallback.peaks_median_m < FALLBACK_MARGIN * fit.peaks_median_m
    return fallback if clearly or not fit.explains else fit


def near_groups(pieces: list[Fragment], reach_m: float = JOIN_REACH_M) -> list[list[int]]:
    """The indices of ``pieces`` in groups of two or more whose warm surfaces come within
    ``reach_m`` of each other, directly or through others of the group."""
    if not pieces:
        return []
    near = np.zeros((len(pieces), len(pieces)), bool)
    for i, j in zip(*np.triu_indices(len(pieces), 1)):
        if len(pieces[i].surface) and len(pieces[j].surface):
            near[i, j] = torch.cdist(pieces[i].surface, pieces[j].surface).min() < reach_m
    _, group = connected_components(near, directed=False)
    members = [np.flatnonzero(group == g).tolist() for g in range(group.max() + 1)]
    return [m for m in members if len(m) > 1]


def explain_together(fits: list[FragmentFit], sdf, free: torch.Tensor) -> list[FragmentFit]:
    """``fits`` with each :func:`near_groups` of their fragments fitted as one (:func:`joined`
    over ``sdf``, :func:`explain_fragment` with the free-space samples ``free``): where one
    primitive explains the group, its fit stands for the members'. Where none does, the group less
    its members already :attr:`~FragmentFit.near` their peaks (objects of their own beside it) is
    fitted again, held to a bridge's acceptance where each member left has ``BRIDGE_MIN_PEAKS`` peaks."""
    def as_one(members: list[int]) -> FragmentFit:
        return explain_fragment(joined([fits[i].fragment for i in members], sdf), free)

    taken = []
    for group in near_groups([fit.fragment for fit in fits]):
        fit = as_one(group)
        rest = [i for i in group if not (fits[i].explains and fits[i].near)]
        if not fit.explains and 2 <= len(rest) < len(group):
            group, fit = rest, as_one(rest)
            if min(len(fits[i].fragment.peaks) for i in group) >= BRIDGE_MIN_PEAKS:
                fit = _as_bridge(fit)
        if fit.explains:
            taken.append((fit, group))
    replaced = {i for _, group in taken for i in group}
    return [fit for i, fit in enumerate(fits) if i not in replaced] + [fit for fit, _ in taken]


def linked_pairs(pieces: list[Fragment], free: torch.Tensor) -> list[tuple[int, int]]:
    """The index pairs of ``pieces`` of at least ``LINK_MIN_PEAKS`` peaks each with no free-space
    sample of ``free`` (M, 3) [m] within ``LINK_CLEAR_M`` of the middle 80 % of the segment between
    their peaks' centroids, the nearest pairs (their peaks' least distance) first."""
    if not len(free):
        return []
    clear = cKDTree(free.numpy())
    along = np.linspace(0.1, 0.9, 50)[:, None]
    pairs = []
    for i, j in zip(*np.triu_indices(len(pieces), 1)):
        a, b = pieces[i].peaks, pieces[j].peaks
        if min(len(a), len(b)) < LINK_MIN_PEAKS:
            continue
        start, end = a.mean(0).numpy(), b.mean(0).numpy()
        if np.isinf(clear.query(start + along * (end - start), distance_upper_bound=LINK_CLEAR_M)[0]).all():
            pairs.append((float(torch.cdist(a, b).min()), int(i), int(j)))
    return [(i, j) for _, i, j in sorted(pairs)]


def _as_bridge(fit: FragmentFit) -> FragmentFit:
    """``fit`` held to a bridge's acceptance (``BRIDGE_MEDIAN_M``, ``BRIDGE_WITHIN``)."""
    return replace(fit, accept_median_m=max(fit.accept_median_m, BRIDGE_MEDIAN_M), accept_within=BRIDGE_WITHIN)


def explain_linked(fits: list[FragmentFit], sdf, free: torch.Tensor) -> list[FragmentFit]:
    """``fits`` with each of :func:`linked_pairs` of their units (each :func:`near_groups` of their
    fragments joined, every other fragment alone; with ``free``), nearest first and each unit in one
    pair at most, fitted as one (:func:`joined` over ``sdf``, :func:`explain_fragment`, held to a
    bridge's acceptance where each side has ``BRIDGE_MIN_PEAKS`` peaks): where one primitive explains
    the pair, its fit stands for every fit of the two."""
    groups = near_groups([fit.fragment for fit in fits])
    grouped = {i for group in groups for i in group}
    units = [[i] for i in range(len(fits)) if i not in grouped] + groups
    sides = [joined([fits[i].fragment for i in unit], sdf) if len(unit) > 1 else fits[unit[0]].fragment
             for unit in units]
    used, together = set(), []
    for a, b in linked_pairs(sides, free):
        if a in used or b in used:
            continue
        fit = explain_fragment(joined([sides[a], sides[b]], sdf), free)
        if min(len(sides[a].peaks), len(sides[b].peaks)) >= BRIDGE_MIN_PEAKS:
            fit = _as_bridge(fit)
        if fit.explains:
            used |= {a, b}
            together.append(fit)
    replaced = {i for unit in used for i in units[unit]}
    return [fit for i, fit in enumerate(fits) if i not in replaced] + together


def explain_split(fits: list[FragmentFit], sdf, labels: np.ndarray, grid: Grid,
                  free: torch.Tensor) -> tuple[np.ndarray, list[FragmentFit]]:
    """``fits`` with each of one label whose primitive does not explain it :func:`split` (on
    ``labels``' ``grid``, of ``sdf``) and its parts with peaks fitted alone (:func:`explain_fragment`
    with ``free``), where a primitive explains one of them and stands :attr:`~FragmentFit.near` its
    peaks (the module docstring's split); and ``labels`` with those parts."""
    kept = []
    for fit in fits:
        parts = []
        if not fit.explains and len(fit.fragment.labels) == 1 and len(fit.fragment.peaks) >= 2 * MIN_PEAKS:
            cut, pieces = split(fit.fragment, sdf, labels, grid)
            parts = [explain_fragment(piece, free) for piece in pieces if len(piece.peaks)]
        if any(part.explains and part.near for part in parts):
            labels, kept = cut, kept + parts
        else:
            kept.append(fit)
    return labels, kept


def explain_all(pieces: list[Fragment], sdf, labels: np.ndarray, grid: Grid, free: torch.Tensor, *,
                progress: bool = False) -> tuple[np.ndarray, list[FragmentFit]]:
    """:func:`explain_fragment` of every one of ``pieces`` with peaks (one without has nothing to
    explain), :func:`explain_split` of those no primitive explains (on ``labels``' ``grid``), then
    :func:`explain_together` of the near ones and :func:`explain_linked` of the far ones (over ``sdf``,
    with ``free``): the labels, with any split, and the fits."""
    seen = [piece for piece in pieces if len(piece.peaks)]
    fits = [explain_fragment(piece, free) for piece in progress_bar(seen, desc="primitives", enabled=progress)]
    labels, fits = explain_split(fits, sdf, labels, grid, free)
    return labels, explain_linked(explain_together(fits, sdf, free), sdf, free)


def bridged_peaks(fits: list[FragmentFit], points: torch.Tensor) -> torch.Tensor:
    """(N,) bool: which of the range ``points`` (N, 3) [m] the ``fits``' fragments were cut from
    belong to a :attr:`~FragmentFit.bridged` fit. The fit does not hold those on its surface: held,
    pantry's boxes followed them (its block 1.19 -> 1.41 mm, its glass box 2.29 -> 2.66 over the 50
    steps; not held 1.20 and 1.96; docs/results/demo-quality.md, "Bridges of rim returns")."""
    rims = [fit.fragment.peaks for fit in fits if fit.bridged]
    if not rims or not len(points):
        return torch.zeros(len(points), dtype=torch.bool)
    return torch.cdist(points.double(), torch.cat(rims)).min(1).values < 1e-9


def primitive_target(sdf, labels: np.ndarray, grid: Grid, fits: list[FragmentFit], unplaced: tuple[Fragment, ...] = ()):
    """The new target, points (N, 3) -> f [m] (their dtype and device; computed on the CPU, as
    ``sdf`` is): ``sdf`` (the warm start, held constant) with the fragments whose primitive
    :attr:`~FragmentFit.explains` them and the ``unplaced`` ones cut out, united with those
    primitives; ``sdf`` itself where none is cut. Cut out means bounded below by the distance to
    the interior left on ``labels``' grid, less a voxel: a cut fragment far from the rest is as far
    from the new surface as it is from the rest (a voxel-deep margin left a plateau a few
    millimetres above zero there, which the network's regression kept a floater under)."""
    chosen = [fit for fit in fits if fit.explains]
    cut_labels = [label for fit in chosen for label in fit.fragment.labels] + [
        label for piece in unplaced for label in piece.labels]
    if not cut_labels:
        return sdf
    left = (labels > 0) & ~np.isin(labels, cut_labels)
    if left.any():  # signed, on the voxel centres: outside the interior left, inside it negative
        bound = ndimage.distance_transform_edt(~left) - ndimage.distance_transform_edt(left) - 1.0
    else:  # nothing left: the box's diagonal
        bound = np.full(labels.shape, float(np.linalg.norm(labels.shape)))
    cut = interpolated_sdf(torch.as_tensor(bound * FRAGMENT_VOXEL_M, dtype=torch.float32).flatten(), grid)
    primitives = [fit.primitive for fit in chosen]

    def target(points: torch.Tensor) -> torch.Tensor:
        at = points.detach().cpu()
        with torch.no_grad():
            rest = torch.maximum(sdf(at.float()), cut(at.float()))
            if primitives:
                rest = torch.minimum(rest, torch.stack([p(at) for p in primitives]).min(0).values.float())
        return rest.to(points)

    return target


def primitive_surface(target, primitives: list[FramedPrimitive],
                      near: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Points (M, 3) float32 [m] on the ``primitives``' surfaces that are on ``target``'s too (within
    ``PIN_TOLERANCE_M``; not where another piece covers them), ``near`` (N, 3) [m] projected onto
    each, and their primitive's outward unit normals there (M, 3) float32 (none without primitives)."""
    if not primitives:
        return torch.empty(0, 3), torch.empty(0, 3)
    on = [project_to_zero_set(primitive, near.double()) for primitive in primitives]
    facing = torch.cat([geo.normals(primitive, points) for primitive, points in zip(primitives, on)])
    on = torch.cat(on)
    with torch.no_grad():
        kept = target(on).abs() < PIN_TOLERANCE_M
    return on[kept].float(), facing[kept].detach().float()


def regress_to_primitives(field, frozen, target, chosen: list[FragmentFit], grid: Grid, *, steps: int, lr: float,
                          batch: int, eikonal_weight: float, near_share: float, generator: torch.Generator,
                          decay: bool = False, progress: bool = False) -> None:
    """Regress ``field`` onto ``target`` (:func:`primitive_target` of ``frozen``, the warm start
    held, over the fragments' ``grid``) by :func:`~rfsdf.recon.warm_start.fit_to_image` (``steps``
    at ``lr``, cosine-decayed with ``decay``), its reflectivity held where ``frozen``'s was and
    f = 0 pinned at :func:`primitive_surface` of the ``chosen`` fits' primitives, with its normals
    there (Hermite data: ``PIN_NORMAL_WEIGHT``). Its near points lie within a voxel of either zero
    set, ``target``'s or ``frozen``'s: where a fragment was cut the network has a surface to lose."""
    grid_points = grid.points()
    with torch.no_grad():
        near = grid_points[torch.minimum(target(grid_points).abs(), frozen.sdf(grid_points).abs()) < FRAGMENT_VOXEL_M]
    pins, normals = primitive_surface(target, [fit.primitive for fit in chosen], near)
    reflectivity = lambda p: frozen.reflectivity(p.cpu()).to(p)  # noqa: E731  (held where it was)
    fit_to_image(field, grid.lower_m, grid.upper_m, target, reflectivity, steps=steps, lr=lr, batch=batch,
                 eikonal_weight=eikonal_weight, generator=generator, near_m=near, near_share=near_share,
                 near_jitter_m=FRAGMENT_VOXEL_M, surface_m=pins, surface_weights=torch.ones(len(pins)),
                 surface_weight=PIN_WEIGHT, surface_normals=normals, surface_normal_weight=PIN_NORMAL_WEIGHT,
                 decay=decay, progress=progress)


def primitive_start(field, points: torch.Tensor, towards: torch.Tensor, lower_m, upper_m, *, lr: float, batch: int,
                    eikonal_weight: float, near_share: float, generator: torch.Generator,
                    caps: torch.Tensor | None = None, amplitude: torch.Tensor | None = None,
                    progress: bool = False) -> list[FragmentFit]:
    """Fit every fragment of ``field``'s surface (the range peaks ``points`` (N, 3) [m], unit
    directions ``towards`` their views (N, 3), their glint ``caps`` (N, K, 3) [m] where they are
    read as glints and their ``amplitude`` (N,), see :class:`Fragment`) and, where a primitive
    explains its fragment or a fragment is not :attr:`~Fragment.placed` (cut), :func:`regress_to_primitives`
    (``REGRESSION_STEPS`` from ``lr``, decayed). Returns the fits, each with whether it replaced its
    fragment."""
    frozen = copy.deepcopy(field).cpu().requires_grad_(False)  # the primitives' work is small: on the CPU
    labels, grid, pieces = fragments(frozen.sdf, lower_m, upper_m, points, caps, amplitude)
    free = free_space(points, towards, lower_m, upper_m, occluder=frozen.sdf)
    labels, fits = explain_all(pieces, frozen.sdf, labels, grid, free, progress=progress)
    chosen = [fit for fit in fits if fit.explains]
    unplaced = tuple(piece for piece in pieces if not piece.placed)
    if chosen or unplaced:
        regress_to_primitives(field, frozen, primitive_target(frozen.sdf, labels, grid, chosen, unplaced), chosen,
                              grid, steps=REGRESSION_STEPS, lr=lr, batch=batch, eikonal_weight=eikonal_weight,
                              near_share=near_share, generator=generator, decay=True, progress=progress)
    return fits
