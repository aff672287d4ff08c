"""The matrix-free operator against the dense reference, the adjoint identity and autograd."""

import numpy as np
import pytest
import torch

from rfsdf.radar import Acquisition, SensingOperator, load_radar
from rfsdf.radar.dense import dense_matrix

REL_TOL = 2e-5  # complex64 factors, float64-wrapped phases


def _random_acquisition(seed, *, uniform=True, pattern=0.0, spreading=True):
    g = torch.Generator().manual_seed(seed)
    v, t, r, k = 2, 3, 4, 5
    freqs = torch.linspace(77e9, 81e9, k, dtype=torch.float64)
    if not uniform:
        freqs = freqs + torch.tensor([0.0, 3e7, -2e7, 1e7, 0.0], dtype=torch.float64)
    bore = torch.nn.functional.normalize(torch.tensor([[0.1, 0.0, 1.0], [0.0, -0.2, 1.0]], dtype=torch.float64), dim=1)
    return Acquisition(torch.randn(v, t, 3, generator=g, dtype=torch.float64) * 0.05,
                       torch.randn(v, r, 3, generator=g, dtype=torch.float64) * 0.05, freqs, bore, pattern, spreading)


def _points(seed, q=9):
    g = torch.Generator().manual_seed(seed)
    return torch.randn(q, 3, generator=g) * 0.05 + torch.tensor([0.0, 0.0, 0.5])


@pytest.mark.parametrize("uniform,pattern,spreading", [(True, 0.0, True), (False, 1.5, True), (True, 2.0, False)])
def test_forward_adjoint_norms_match_dense(uniform, pattern, spreading):
    acq = _random_acquisition(0, uniform=uniform, pattern=pattern, spreading=spreading)
    pts = _points(1)
    A = dense_matrix(acq, pts.double().numpy())
    op = SensingOperator(acq, memory_budget_bytes=3000)  # forces several chunks
    g = torch.Generator().manual_seed(2)
    c = torch.randn(len(pts), dtype=torch.complex64, generator=g)
    y = torch.randn(*acq.shape, dtype=torch.complex64, generator=g)
    ref_y = A @ c.numpy()
    np.testing.assert_allclose(op.forward(pts, c).numpy().ravel(), ref_y, atol=REL_TOL * np.abs(ref_y).max())
    ref_x = A.conj().T @ y.numpy().ravel()
    np.testing.assert_allclose(op.adjoint(y, pts).numpy(), ref_x, atol=REL_TOL * np.abs(ref_x).max())
    np.testing.assert_allclose(op.column_norms_sq(pts).numpy(), (np.abs(A) ** 2).sum(0), rtol=REL_TOL)
    ref_psf = A.conj().T @ A[:, 2]  # A^H A e_2: CLEAN's point response, factorised over Tx and Rx
    np.testing.assert_allclose(op.point_response(pts[2], pts).numpy(), ref_psf, atol=REL_TOL * np.abs(ref_psf).max())
    per_view = op.point_response(pts[2], pts, per_view=True)
    assert per_view.shape == (acq.shape[0], len(pts))
    torch.testing.assert_close(per_view.sum(0), op.point_response(pts[2], pts))


def test_chunked_equals_unchunked_and_per_view_sums():
    acq, pts = _random_acquisition(3), _points(4, q=50)
    y = torch.randn(*acq.shape, dtype=torch.complex64)
    small, big = SensingOperator(acq, memory_budget_bytes=2000), SensingOperator(acq)
    torch.testing.assert_close(small.adjoint(y, pts), big.adjoint(y, pts), rtol=1e-5, atol=1e-3)
    torch.testing.assert_close(big.adjoint(y, pts, per_view=True).sum(0), big.adjoint(y, pts))


def test_a_gpu_gets_larger_chunks_than_the_cpu_unless_a_budget_is_given():
    """32 MiB chunks keep the CPU's factors in cache; on a GPU they made A c launch-bound
    (as slow as 16 CPU cores on an H200, measured), so CUDA points get 1 GiB chunks. Only the
    device's type is read: no GPU is needed to check the sizes."""
    acq = load_radar("room-60g").acquisition()  # 8 views, 12 channels, 400 frequencies
    op = SensingOperator(acq)
    cpu, cuda = (list(op._chunks(100_000, torch.device(d))) for d in ("cpu", "cuda"))
    assert len(cpu) == 8 * 201 and len(cuda) < len(cpu) / 25  # 499 facets a chunk on the CPU
    for chunks in (cpu, cuda):  # every view and point once
        assert sum((v.stop - v.start if v.stop <= 8 else 8 - v.start) * (min(q.stop, 100_000) - q.start)
                   for v, q in chunks) == 8 * 100_000
    given = SensingOperator(acq, memory_budget_bytes=2**20)
    assert len(list(given._chunks(1000, torch.device("cuda")))) == len(list(given._chunks(1000, torch.device("cpu"))))


def test_adjoint_identity():
    acq, pts = _random_acquisition(5), _points(6, q=40)
    op = SensingOperator(acq)
    g = torch.Generator().manual_seed(7)
    x = torch.randn(len(pts), dtype=torch.complex64, generator=g)
    y = torch.randn(*acq.shape, dtype=torch.complex64, generator=g)
    lhs = torch.vdot(op.forward(pts, x).ravel(), y.ravel())  # <A x, y>
    rhs = torch.vdot(x, op.adjoint(y, pts))  # <x, A^H y>
    assert abs(lhs - rhs) <= 1e-5 * abs(lhs)


def test_the_adjoint_of_bands_is_each_band_s_own_adjoint_and_gradchecks():
    """A^H (y w_b) for every weighting w_b of the frequencies in one pass equals the adjoint of
    each weighted y apart (per view, across chunks), and its backward pass gradchecks."""
    acq, pts = _random_acquisition(12), _points(13, q=30)
    op = SensingOperator(acq, memory_budget_bytes=3000)  # several chunks
    g = torch.Generator().manual_seed(14)
    y = torch.randn(*acq.shape, dtype=torch.complex64, generator=g)
    bands = torch.tensor([[1.0, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0, 1.0], [0.5, 0.0, 2.0, 0.0, 1.0]])
    together = op.adjoint(y, pts, per_view=True, bands=bands)
    assert together.shape == (acq.shape[0], len(bands), len(pts))
    for b, weights in enumerate(bands):
        torch.testing.assert_close(together[:, b], op.adjoint(y * weights, pts, per_view=True), rtol=1e-5, atol=1e-4)
    torch.testing.assert_close(op.adjoint(y, pts, bands=bands), together.sum(0))
    y64 = torch.randn(*acq.shape, dtype=torch.complex128, generator=g).requires_grad_(True)
    few = SensingOperator(acq, memory_budget_bytes=6000)  # six points in two chunks: a gradcheck costs a pass an input
    assert torch.autograd.gradcheck(lambda yy: few.adjoint(yy, pts[:6].double(), bands=bands.double()), (y64,))
    with pytest.raises(ValueError, match="bands"):
        op.adjoint(y, pts, bands=bands[:, :3])


def test_the_adjoint_of_stacked_data_sets_is_each_one_s_and_gradchecks():
    """A^H of S data sets stacked (the factors formed once) equals each set's adjoint apart,
    summed and per view, with and without bands, across chunks; its backward pass gradchecks."""
    acq, pts = _random_acquisition(15), _points(16, q=30)
    op = SensingOperator(acq, memory_budget_bytes=3000)  # several chunks
    g = torch.Generator().manual_seed(17)
    y = torch.randn(3, *acq.shape, dtype=torch.complex64, generator=g)
    bands = torch.tensor([[1.0, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1.0, 1.0]])
    for options in ({}, {"per_view": True}, {"bands": bands}, {"per_view": True, "bands": bands}):
        together = op.adjoint(y, pts, **options)
        torch.testing.assert_close(together, torch.stack([op.adjoint(one, pts, **options) for one in y]),
                                   rtol=1e-5, atol=1e-4)
    y64 = torch.randn(2, *acq.shape, dtype=torch.complex128, generator=g).requires_grad_(True)
    few = SensingOperator(acq, memory_budget_bytes=6000)  # six points in four chunks (two sets: each 1/2 the budget)
    assert torch.autograd.gradcheck(lambda yy: few.adjoint(yy, pts[:6].double(), per_view=True), (y64,))
    with pytest.raises(ValueError, match=r"\(S, V, T, R, K\)"):
        op.adjoint(y[:, :1], pts)


def test_per_view_reflectivity():
    acq, pts = _random_acquisition(8), _points(9)
    c = torch.randn(2, len(pts), dtype=torch.complex64)
    op = SensingOperator(acq)
    y = op.forward(pts, c)
    torch.testing.assert_close(y[1], SensingOperator(acq.view(1)).forward(pts, c[1])[0])
    with pytest.raises(ValueError, match="shape"):
        op.forward(pts, torch.ones(3, len(pts), dtype=torch.complex64))


def test_differentiable_in_reflectivity_and_positions():
    acq = _random_acquisition(10)
    pts = _points(11, q=4).double().requires_grad_(True)
    c = torch.randn(4, dtype=torch.complex64, requires_grad=True)
    y_obs = torch.randn(*acq.shape, dtype=torch.complex64)
    loss = (SensingOperator(acq).forward(pts, c) - y_obs).abs().pow(2).sum()
    loss.backward()
    assert torch.isfinite(pts.grad).all() and pts.grad.abs().sum() > 0
    assert torch.isfinite(c.grad.real).all() and c.grad.abs().sum() > 0


def test_per_frequency_reflectivity_against_dense_and_gradcheck():
    """c (V, K, Q), e.g. a facet's phase integral at each frequency: each frequency's data are
    A_k c_k (the dense reference, row by row), and the hand-written backward passes gradcheck
    in the positions and in c."""
    acq, pts = _random_acquisition(12), _points(13, q=3).double()
    v, t, r, k = acq.shape
    c = torch.randn(v, k, len(pts), dtype=torch.complex128, generator=torch.Generator().manual_seed(1))
    y = SensingOperator(acq).forward(pts, c)
    dense = dense_matrix(acq, pts.numpy()).reshape(v, t, r, k, len(pts))
    expected = torch.einsum("vtrkq,vkq->vtrk", torch.as_tensor(dense).to(c), c)
    torch.testing.assert_close(y, expected, rtol=1e-9, atol=1e-12)
    constant = c[:, :1].expand(v, k, len(pts)).contiguous()
    torch.testing.assert_close(SensingOperator(acq).forward(pts, constant), SensingOperator(acq).forward(pts, c[:, 0]))
    op = SensingOperator(acq)
    args = (pts.clone().requires_grad_(True), c.clone().requires_grad_(True))
    assert torch.autograd.gradcheck(lambda p, cc: op.forward(p, cc), args, eps=1e-7, atol=1e-6, rtol=1e-4)


def test_a_spectrum_beside_per_view_reflectivity_is_their_product_and_gradchecks():
    """c (V, Q) with a spectrum s (K, Q) common to every view (a scan's frames each with its
    own lobe, the facets' phase integral from the scan's centre): the data are A (c s) with
    c s formed as (V, K, Q), and the backward passes gradcheck in the positions, c and s."""
    acq, pts = _random_acquisition(14), _points(15, q=3).double()
    v, _, _, k = acq.shape
    generator = torch.Generator().manual_seed(2)
    c = torch.randn(v, len(pts), dtype=torch.complex128, generator=generator)
    s = torch.randn(k, len(pts), dtype=torch.complex128, generator=generator)
    op = SensingOperator(acq)
    torch.testing.assert_close(op.forward(pts, c, spectrum=s), op.forward(pts, c[:, None] * s[None]))
    with pytest.raises(ValueError, match="spectrum must have shape"):
        op.forward(pts, c, spectrum=s[:, :2])
    args = (pts.clone().requires_grad_(True), c.clone().requires_grad_(True), s.clone().requires_grad_(True))
    assert torch.autograd.gradcheck(lambda p, cc, ss: op.forward(p, cc, spectrum=ss), args, eps=1e-7, atol=1e-6,
                                    rtol=1e-4)
