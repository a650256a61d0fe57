"""Band L D L^T of a narrow pencil (mjsound.modal.banded), the shifted pencil on K's pattern
(mjsound.modal.pencil) and SuperLU's order (mjsound.modal.pardiso.superlu), against dense
LAPACK and scipy."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from mjsound.modal import analyze as A
from mjsound.modal import banded as B
from mjsound.modal import eigen as E
from mjsound.modal.pardiso import count_below, superlu
from mjsound.modal.pencil import Pencil


@pytest.fixture(scope="module")
def bar():
    """A free aluminium bar, 12 quadratic cells along it, numbered along its length (a
    narrow band), and its dense spectrum."""
    tm = A.load_mesh("box:0.2,0.01,0.01")
    mat = A.parse_material("aluminium")
    pts, _ = A.surface_samples(tm, 64)
    d = A._discretize("hex", tm, mat, 0.2 / 12, pts, "default", None, 2, None)
    w = sla.eigh(d.K.toarray(), d.M.toarray(), eigvals_only=True)
    return d, w


def _cut(w, i):
    """A point in the first clear gap of the spectrum at or after index i (the bar's bending
    modes come in degenerate pairs): ``(cut, eigenvalues below it)``."""
    while w[i + 1] < w[i] * (1 + 1e-3):
        i += 1
    return 0.5 * (w[i] + w[i + 1]), i + 1


def test_half_bandwidth_matches_dense():
    rng = np.random.default_rng(0)
    D = np.zeros((40, 40))
    for k in range(5):
        D += np.diag(rng.standard_normal(40 - k), -k)
    D = D + D.T
    D[30, 20] = D[20, 30] = 1.0  # one entry further out: the half-bandwidth is 10
    assert B.half_bandwidth(sp.csr_matrix(D)) == 10
    U = sp.csr_matrix(D)
    U.indices = U.indices.copy()
    assert B.half_bandwidth(U.tocoo().tocsr()) == 10


def test_band_count_is_sylvester(bar):
    d, w = bar
    assert B.band_width(d.K, d.M) is not None
    for i in (5, 8, 20, 41):
        lam, below = _cut(w, i)
        assert B.band_count(d.K, d.M, lam) == below
        assert count_below(d.K, d.M, lam, backend="superlu") == below
    # on an eigenvalue (the middle of a degenerate pair) a pivot vanishes: refused
    assert B.band_count(d.K, d.M, 0.5 * (w[8] + w[9])) is None
    assert B.band_count(d.K, d.M, -1e-3 * w[40]) == 0  # the solver's definite shift


def test_band_solver_solves_the_shifted_system(bar):
    d, w = bar
    for sigma in (-1e-3 * w[40], _cut(w, 10)[0]):  # definite, and inside the spectrum
        A_ = (d.K - sigma * d.M).toarray()
        solve = B.band_solver(d.K, d.M, sigma)
        Y = np.random.default_rng(1).standard_normal((A_.shape[0], 5))
        X = solve(Y)
        assert X.shape == Y.shape
        assert np.allclose(X, np.linalg.solve(A_, Y), rtol=1e-7, atol=1e-12 * np.abs(X).max())
        assert np.allclose(solve(Y[:, 2]), X[:, 2], rtol=1e-13, atol=0)


def test_band_refuses_wide_bands_and_zero_pivots():
    # a ring (tridiagonal and a corner): a band as wide as the matrix for 3 entries a row
    ring = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(60, 60)).tolil()
    ring[0, 59] = ring[59, 0] = -1.0
    ring = ring.tocsr()
    assert B.half_bandwidth(ring) == 59
    assert B.band_width(ring, sp.identity(60, format="csr")) is None
    assert B.band_count(ring, sp.identity(60, format="csr"), 1.0) is None
    K = sp.diags(np.arange(1.0, 11.0)).tocsr()  # eigenvalues 1 .. 10 of (K, I)
    M = sp.identity(10, format="csr")
    assert B.band_count(K, M, 3.5) == 3
    assert B.band_count(K, M, 3.0) is None  # the shift on an eigenvalue: a zero pivot
    assert B.band_solver(K, M, 3.0) is None


def test_narrow_band_takes_the_band_route_with_the_dense_band(bar):
    d, w = bar
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 30)[0]
    sol = E.solve_band(d.K, d.M, lo, hi, dense_max=10)
    assert sol.backend == "block-lanczos+superlu"
    ref = w[(w >= lo) & (w <= hi)]
    assert len(sol.eigenvalues) == len(ref) and sol.n_below == 6
    # Rayleigh quotients at the Ritz tolerance: the top pair 1.9e-9 off (SuperLU's factor: 1.8e-9)
    assert np.allclose(sol.eigenvalues, ref, rtol=1e-8)


def test_pencil_is_k_minus_sigma_m_on_k_pattern(bar):
    d, _ = bar
    p = Pencil(d.K, d.M)
    assert p.pos is not None
    A_ = p(123.5)
    assert np.shares_memory(A_.indices, p.K.indices) and np.shares_memory(A_.indptr, p.K.indptr)
    assert abs(A_ - (d.K - 123.5 * d.M)).max() <= 1e-12 * abs(d.K).max()
    # M outside K's pattern: scipy's sum
    K = sp.diags([1.0, 2.0, 3.0]).tocsr()
    M = sp.csr_matrix(np.array([[1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    q = Pencil(K, M)
    assert q.pos is None
    assert np.allclose(q(2.0).toarray(), K.toarray() - 2.0 * M.toarray())


def test_superlu_natural_and_minimum_degree_orders_solve(bar):
    """A narrow band keeps its own order, a compact matrix gets minimum degree: both solve."""
    d, w = bar
    A_ = (d.K + 1e-3 * w[40] * d.M).tocsr()
    rng = np.random.default_rng(3)
    y = rng.standard_normal(A_.shape[0])
    lu = superlu(A_)
    assert np.array_equal(lu.perm_c, np.arange(A_.shape[0]))  # natural
    assert np.allclose(A_ @ lu.solve(y), y, rtol=0, atol=1e-8 * np.abs(y).max())
    G = rng.standard_normal((50, 50))
    C = sp.csr_matrix(G @ G.T + 50 * np.eye(50))
    lu = superlu(C)
    assert np.allclose(C @ lu.solve(y[:50]), y[:50], atol=1e-9)


def test_small_product_kernels_match_numpy():
    from mjsound.modal.block_lanczos import _combine_small, _project_small

    rng = np.random.default_rng(4)
    Q, F, MF, S = (rng.standard_normal(s) for s in ((9, 40), (3, 40), (3, 40), (9, 5)))
    C = np.empty((9, 3))
    G = F.copy()
    _project_small(G, MF, Q, C)
    assert np.allclose(C, Q @ MF.T, rtol=1e-13, atol=1e-13)
    assert np.allclose(G, F - (Q @ MF.T).T @ Q, rtol=1e-13, atol=1e-13)
    V = np.full((40, 5), np.nan)
    _combine_small(Q, S, V)
    assert np.allclose(V, Q.T @ S, rtol=1e-13, atol=1e-13)


def test_block_band_small_products_and_blas_agree(bar, monkeypatch):
    """The bar's band with the numba products and with BLAS's (SMALL_PRODUCTS = 0)."""
    from mjsound.modal import block_lanczos as BL

    d, w = bar
    lo, hi = (2 * np.pi * 20) ** 2, _cut(w, 30)[0]
    small = E.solve_band(d.K, d.M, lo, hi, dense_max=10)
    monkeypatch.setattr(BL, "SMALL_PRODUCTS", 0.0)
    blas = E.solve_band(d.K, d.M, lo, hi, dense_max=10)
    assert len(small.eigenvalues) == len(blas.eigenvalues)
    assert np.allclose(small.eigenvalues, blas.eigenvalues, rtol=1e-10)
