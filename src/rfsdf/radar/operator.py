"""The sensing matrix A of the Born model, applied without storing it.

[A]_{m,q} = a_i(p_q) b_j(p_q) / (d(s_i,p_q) d(p_q,r_j)) exp(-j 2 pi f_k (d(s_i,p_q) + d(p_q,r_j)) / c)
for m = (v, i, j, k). It factorises as U[v,k,i,q] * W[v,k,j,q] with one factor per Tx and
one per Rx, so for each (view, frequency) A c is a (T, Q) @ diag(c) @ (Q, R) product and
A^H y a (T, R) @ (R, Q) product: complex GEMMs instead of T*R*K*Q exponentials.
Phases are computed in float64 and wrapped before the cast to complex64 (at 80 GHz over
0.8 m the phase is ~1300 rad, which float32 would resolve to only ~1e-4 rad).

Gradients. ``forward`` is differentiable in c and in the point positions, ``adjoint`` in y.
Both have hand-written backward passes that recompute the factors chunk by chunk, so a
backward pass needs no more memory than a forward one (autograd through the factors would
keep every chunk's (V, K, T + R, Q) phasors alive). With g = dL/dy (PyTorch's convention
for complex tensors) the position gradient is

    dL/dp_q = Re( c_q sum_m conj(g_m) A_mq [grad log a_i + grad log b_j - j k_k (u_iq + u_qj)] )

with u the unit vectors from the elements to the point: two more GEMMs per chunk. Inputs
in float64 / complex128 are computed in double precision throughout (gradcheck).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from ..geometry import as_points
from ..progress import progress_bar
from .acquisition import SPEED_OF_LIGHT, Acquisition

__all__ = ["SensingOperator"]

# Small chunks keep the factors cache-resident: on 2 cores 32 MiB ran the adjoint 2x faster than 256 MiB.
# A GPU wants large ones: with 32 MiB, A c of l-room's facets (room-60g: 8 views, 400 frequencies,
# 12 channels; 500 facets a chunk) ran no faster on an H200 than on 16 CPU cores (12.9 against
# 14.3 s per 100,000 facets, measured): thousands of small kernels, launch-bound.
_BUDGET_BYTES = {"cpu": 32 * 2**20, "cuda": 2**30}
_BACKWARD_BUFFERS = 3  # the backward pass holds factors, GEMM products and their element-wise products


def _complex_dtype(real: torch.dtype) -> torch.dtype:
    return torch.complex128 if real == torch.float64 else torch.complex64


class SensingOperator:
    """A c, A^H y and the column norms ||A_q||^2 for an :class:`Acquisition`.

    Parameters
    ----------
    acquisition : the measurement geometry.
    memory_budget_bytes : approximate peak memory of the per-chunk factors (None: 32 MiB on
        the CPU, 1 GiB on a GPU, by where the points are).
    """

    def __init__(self, acquisition: Acquisition, *, memory_budget_bytes: int | None = None):
        self.acq = acquisition
        self.budget = None if memory_budget_bytes is None else int(memory_budget_bytes)
        steps = torch.diff(acquisition.frequencies_hz)
        self._uniform = len(steps) > 0 and bool((steps - steps.mean()).abs().max() <= 1e-9 * steps.mean().abs())

    # Factors ------------------------------------------------------------------------
    def _geometry(self, positions: torch.Tensor, boresight: torch.Tensor, points: torch.Tensor,
                  derivatives: bool = False):
        """Distances d (v, E, q) float64 [m] and amplitudes pattern / d (v, E, q) in the points' dtype.

        Elements (v, E, 3) to points (q, 3). The three coordinates are handled one at a
        time: torch.linalg.norm over a last axis of 3 is several times slower. With
        ``derivatives`` also the unit vectors element -> point and grad_p log(amplitude),
        both (v, E, q, 3) [1, 1/m].
        """
        real = points.dtype if points.dtype == torch.float64 else torch.float32
        p = points.detach().double()
        e = positions.to(points.device, torch.float64)
        rel = [p[None, None, :, i] - e[:, :, None, i] for i in range(3)]
        d = torch.sqrt(rel[0] ** 2 + rel[1] ** 2 + rel[2] ** 2)
        amplitude = 1.0 / d if self.acq.spreading else torch.ones_like(d)
        n = self.acq.pattern_exponent
        if n > 0:
            b = boresight.to(points.device, torch.float64)
            cos = sum(rel[i] * b[:, None, None, i] for i in range(3)) / d
            amplitude = amplitude * cos.clamp(min=0) ** n
        if not derivatives:
            return d, amplitude.to(real)
        unit = torch.stack(rel, dim=-1) / d[..., None]
        dlog = -unit / d[..., None] if self.acq.spreading else torch.zeros_like(unit)
        if n > 0:
            lit = (cos > 0)[..., None]
            pattern = n * (b[:, None, None, :] - cos[..., None] * unit) / (d * cos.clamp(min=1e-12))[..., None]
            dlog = dlog + torch.where(lit, pattern, torch.zeros_like(pattern))
        return d, amplitude.to(real), unit.to(real), dlog.to(real)

    def _phasors(self, d: torch.Tensor, amplitude: torch.Tensor, conjugate: bool) -> torch.Tensor:
        """(v, K, E, q) complex: amplitude * exp(-+j k_k d).

        ``conjugate`` builds exp(+j k_k d) directly: multiplying by a lazily conjugated
        tensor is about 2.5x slower than by a plain one, which matters in the adjoint.

        Phases k d are wrapped in float64 before the cast. For uniformly spaced frequencies
        the K phasors are exp(-j k_0 d) s^k with s = exp(-j dk d), K - 1 complex products, so
        trigonometry runs on (v, E, q) only; otherwise every phase is formed directly.
        """
        k = self._wavenumbers(d.device)
        sign = 1.0 if conjugate else -1.0
        wrap = lambda phase: torch.remainder(sign * phase, 2 * math.pi).to(amplitude.dtype)  # noqa: E731
        if self._uniform:
            phasors = [torch.polar(amplitude, wrap(k[0] * d))]  # (v, E, q) each
            step = torch.polar(torch.ones_like(amplitude), wrap((k[1] - k[0]) * d))
            for _ in range(len(k) - 1):
                phasors.append(phasors[-1] * step)
            return torch.stack(phasors, dim=1)
        phase = wrap(k[None, :, None, None] * d[:, None])
        return torch.polar(amplitude[:, None].expand_as(phase), phase)

    def _wavenumbers(self, device) -> torch.Tensor:
        """(K,) float64 free-space wavenumbers 2 pi f / c [rad/m]."""
        return (2 * math.pi / SPEED_OF_LIGHT) * self.acq.frequencies_hz.to(device)

    def _chunks(self, num_points: int, device: torch.device, share: int = 1):
        """Yield (view slice, point slice) pairs sized to ``1 / share`` of the memory budget
        for ``device``."""
        budget = (self.budget or _BUDGET_BYTES.get(torch.device(device).type, _BUDGET_BYTES["cpu"])) // share
        v_total, t, r, k = self.acq.shape
        bytes_per_view_point = k * (t + r) * 24  # complex64 factors + float32 phase temporaries
        points_per_chunk = max(1, min(num_points, budget // bytes_per_view_point))
        views_per_chunk = max(1, min(v_total, budget // (bytes_per_view_point * points_per_chunk)))
        for v0 in range(0, v_total, views_per_chunk):
            for q0 in range(0, num_points, points_per_chunk):
                yield slice(v0, v0 + views_per_chunk), slice(q0, q0 + points_per_chunk)

    def _factors(self, views: slice, points: torch.Tensor, conjugate: bool = False):
        """Tx factor U (v, K, T, q) and Rx factor W (v, K, R, q) of the views ``views``."""
        acq = self.acq
        return tuple(self._phasors(*self._geometry(pos[views], acq.boresight[views], points), conjugate)
                     for pos in (acq.tx_m, acq.rx_m))

    # Public operations ----------------------------------------------------------------
    def forward(self, points: torch.Tensor, c: torch.Tensor, *, spectrum: torch.Tensor | None = None,
                progress: bool = False) -> torch.Tensor:
        """y = A c : (V, T, R, K) complex64 (complex128 for float64 points).

        points : (Q, 3) [m], scene frame. c : (Q,), (V, Q) or (V, K, Q) complex
        reflectivities (one set for all views, one per view, e.g. angle-dependent
        scattering, or one per view and frequency, e.g. a facet's phase integral,
        ``radar/facets.py``). spectrum : (K, Q) complex, a factor per frequency common to
        every view, so that c (V, Q) times it stands for (V, K, Q) without forming it (a
        scan's frames each with its own lobe, their facets' phase integral from the scan's
        centre). Differentiable in ``c``, ``spectrum`` and ``points``.
        """
        points = as_points(points)
        v_total, k_total, q = self.acq.shape[0], self.acq.shape[3], points.shape[0]
        if tuple(c.shape) not in ((q,), (v_total, q), (v_total, k_total, q)):
            raise ValueError(f"c must have shape (Q,), (V, Q) or (V, K, Q) = ({q},), ({v_total}, {q}) or "
                             f"({v_total}, {k_total}, {q}), got {tuple(c.shape)}")
        c = c.to(_complex_dtype(points.dtype))
        c = c.reshape(-1, 1, q).expand(v_total, 1, q) if c.dim() < 3 else c  # (V, 1 or K, Q)
        if spectrum is None:
            return _ApplyA.apply(points, c, self, progress, None)
        if tuple(spectrum.shape) != (k_total, q) or c.shape[1] != 1:
            raise ValueError(f"spectrum must have shape (K, Q) = ({k_total}, {q}) beside c of shape (Q,) or (V, Q), "
                             f"got {tuple(spectrum.shape)} beside {tuple(c.shape)}")
        return _ApplyA.apply(points, c, self, progress, spectrum.to(c.dtype))

    def forward_weighted(self, points: torch.Tensor, c: torch.Tensor,
                         weight: Callable[[slice, slice], torch.Tensor], *, progress: bool = False) -> torch.Tensor:
        """y = A (c w): :meth:`forward` with per-view c (V, Q), each point's c times a weight
        per view and frequency that ``weight(views, points)`` returns for a chunk, (v, K, q)
        complex (a facet's phase integral, ``radar/facets.py``), so that the (V, K, Q)
        weights never exist at once. Not differentiable."""
        points = as_points(points)
        if tuple(c.shape) != (self.acq.shape[0], points.shape[0]):
            raise ValueError(f"c must have shape (V, Q) = ({self.acq.shape[0]}, {points.shape[0]}), got {tuple(c.shape)}")
        return self._apply(points.detach(), c.detach().to(_complex_dtype(points.dtype))[:, None], progress, weight)

    def adjoint(self, y: torch.Tensor, points: torch.Tensor, *, per_view: bool = False,
                bands: torch.Tensor | None = None, progress: bool = False) -> torch.Tensor:
        """x = A^H y at ``points`` (Q, 3): (Q,) complex, or (V, Q) with ``per_view``.

        y : (V, T, R, K), or a stack of S data sets (S, V, T, R, K): then (S, Q) or (S, V, Q),
        the factors formed once for all of them (S adjoints for about one's phasors).
        bands : (B, K) real weights of the frequencies (e.g. masks of sub-bands): the adjoint
        of each weighting of y at once, A^H (y w_b), (B, Q) or (V, B, Q), for the price of one
        (the sum over frequencies is the last one taken). Differentiable in ``y`` (not in the
        points: images are formed on fixed voxels).
        """
        points = as_points(points)
        stacked = y.dim() == 5
        if tuple(y.shape[stacked:]) != self.acq.shape:
            raise ValueError(f"y must have shape (V, T, R, K) = {self.acq.shape} or (S, V, T, R, K), "
                             f"got {tuple(y.shape)}")
        if bands is not None and (bands.dim() != 2 or bands.shape[1] != self.acq.shape[3]):
            raise ValueError(f"bands must have shape (B, K) with K = {self.acq.shape[3]}, got {tuple(bands.shape)}")
        sets = y.movedim(0, 1) if stacked else y[:, None]  # (V, S, T, R, K)
        out = _ApplyAH.apply(sets.to(_complex_dtype(points.dtype)), points, self, progress, bands)  # (V, S, ..., Q)
        if not per_view:
            out = out.sum(dim=0)  # (S, ..., Q)
            return out if stacked else out[0]
        return out.movedim(0, 1) if stacked else out[:, 0]

    def point_response(self, source: torch.Tensor, points: torch.Tensor, *, per_view: bool = False) -> torch.Tensor:
        """A^H A e at ``points`` (Q, 3) [m] for a unit reflector at ``source`` (3,) [m]: (Q,)
        complex, or (V, Q) with ``per_view``; equal to ``adjoint(forward(source, 1), points)``.

        One point's data are rank one in (Tx, Rx) at each frequency, u_t w_r, so the T x R sum
        of the adjoint factorises into a Tx sum times an Rx sum: (T + R) K Q work per view
        instead of T R K Q (24x less for the 48 x 48 demo array; CLEAN's minor cycles).
        """
        points = as_points(points)
        source = as_points(torch.as_tensor(source).reshape(1, 3)).to(points)

        def response(views: slice, pts: slice) -> torch.Tensor:  # (v, q)
            u_src, w_src = self._factors(views, source)  # (v, K, T, 1), (v, K, R, 1)
            u_conj, w_conj = self._factors(views, points[pts], conjugate=True)  # (v, K, T, q), (v, K, R, q)
            return ((u_conj * u_src).sum(2) * (w_conj * w_src).sum(2)).sum(1)

        with torch.no_grad():
            out = self._per_view_points(points, response)
        return out if per_view else out.sum(dim=0)

    def column_norms_sq(self, points: torch.Tensor, *, per_view: bool = False) -> torch.Tensor:
        """||A_q||^2 = K (sum_i a_i^2 / d_i^2)(sum_j b_j^2 / d_j^2): (Q,) float32, or (V, Q) with ``per_view``.

        |exp(-j k d)| = 1, so no phase is formed: this costs (T + R) Q per view, not T R K Q.
        """
        points = as_points(points)
        acq = self.acq
        out = torch.zeros(acq.shape[0], points.shape[0], dtype=torch.float32, device=points.device)
        with torch.no_grad():
            for views, pts in self._chunks(points.shape[0], points.device):
                tx = self._geometry(acq.tx_m[views], acq.boresight[views], points[pts])[1]
                rx = self._geometry(acq.rx_m[views], acq.boresight[views], points[pts])[1]
                out[views, pts] = len(acq.frequencies_hz) * (tx**2).sum(1) * (rx**2).sum(1)
        return out if per_view else out.sum(dim=0)

    # The passes behind forward/adjoint and their gradients -------------------------------
    @torch.no_grad()
    def _apply(self, points: torch.Tensor, c: torch.Tensor, progress: bool = False,
               weight: Callable[[slice, slice], torch.Tensor] | None = None,
               spectrum: torch.Tensor | None = None) -> torch.Tensor:
        """A c for c (V, 1 or K, Q), times ``weight`` (see forward_weighted) or ``spectrum``
        (K, Q) (see forward): (V, T, R, K).
        Each chunk's data are added into one (V, K, T, R) sum as it comes: kept apart until
        the end, the 45,680 chunks of a 10 x 10 m room filled 24 GiB (measured)."""
        total = None
        for views, pts in progress_bar(list(self._chunks(points.shape[0], points.device)), desc="A c",
                                       enabled=progress):
            u, w = self._factors(views, points[pts])  # (v, K, T, q), (v, K, R, q)
            cw = c[views, :, None, pts]  # (v, 1 or K, 1, q)
            if weight is not None:
                cw = cw * weight(views, pts)[:, :, None, :].to(cw.dtype)
            if spectrum is not None:
                cw = cw * spectrum[None, :, None, pts]
            y = torch.matmul(u * cw, w.transpose(-1, -2))  # (v, K, T, R)
            if total is None:
                total = torch.zeros((self.acq.shape[0], *y.shape[1:]), dtype=y.dtype, device=y.device)
            total[views] += y
        return total.permute(0, 2, 3, 1).contiguous()

    @torch.no_grad()
    def _apply_adjoint(self, y: torch.Tensor, points: torch.Tensor, progress: bool = False,
                       bands: torch.Tensor | None = None) -> torch.Tensor:
        """A^H y per view of S data sets y (V, S, T, R, K): (V, S, Q); with ``bands`` (B, K),
        A^H (y w_b) per view: (V, S, B, Q)."""
        y_kf = y.permute(0, 1, 4, 2, 3)  # (V, S, K, T, R)

        def back_project(views: slice, pts: slice) -> torch.Tensor:  # (v, S, q) or (v, S, B, q)
            u_conj, w_conj = (factor[:, None] for factor in self._factors(views, points[pts], conjugate=True))
            z = torch.matmul(y_kf[views].to(points.device), w_conj)  # (v, S, K, T, q)
            if bands is None:
                return (u_conj * z).sum(dim=(2, 3))
            return torch.einsum("bk,vskq->vsbq", bands.to(z.dtype), (u_conj * z).sum(dim=3))

        return self._per_view_points(points, back_project, desc="A^H y", progress=progress, share=y.shape[1])

    def _per_view_points(self, points: torch.Tensor, compute: Callable[[slice, slice], torch.Tensor], *,
                         desc: str = "", progress: bool = False, share: int = 1) -> torch.Tensor:
        """(V, ..., Q): ``compute(views, points)`` (v, ..., q) on each chunk of ``points`` (Q, 3)
        sized to ``1 / share`` of the memory budget, put together."""
        blocks: dict[int, list[torch.Tensor]] = {}
        for views, pts in progress_bar(list(self._chunks(points.shape[0], points.device, share)), desc=desc,
                                       enabled=progress):
            blocks.setdefault(views.start, []).append(compute(views, pts))
        return torch.cat([torch.cat(parts, dim=-1) for _, parts in sorted(blocks.items())], dim=0)

    @torch.no_grad()
    def _apply_vjp(self, points: torch.Tensor, c: torch.Tensor, grad_y: torch.Tensor, need_points: bool,
                   spectrum: torch.Tensor | None = None, need_spectrum: bool = True):
        """Gradients of a real loss with respect to c (V, 1 or K, Q), ``spectrum`` (K, Q) (None:
        none; see forward; not formed unless ``need_spectrum``) and points (Q, 3) (None unless
        ``need_points``), given g = dL/dy."""
        acq = self.acq
        k = self._wavenumbers(points.device).to(points.dtype if points.dtype == torch.float64 else torch.float32)
        g = grad_y.conj().permute(0, 3, 1, 2)  # (V, K, T, R)
        grad_c = torch.zeros_like(c)
        grad_spectrum = None if spectrum is None or not need_spectrum else torch.zeros_like(spectrum)
        grad_points = torch.zeros(points.shape, dtype=points.dtype, device=points.device) if need_points else None
        for views, pts in self._chunks(points.shape[0], points.device, _BACKWARD_BUFFERS):
            tx = self._geometry(acq.tx_m[views], acq.boresight[views], points[pts], derivatives=need_points)
            rx = self._geometry(acq.rx_m[views], acq.boresight[views], points[pts], derivatives=need_points)
            u, w = self._phasors(*tx[:2], False), self._phasors(*rx[:2], False)
            g_v = g[views]
            per_tx = u * torch.matmul(g_v, w)  # (v, K, T, q): sum_j conj(g) A over Rx
            per_frequency = per_tx.sum(dim=2)  # (v, K, q)
            c_chunk = c[views, :, pts]  # (v, 1 or K, q): the reflectivity A sees, times the spectrum if any
            if spectrum is not None:
                grad_c[views, :, pts] = (per_frequency.conj() * spectrum[:, pts].conj()).sum(1, keepdim=True)
                if grad_spectrum is not None:
                    grad_spectrum[:, pts] += (per_frequency.conj() * c_chunk.conj()).sum(0)
                c_chunk = c_chunk * spectrum[:, pts]
            else:
                grad_c[views, :, pts] = (per_frequency if c.shape[1] > 1 else per_frequency.sum(1, keepdim=True)).conj()
            if need_points:
                per_rx = w * torch.matmul(g_v.transpose(-1, -2), u)  # (v, K, R, q): sum_i over Tx
                per_frequency_c = c_chunk.shape[1] > 1
                total = 0
                for per_element, (_, _, unit, dlog) in ((per_tx, tx), (per_rx, rx)):
                    if per_frequency_c:  # c inside the sum over frequencies; else it factors out of it
                        per_element = c_chunk[:, :, None] * per_element  # (v, K, E, q)
                    plain = per_element.sum(1)  # (v, E, q)
                    weighted = (k[None, :, None, None] * per_element).sum(1)
                    total = total + (plain[..., None] * dlog).sum(1) - 1j * (weighted[..., None] * unit).sum(1)
                grad_points[pts] += (total if per_frequency_c else c_chunk[:, 0, :, None] * total).real.sum(0)
        return grad_c, grad_spectrum, grad_points


class _ApplyA(torch.autograd.Function):
    """y = A(points) (c times spectrum) with the memory-bounded backward of
    :meth:`SensingOperator._apply_vjp`."""

    @staticmethod
    def forward(ctx, points, c, op, progress, spectrum):
        ctx.save_for_backward(points, c, spectrum)
        ctx.op = op
        return op._apply(points.detach(), c.detach(), progress, spectrum=None if spectrum is None else spectrum.detach())

    @staticmethod
    def backward(ctx, grad_y):
        points, c, spectrum = ctx.saved_tensors
        grad_c, grad_spectrum, grad_points = ctx.op._apply_vjp(
            points.detach(), c.detach(), grad_y, ctx.needs_input_grad[0],
            None if spectrum is None else spectrum.detach(), ctx.needs_input_grad[4])
        return (grad_points, grad_c if ctx.needs_input_grad[1] else None, None, None,
                grad_spectrum if ctx.needs_input_grad[4] else None)


class _ApplyAH(torch.autograd.Function):
    """x = A^H y per view and data set (per band: A^H (y w_b)); its gradient in each data set y
    is A applied to the gradient in its x (with bands, to sum_b w_bk times the gradient of band
    b, at frequency k)."""

    @staticmethod
    def forward(ctx, y, points, op, progress, bands):
        ctx.save_for_backward(points, bands)
        ctx.op = op
        return op._apply_adjoint(y.detach(), points.detach(), progress, bands)

    @staticmethod
    def backward(ctx, grad_x):
        points, bands = ctx.saved_tensors
        grads = []
        for grad in grad_x.unbind(1):  # each data set's
            c = grad[:, None] if bands is None else torch.einsum("bk,vbq->vkq", bands.to(grad.dtype), grad)
            grads.append(ctx.op._apply(points.detach(), c))
        return torch.stack(grads, dim=1), None, None, None, None
