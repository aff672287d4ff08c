"""The search over every patch at once (``benchmarks/joint_search.py``) with each candidate's
change kept whole: in the data, every antenna pair and frequency, instead of in the images
near the patch. ``joint_search.py`` keeps each cube's change of the band images within a
margin of the cube, which drops the array's far sidelobes and moves the landscape's minimum
off the truth; the data hold each change exactly (the renderer's sum over facets is linear)
and, thinned as the fit thins them, fit in memory: about 9,000 samples a view.

The same start as there (``--start cubes``: each 1.5 cm cube of the demo's true facets moved
rigidly by the basin study's smooth field, rounded to a searched offset, so the truth is one
of the states searched; ``smooth``: the field itself, tilting the facets), every material and
the radar's gain known. Each searched cube's change of each lit view's data is rendered once
per offset (+-``--span-mm`` at 0.5 mm along its facets' normals), and each loss of a joint
state is exact: ``complex``, sum |turn_v y_v - d_v|^2 over every sample (each view's phase
turn_v held through a sweep, as the fit holds its gain); ``amplitude``, the same over each
antenna pair's range profile's magnitude (the data's FFT over the frequencies). Minimised as
there: iterated conditional modes (ten sweeps) and simulated annealing (T lowered 1000-fold
over 60 sweeps from ``--temperature``).

Usage: python benchmarks/data_search.py [--start cubes|smooth] [--cells 0] [--out FILE]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch
from joint_search import ICM_SWEEPS, STEP_MM, _cooling, displaced, draw, miss_report

from rfsdf.jsonio import to_json

LOSSES = ("complex", "amplitude")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--error-mm", type=float, default=2.0)
    parser.add_argument("--span-mm", type=float, default=4.0)
    parser.add_argument("--cells", type=int, default=0, help="how many cubes to search (0: every cube)")
    parser.add_argument("--start", choices=("smooth", "cubes"), default="cubes")
    parser.add_argument("--cell-m", type=float, default=0.015)
    parser.add_argument("--temperature", type=float, default=1e-3, help="annealing's first temperature")
    parser.add_argument("--radar", default="near-77g")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/data-search.json"))
    args = parser.parse_args()
    torch.set_grad_enabled(False)
    clock = time.perf_counter()
    search = DataSearch(**render_tables(args))
    rendered_s = time.perf_counter() - clock
    rows = {"start": search.report(search.start), "the truth's offsets": search.report(search.truth)}
    for name in LOSSES:
        row = rows[name] = {"loss at the start": search.loss(name, search.start),
                            "loss at the truth's offsets": search.loss(name, search.truth),
                            "loss of the true surface": search.loss_of(name, search.true_data)}
        for label, temperatures in (("iterated conditional modes", [0.0] * ICM_SWEEPS),
                                    (f"annealing from T = {args.temperature:g}", _cooling(args.temperature))):
            state = search.minimise(name, temperatures, np.random.default_rng(0))
            row[label] = {**search.report(state), "loss": search.loss(name, state)}
            print(name, label, to_json(row[label], indent=None), f"{time.perf_counter() - clock:.0f} s", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(to_json({"error_mm": args.error_mm, "cell_m": args.cell_m, "span_mm": args.span_mm,
                                 "step_mm": STEP_MM, "start": args.start, "radar": args.radar,
                                 "cubes searched": len(search.tables), "samples_per_view": search.observed.shape[1],
                                 "rows": rows, "rendering_s": rendered_s, "seconds": time.perf_counter() - clock}))


def _profiles(y: torch.Tensor, order: torch.Tensor) -> torch.Tensor:
    """(T R K,) each antenna pair's range profile of data ``y`` (1, T, R, K): the unitary FFT
    over the frequencies sorted (so the complex loss is the data's own)."""
    return torch.fft.fft(y[..., order], dim=-1, norm="ortho").reshape(-1)


def render_tables(args) -> dict:
    """The start's and the truth's data of every view, the data's own, and for each searched
    cube its lit views and the change of their data (offsets, lit views, samples) per offset."""
    d = displaced(args)
    renderer, gain = d.losses.renderer, d.losses.gain
    order = torch.argsort(renderer.frequencies_hz)

    def data(view: int, facets: torch.Tensor, where: torch.Tensor, facing: torch.Tensor) -> torch.Tensor:
        y = renderer.predict_data(view, where, facing[facets], d.area[facets], d.reflection(facets), d.corners[facets])
        return _profiles(y * gain, order)

    views = range(renderer.num_views)
    observed = torch.stack([_profiles(renderer.view_data(v), order) for v in views])  # (V, n)
    start, truth = torch.zeros_like(observed), torch.zeros_like(observed)
    for view in views:
        for chunk in renderer.lit[view].nonzero().squeeze(1).split(4000):
            start[view] += data(view, chunk, d.start[chunk], d.start_normals)
            truth[view] += data(view, chunk, d.points[chunk], d.normals)
    offsets_mm = np.arange(-args.span_mm, args.span_mm + 1e-9, STEP_MM)
    tables = []
    for j, c in enumerate(d.searched.tolist()):
        members = (d.cube_of_facet == c).nonzero().squeeze(1)
        lit_views = [v for v in views if renderer.lit[v, members].any()]
        change = torch.zeros(len(offsets_mm), len(lit_views), observed.shape[1], dtype=observed.dtype)
        for i, view in enumerate(lit_views):
            lit = members[renderer.lit[view, members]]
            held = data(view, lit, d.start[lit], d.start_normals)
            for o, offset in enumerate(offsets_mm):
                if offset != 0:
                    change[o, i] = data(view, lit, d.start[lit] + offset * 1e-3 * d.normals[lit], d.start_normals) - held
        tables.append((torch.tensor(lit_views, dtype=torch.long), change))
        if (j + 1) % 25 == 0 or j + 1 == len(d.searched):
            print(f"cube {j + 1}/{len(d.searched)}: {len(members)} facets, {len(lit_views)} views", flush=True)
    return {"offsets_mm": offsets_mm, "truth_mm": -d.per_cube(d.error_mm)[d.searched].numpy(),
            "energy": d.energy[d.searched].numpy(), "tables": tables, "start_data": start, "true_data": truth,
            "observed": observed}


class DataSearch:
    """Each loss of any joint state (an offset index per searched cube) over all the data,
    exactly, from the rendered changes, and its minimisation."""

    def __init__(self, offsets_mm, truth_mm, energy, tables, start_data, true_data, observed):
        self.offsets_mm, self.truth_mm, self.energy, self.tables = offsets_mm, truth_mm, energy, tables
        self.start_data, self.true_data, self.observed = start_data, true_data, observed
        self.norm = float((observed.abs() ** 2).sum())
        self.start = np.full(len(tables), int(np.argmin(np.abs(offsets_mm))))
        self.truth = np.array([int(np.argmin(np.abs(offsets_mm - t))) for t in truth_mm])
        self.seen = np.array([bool(change.abs().amax() > 0) for _, change in tables])

    def data(self, state: np.ndarray) -> torch.Tensor:
        """(V, n) the data of a joint state."""
        data = self.start_data.clone()
        for (views, change), o in zip(self.tables, state):
            data[views] += change[o]
        return data

    def misfit(self, name: str, data: torch.Tensor, views, turn: torch.Tensor) -> torch.Tensor:
        """(...,) the loss's share of the data (..., v, n) of ``views``, each turned by ``turn`` (v,)."""
        if name == "complex":
            residual = (turn[:, None] * data - self.observed[views]).abs() ** 2
        else:
            residual = (data.abs() - self.observed[views].abs()) ** 2
        return residual.sum((-2, -1)) / self.norm

    def turn(self, data: torch.Tensor) -> torch.Tensor:
        """(V,) each view's phase that best aligns its data with the measured."""
        inner = (data.conj() * self.observed).sum(1)
        return inner / inner.abs()

    def loss(self, name: str, state: np.ndarray) -> float:
        return self.loss_of(name, self.data(state))

    def loss_of(self, name: str, data: torch.Tensor) -> float:
        return float(self.misfit(name, data, slice(None), self.turn(data)))

    def minimise(self, name: str, temperatures: list[float], rng: np.random.Generator,
                 start: np.ndarray | None = None) -> np.ndarray:
        """From ``start`` (the start's offsets if None), one sweep per temperature over the cubes
        in random order, each cube's offset drawn from exp(-loss / T) given the rest (T = 0: the lowest)."""
        state = (self.start if start is None else start).copy()
        data = self.data(state)
        for temperature in temperatures:
            turn = self.turn(data)
            for j in rng.permutation(len(state)):
                views, change = self.tables[j]
                rest = data[views] - change[state[j]]
                losses = self.misfit(name, rest + change, views, turn[views]).double().numpy()
                choice = draw(losses, state[j], temperature, rng)
                data[views] = rest + change[choice]
                state[j] = choice
        return state

    def report(self, state: np.ndarray) -> dict:
        return miss_report(np.abs(self.offsets_mm[state] - self.truth_mm)[self.seen], self.energy[self.seen])


if __name__ == "__main__":
    main()
