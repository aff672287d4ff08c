"""Interactive 3-D views of meshes for the HTML report and ``rfsdf view`` (plotly).

A reconstruction is judged by turning it around: each figure here is a plotly figure of
one or more meshes, coloured by a per-face quantity with a labelled colour bar, in scene
coordinates [m] with equal axis scales. :func:`figures_html` writes figures into one
self-contained page fragment (plotly.js inline once, no network). Meshes are decimated to
``MAX_FACES`` faces (quadric decimation; the true surface to ``TRUTH_FACES``) so that a page
with four views stays under 10 MB.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import plotly.graph_objects as go
import torch
import trimesh

__all__ = ["MAX_FACES", "TRUTH_FACES", "decimated", "signed_distance_mm", "error_figure", "observed_figure", "views_figure",
           "material_figure", "mesh_figure", "figures_html"]

MAX_FACES = 30_000
TRUTH_FACES = 15_000  # the true surface, drawn as context or coloured by a costly per-face mask
ERROR_LIMIT_MM = 10.0  # colour range of signed errors: +-10 mm, two F-score thresholds
_GREY = "rgb(175,175,175)"


def decimated(mesh: trimesh.Trimesh, max_faces: int = MAX_FACES) -> trimesh.Trimesh:
    """``mesh`` itself when it has at most ``max_faces`` faces, else a quadric decimation to that count."""
    if len(mesh.faces) <= max_faces:
        return mesh
    return mesh.simplify_quadric_decimation(face_count=max_faces)


def signed_distance_mm(points: np.ndarray, sdf: Callable[[torch.Tensor], torch.Tensor]) -> np.ndarray:
    """(N,) signed distance [mm] of points (N, 3) [m] to the zero set of ``sdf`` (positive outside)."""
    with torch.no_grad():
        return sdf(torch.tensor(np.asarray(points), dtype=torch.float64)).double().cpu().numpy() * 1e3


def _surface(mesh: trimesh.Trimesh, name: str, face_values: np.ndarray | None = None, *, color: str = _GREY,
             opacity: float = 1.0, **colouring) -> go.Mesh3d:
    """A Mesh3d trace; with ``face_values`` (F,) the faces are coloured by them (``colouring``:
    colorscale, cmin, cmax, colorbar), otherwise in one colour."""
    v, f = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32)
    trace = dict(x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2], name=name, opacity=opacity,
                 showlegend=True, flatshading=False, lighting=dict(ambient=0.45, diffuse=0.7, specular=0.15))
    if face_values is None:
        return go.Mesh3d(**trace, color=color, hoverinfo="name")
    return go.Mesh3d(**trace, intensity=np.asarray(face_values, np.float32), intensitymode="cell",
                     hovertemplate="%{intensity:.2f}<extra>" + name + "</extra>", **colouring)


def _figure(traces: Sequence, title: str) -> go.Figure:
    axis = lambda name: dict(title=f"{name} [m]", backgroundcolor="rgb(246,246,246)")  # noqa: E731
    fig = go.Figure(list(traces))
    fig.update_layout(title=title, height=620, margin=dict(l=0, r=0, t=50, b=0),
                      legend=dict(x=0, y=1), scene=dict(aspectmode="data", xaxis=axis("x"), yaxis=axis("y"),
                                                        zaxis=axis("z")))
    return fig


def error_figure(mesh: trimesh.Trimesh, truth_sdf: Callable[[torch.Tensor], torch.Tensor], title: str, *,
                 truth: trimesh.Trimesh | None = None, limit_mm: float = ERROR_LIMIT_MM) -> go.Figure:
    """``mesh`` coloured by the signed distance of each face centre to the true surface [mm]
    (red outside the truth, blue inside, clipped at +-limit_mm); with ``truth`` its mesh is
    drawn faintly beside it."""
    mesh = decimated(mesh)
    error = signed_distance_mm(mesh.triangles_center, truth_sdf)
    traces = [_surface(mesh, "reconstruction", error, colorscale="RdBu_r", cmin=-limit_mm, cmax=limit_mm,
                       colorbar=dict(title="signed distance<br>to truth [mm]"))]
    if truth is not None:
        traces.append(_surface(decimated(truth, TRUTH_FACES), "true surface", opacity=0.25))
    return _figure(traces, title)


def observed_figure(truth: trimesh.Trimesh, observed: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
                    title: str) -> go.Figure:
    """The true surface with each face coloured by whether some view observes it:
    ``observed(points (F, 3), normals (F, 3)) -> (F,) bool`` (:func:`rfsdf.radar.coverage.observed_mask`)."""
    truth = decimated(truth, TRUTH_FACES)
    seen = np.asarray(observed(torch.tensor(truth.triangles_center), torch.tensor(truth.face_normals)), float)
    colorscale = [[0.0, "rgb(120,120,120)"], [0.5, "rgb(120,120,120)"], [0.5, "rgb(255,160,20)"],
                  [1.0, "rgb(255,160,20)"]]
    trace = _surface(truth, "true surface", seen, colorscale=colorscale, cmin=0.0, cmax=1.0,
                     colorbar=dict(title="observed", tickvals=[0.25, 0.75], ticktext=["no view", "some view"]))
    fraction = float((seen * truth.area_faces).sum() / truth.area)
    return _figure([trace], f"{title} ({fraction:.0%} of its area observed)")


def views_figure(truth: trimesh.Trimesh, tx_m: np.ndarray, rx_m: np.ndarray, title: str) -> go.Figure:
    """The true surface with the radar's transmitters and receivers of every view around it.

    tx_m : (V, T, 3), rx_m : (V, R, 3) element positions [m] (``Acquisition.tx_m``, ``rx_m``).
    """
    traces = [_surface(decimated(truth, TRUTH_FACES), "true surface")]
    for label, elements, colour in (("Tx", tx_m, "rgb(200,30,30)"), ("Rx", rx_m, "rgb(30,80,200)")):
        e = np.asarray(elements, float)
        views = np.repeat(np.arange(e.shape[0]), e.shape[1])
        traces.append(go.Scatter3d(x=e[..., 0].ravel(), y=e[..., 1].ravel(), z=e[..., 2].ravel(), mode="markers",
                                   name=label, marker=dict(size=2, color=colour), text=[f"view {v}" for v in views],
                                   hovertemplate="%{text}<extra>" + label + "</extra>"))
    return _figure(traces, title)


_CLASS_COLOURS = ("rgb(110,110,120)", "rgb(60,160,220)", "rgb(170,160,140)", "rgb(240,230,200)", "rgb(190,120,60)",
                  "rgb(120,200,120)", "rgb(220,90,160)", "rgb(250,200,40)")


def material_figure(mesh: trimesh.Trimesh, face_class: Callable[[np.ndarray], np.ndarray], classes: Sequence[str],
                    title: str) -> go.Figure:
    """``mesh`` with each face coloured by its predicted material class: ``face_class(centres
    (F, 3) [m]) -> (F,) int`` indexes ``classes`` (one colour each, named on the colour bar)."""
    mesh = decimated(mesh)
    index = np.asarray(face_class(mesh.triangles_center), float)
    k = len(classes)
    colours = [_CLASS_COLOURS[i % len(_CLASS_COLOURS)] for i in range(k)]
    colorscale = [[edge / k, colours[min(i, k - 1)]] for i in range(k) for edge in (i, i + 1)]
    trace = _surface(mesh, "reconstruction", index + 0.5, colorscale=colorscale, cmin=0.0, cmax=float(k),
                     colorbar=dict(title="material", tickvals=[i + 0.5 for i in range(k)], ticktext=list(classes)))
    return _figure([trace], title)


def mesh_figure(mesh: trimesh.Trimesh, title: str) -> go.Figure:
    """``mesh`` in one colour (no truth to compare with)."""
    return _figure([_surface(decimated(mesh), "surface")], title)


def figures_html(figures: Sequence[go.Figure]) -> list[str]:
    """One HTML ``<div>`` per figure; the first carries plotly.js inline, so the page needs no network."""
    return [fig.to_html(full_html=False, include_plotlyjs=(index == 0), config={"displaylogo": False})
            for index, fig in enumerate(figures)]
