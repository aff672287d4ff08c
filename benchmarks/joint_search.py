"""Can a search over many patches' offsets *at once* find the surface where descent and a
search knot by knot (``benchmarks/knot_search.py``) cannot? The demo's true surface, its facets
partitioned into cubes ``--cell-m`` across, is displaced by the basin study's smooth 20 mm
field (rms ``--error-mm``; every material and the radar's gain known), as ``--start``:
``smooth``, the field itself (facets moved along their normals and tilted with it, as a fit's
errors are); ``cubes``, each cube's
facets moved rigidly by the field at the cube rounded to a searched offset (the truth is then
one of the states searched). Every cube is searched (or the ``--cells`` with the most data
energy, the rest held at the start) over offsets of +-``--span-mm`` at 0.5 mm along the
facets' normals: for each cube, offset and view the change of the band images at the voxels
within ``--margin-m`` of the cube is rendered once (superposition: the renderer's sum over
facets is linear), so any joint state's images are the start's plus one change per cube.
Each loss is minimised over the joint offsets by iterated conditional modes (each cube in
turn takes its best offset given the rest, ten sweeps) and by simulated annealing (each cube
drawn from exp(-loss / T), T lowered 1000-fold over 60 sweeps). Reported: how far each lit
cube's offset lies from the truth's (the mean correction over its facets), and each loss at
the start, at the end, at the truth's offsets and of the true surface.

Usage: python benchmarks/joint_search.py [--start smooth|cubes] [--error-mm 2] [--cells 0] [--cache FILE] [--out FILE]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from rfsdf.jsonio import to_json
from rfsdf.materials import MATERIAL_CLASSES, mixture_fresnel
from rfsdf.studies import basin

STEP_MM = 0.5
ANNEALING_SWEEPS, ICM_SWEEPS = 60, 10


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--error-mm", type=float, default=2.0)
    parser.add_argument("--span-mm", type=float, default=4.0)
    parser.add_argument("--cells", type=int, default=0, help="how many cubes to search (0: every cube)")
    parser.add_argument("--start", choices=("smooth", "cubes"), default="smooth",
                        help="the field itself, tilting the facets, or rigid cubes at searched offsets")
    parser.add_argument("--cell-m", type=float, default=0.015)
    parser.add_argument("--margin-m", type=float, default=0.015)
    parser.add_argument("--radar", default=basin.Settings.radar)
    parser.add_argument("--cache", type=Path, help="keep the rendered changes here (and read them if there)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/joint-search.json"))
    args = parser.parse_args()
    torch.set_grad_enabled(False)
    clock = time.perf_counter()
    if args.cache and args.cache.exists():
        changes = torch.load(args.cache, weights_only=False)
    else:
        changes = render_changes(args)
        if args.cache:
            torch.save(changes, args.cache)
    search = JointSearch(changes)
    rows = {"start": search.report(search.start), "the truth's offsets": search.report(search.truth)}
    for images in ("the start's", "the truth's")[:2 if args.start == "cubes" else 1]:
        if images == "the truth's":  # the truth (a state searched) exact, every other state by its changes from it
            search.anchor_at_truth()
        for name in ("amplitude", "split", "complex"):
            row = rows.setdefault(f"{images} images exact", {})[name] = {
                "loss at the start": search.loss(name, search.start),
                "loss at the truth's offsets": search.loss(name, search.truth),
                "loss of the true surface": search.loss_of(name, changes["truth"])}
            for label, temperatures in (("iterated conditional modes", [0.0] * ICM_SWEEPS),
                                        ("annealing from T = 1e-3", _cooling(1e-3))):
                state = search.minimise(name, temperatures, np.random.default_rng(0))
                row[label] = {**search.report(state), "loss": search.loss(name, state)}
                print(images, name, label, to_json(row[label], indent=None), f"{time.perf_counter() - clock:.0f} s",
                      flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"error_mm": args.error_mm, "cell_m": args.cell_m, "margin_m": args.margin_m,
                                 "span_mm": args.span_mm, "step_mm": STEP_MM, "start": args.start,
                                 "cubes searched": len(changes["changes"]),
                                 "searched_energy_share": changes["energy_share"], "rows": rows,
                                 "seconds": time.perf_counter() - clock}))


def _cooling(start: float) -> list[float]:
    """Annealing temperatures: ``start`` lowered 1000-fold geometrically, then five sweeps at 0."""
    return list(start * np.geomspace(1.0, 1e-3, ANNEALING_SWEEPS)) + [0.0] * 5


@dataclass
class Displaced:
    """The demo's true surface as the renderer sums it, cut into cubes, and the start displaced
    from it (``--start``); shared by the image-space search here and ``data_search.py``."""

    scene: object
    losses: basin.SurfaceLosses
    points: torch.Tensor  # (Q, 3) the true facets' centroids [m]
    normals: torch.Tensor  # (Q, 3) their unit normals
    area: torch.Tensor  # (Q,) [m^2]
    corners: torch.Tensor  # (Q, 3, 3) [m] relative to the centroids
    probabilities: torch.Tensor  # (Q, classes) one-hot, the true materials
    permittivities: torch.Tensor  # (classes,) at the data's centre frequency
    start: torch.Tensor  # (Q, 3) the start's facets [m]
    start_normals: torch.Tensor  # (Q, 3)
    error_mm: torch.Tensor  # (Q,) the start's displacement along the true normals
    cube_of_facet: torch.Tensor  # (Q,) index into cubes
    cubes: torch.Tensor  # (C, 3) integer corners
    weights: torch.Tensor  # (C,) each cube's area [m^2]
    energy: torch.Tensor  # (C,) the data's image energy at each cube's shown voxels
    searched: torch.Tensor  # (S,) the cubes searched, most energy first

    def per_cube(self, values: torch.Tensor) -> torch.Tensor:
        """(C,) the area-weighted mean over each cube's facets of per-facet ``values`` (Q,)."""
        return _cube_mean(values, self.cube_of_facet, self.area, self.weights)

    def reflection(self, facets: torch.Tensor):
        """cos (Q_f,) -> the Fresnel coefficients of ``facets``' true materials."""
        return lambda cos: mixture_fresnel(cos, self.probabilities[facets], self.permittivities).to(torch.complex64)


def displaced(args) -> Displaced:
    """The true surface (every material and the gain known), its cubes and the displaced start."""
    settings = basin.Settings(device="cpu", radar=args.radar)
    scene, losses = basin.surface_losses(settings)
    renderer = losses.renderer
    renderer.refresh(scene.sdf, torch.Generator().manual_seed(0))
    points, normals, area, corners = renderer.surface_geometry(basin.FixedSurface(scene.sdf), geometry=False)
    probabilities = torch.nn.functional.one_hot(losses.known(renderer.candidates.anchors), len(MATERIAL_CLASSES)).float()
    lower = torch.as_tensor(scene.lower_m, dtype=points.dtype)
    cube_of_facet, cubes = _cubes(points, lower, args.cell_m)
    field = basin.smooth_displacement(scene, settings.correlation_m, torch.Generator().manual_seed(settings.seed))
    weights = torch.zeros(len(cubes), dtype=points.dtype).index_add_(0, cube_of_facet, area)
    if args.start == "cubes":  # each cube's facets moved rigidly by the field at the cube, rounded to a searched offset
        centres = torch.stack([_cube_mean(points[:, i], cube_of_facet, area, weights) for i in range(3)], 1)
        limit = args.span_mm - STEP_MM
        error_mm = torch.as_tensor(np.clip(np.round(args.error_mm * field(centres).double().numpy() / STEP_MM) * STEP_MM,
                                           -limit, limit), dtype=points.dtype)[cube_of_facet]
        start_normals = normals
    else:  # the smooth field itself, the facets moved along their normals and tilted with it
        with torch.enable_grad():
            where = points.detach().clone().requires_grad_(True)
            moved = args.error_mm * field(where)
            slope = torch.autograd.grad(moved.sum(), where)[0]  # [mm/m]
        error_mm = moved.detach()
        start_normals = torch.nn.functional.normalize(normals - 1e-3 * slope, dim=1)
    start = points + error_mm[:, None] * 1e-3 * normals
    voxels = renderer.voxels[losses.voxels]
    voxel_cubes = _cubes(voxels, lower, args.cell_m, cubes)[0]
    energy = torch.zeros(len(cubes)).index_add_(0, voxel_cubes.clamp(min=0),
                                               (renderer.observed[:, losses.voxels].abs() ** 2).sum(0) * (voxel_cubes >= 0))
    searched = energy.argsort(descending=True)[:args.cells or len(cubes)]
    return Displaced(scene, losses, points, normals, area, corners, probabilities,
                     renderer.class_permittivities(MATERIAL_CLASSES), start, start_normals, error_mm,
                     cube_of_facet, cubes, weights, energy, searched)


def render_changes(args) -> dict:
    """The start's band images at the searched cubes' voxels, the truth's, and each searched
    cube's change of them (offsets, views, 2, its voxels) for each offset from the start."""
    d = displaced(args)
    renderer, losses, searched = d.losses.renderer, d.losses, d.searched
    points, normals, area, corners, start = d.points, d.normals, d.area, d.corners, d.start
    scale = losses.gain / renderer.observed_peak
    lower = torch.as_tensor(d.scene.lower_m, dtype=points.dtype)
    cubes = d.cubes
    voxels = renderer.voxels[losses.voxels]
    near = [((voxels >= lower + cubes[c] * args.cell_m - args.margin_m)
             & (voxels < lower + (cubes[c] + 1) * args.cell_m + args.margin_m)).all(1).nonzero().squeeze(1)
            for c in searched.tolist()]
    region = torch.unique(torch.cat(near))
    at = torch.full((len(voxels),), -1, dtype=torch.long)
    at[region] = torch.arange(len(region))

    def images(view: int, facets: torch.Tensor, where: torch.Tensor, voxel: torch.Tensor,
               facing=d.start_normals) -> torch.Tensor:
        data = renderer.predict_data(view, where, facing[facets], area[facets], d.reflection(facets), corners[facets])
        return renderer._band_images(view, data, voxels[voxel], losses.voxels[voxel]) * scale

    offsets_mm = np.arange(-args.span_mm, args.span_mm + 1e-9, STEP_MM)
    start_images = torch.zeros(renderer.num_views, 2, len(region), dtype=torch.complex64)
    truth_images = torch.zeros_like(start_images)
    for view in range(renderer.num_views):
        for chunk in renderer.lit[view].nonzero().squeeze(1).split(4000):
            start_images[view] += images(view, chunk, start[chunk], region)
            truth_images[view] += images(view, chunk, points[chunk], region, normals)
    changes = []
    for j, c in enumerate(searched.tolist()):
        members = (d.cube_of_facet == c).nonzero().squeeze(1)
        change = torch.zeros(len(offsets_mm), renderer.num_views, 2, len(near[j]), dtype=torch.complex64)
        for view in range(renderer.num_views):
            lit = members[renderer.lit[view, members]]
            if len(lit) == 0:
                continue
            held = images(view, lit, start[lit], near[j])
            for o, offset in enumerate(offsets_mm):
                if offset != 0:
                    change[o, view] = images(view, lit, start[lit] + offset * 1e-3 * normals[lit], near[j]) - held
        changes.append(change)
        print(f"cube {j + 1}/{len(searched)}: {len(members)} facets, {len(near[j])} voxels", flush=True)
    return {"offsets_mm": offsets_mm, "truth_mm": -d.per_cube(d.error_mm)[searched].numpy(), "energy": d.energy[searched].numpy(),
            "energy_share": float(d.energy[searched].sum() / d.energy.sum()), "near": [at[n] for n in near],
            "changes": changes, "start": start_images, "truth": truth_images,
            "observed": renderer.band_observed[:, :, losses.voxels[region]], "band_shares": renderer.band_shares}


def _cube_mean(values: torch.Tensor, cube_of_facet: torch.Tensor, area: torch.Tensor, weights: torch.Tensor):
    """(C,) the area-weighted mean over each cube's facets of per-facet ``values`` (Q,)."""
    return torch.zeros(len(weights), dtype=values.dtype).index_add_(0, cube_of_facet, values * area) / weights


def _cubes(points: torch.Tensor, lower: torch.Tensor, size_m: float, known: torch.Tensor | None = None):
    """Each point's cube (index into the cubes, (N,)) and the cubes' integer corners (C, 3);
    with ``known`` cubes given, -1 for a point in none of them."""
    corner = torch.floor((points - lower) / size_m).long()
    if known is None:
        known, index = torch.unique(corner, dim=0, return_inverse=True)
        return index, known
    lookup = {tuple(c): i for i, c in enumerate(known.tolist())}
    return torch.tensor([lookup.get(tuple(c), -1) for c in corner.tolist()]), known


class JointSearch:
    """Each loss of any joint state (an offset index per searched cube) over the searched
    cubes' voxels, from the rendered changes, and its minimisation."""

    def __init__(self, changes: dict):
        self.offsets_mm, self.changes, self.near = changes["offsets_mm"], changes["changes"], changes["near"]
        self.energy, self.start_images, self.true_images = changes["energy"], changes["start"], changes["truth"]
        self.shares = changes["band_shares"].to(torch.complex64)
        observed = changes["observed"]
        self.observed = torch.einsum("vbx,b->vx", observed, self.shares)
        self.observed_split = observed[:, 0] * observed[:, 1].conj()
        self.norm = {"amplitude": float((self.observed.abs() ** 2).sum()), "complex": float((self.observed.abs() ** 2).sum()),
                     "split": float((self.observed_split.abs() ** 2).sum())}
        self.start = np.full(len(self.changes), int(np.argmin(np.abs(self.offsets_mm))))
        self.truth_mm = changes["truth_mm"]
        self.truth = np.array([int(np.argmin(np.abs(self.offsets_mm - t))) for t in self.truth_mm])
        self.seen = np.array([bool(change.abs().amax() > 0) for change in self.changes])  # some view lights it

    def anchor_at_truth(self) -> None:
        """Images of any state from the true surface's, exact at the truth's offsets (the
        start's are then approximate: each cube's change is kept within its margin only)."""
        self.start_images = self.true_images - (self.images(self.truth) - self.start_images)

    def images(self, state: np.ndarray) -> torch.Tensor:
        images = self.start_images.clone()
        for j, o in enumerate(state):
            images[:, :, self.near[j]] += self.changes[j][o]
        return images

    def misfit(self, name: str, images: torch.Tensor, voxels, turn: torch.Tensor) -> torch.Tensor:
        """(...,) the loss's share at ``voxels`` of band images (..., V, 2, X) there, each view's
        full-band image turned by ``turn`` (V,) for the complex loss (held, as the fit holds it)."""
        full = torch.einsum("...vbx,b->...vx", images, self.shares)
        if name == "amplitude":
            residual = (full.abs() - self.observed[:, voxels].abs()) ** 2
        elif name == "complex":
            residual = (turn[:, None] * full - self.observed[:, voxels]).abs() ** 2
        else:
            residual = (images[..., 0, :] * images[..., 1, :].conj() - self.observed_split[:, voxels]).abs() ** 2
        return residual.sum((-2, -1)) / self.norm[name]

    def turn(self, images: torch.Tensor) -> torch.Tensor:
        """(V,) each view's phase that best aligns its full-band image with the data's."""
        inner = (torch.einsum("vbx,b->vx", images, self.shares).conj() * self.observed).sum(1)
        return inner / inner.abs()

    def loss(self, name: str, state: np.ndarray) -> float:
        return self.loss_of(name, self.images(state))

    def loss_of(self, name: str, images: torch.Tensor) -> float:
        """The loss of band images (V, 2, X) at every voxel of the searched cubes."""
        return float(self.misfit(name, images, slice(None), self.turn(images)))

    def minimise(self, name: str, temperatures: list[float], rng: np.random.Generator) -> np.ndarray:
        """From the start, one sweep per temperature over the cubes in random order, each cube's
        offset drawn from exp(-loss / T) given the rest (T = 0: the lowest)."""
        state, images = self.start.copy(), self.start_images.clone()
        for temperature in temperatures:
            turn = self.turn(images)
            for j in rng.permutation(len(state)):
                near, change = self.near[j], self.changes[j]
                losses = self.misfit(name, images[:, :, near] - change[state[j]] + change, near, turn).double().numpy()
                choice = draw(losses, state[j], temperature, rng)
                images[:, :, near] += change[choice] - change[state[j]]
                state[j] = choice
        return state

    def report(self, state: np.ndarray) -> dict:
        return miss_report(np.abs(self.offsets_mm[state] - self.truth_mm)[self.seen], self.energy[self.seen])


def draw(losses: np.ndarray, present: int, temperature: float, rng: np.random.Generator) -> int:
    """An offset index drawn from exp(-loss / T) over the candidates' ``losses``, or (T = 0)
    the lowest, the ``present`` one where it ties."""
    if temperature > 0:
        weights = np.exp(-(losses - losses.min()) / temperature)
        return int(rng.choice(len(losses), p=weights / weights.sum()))
    return present if losses[present] <= losses.min() else int(np.argmin(losses))


def miss_report(miss: np.ndarray, energy: np.ndarray) -> dict:
    """How far the seen cubes' offsets lie from the truth's (their mean over each cube's
    facets), ``miss`` [mm] and each cube's data ``energy``, (S,) each."""
    return {"median_miss_mm": float(np.median(miss)), "share_within_0.5_mm": float(np.mean(miss <= 0.5)),
            "energy_weighted_miss_mm": float((energy * miss).sum() / energy.sum())}


if __name__ == "__main__":
    main()
