r"""Narrow-banded pencils: ``L D L^T`` of ``K - sigma M`` in band storage, for Sylvester
counts and shift-invert solves without a sparse factorization.

A matrix whose rows reach at most ``w`` columns left of the diagonal (a bar numbered along
its length: the beam's 3123 dofs, ``w = 122``) keeps that band through an elimination
without pivoting, so its factorization ``A = L D L^T`` fits an array ``B`` (n, w + 1) whose
row ``k`` holds column ``k`` from the diagonal down:

.. math::  B_{k, i} = A_{k + i,\, k}, \qquad d_k = B_{k, 0}, \qquad
           B_{k + i,\, j} \mathrel{-}= \frac{B_{k, i}}{d_k}\, B_{k,\, i + j}
           \quad (1 \le i \le w,\ 0 \le j \le w - i)

(column ``k + i`` updated by column ``k``; both contiguous), after which
``L_{k + i, k} = B_{k, i} / d_k``. Sylvester's law of inertia: the eigenvalues of ``K phi =
lambda M phi`` below ``sigma`` are as many as the negative ``d_k``. A solve ``A X = Y`` runs
forward through ``L``, divides by ``D`` and back through ``L^T``, on all columns of ``X``
at once (rows of ``X`` contiguous).

Without pivoting a pivot may come out zero or tiny (``sigma`` on an eigenvalue, or an
unlucky order): then the factorization is refused (None) and the caller takes SuperLU.
For the definite ``K - sigma M`` (``sigma < 0``) every pivot is positive and the
elimination is stable (a Cholesky factorization in another form).

On the beam the count writes a fraction of the memory SuperLU's does (same order, its ``U``
read back for the diagonal), and the shift's factorization is faster too; in a process's
first analysis every fresh page costs a fault (``scripts/bench_modal.py --vs-skfem``
measures both).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

from .. import jit as _jit  # noqa: F401 (registers the kernel cache's stamps before the decorators below)

__all__ = ["band_ldlt", "band_count", "band_solver", "band_width", "half_bandwidth"]

#: the band applies when its storage ``n (w + 1)`` is at most this many times the number
#: of lower-triangle entries of ``K`` (the beam: 2.2) ...
BAND_MAX_FILL = 3.0
#: ... and its factorization's ``n w^2`` multiply-adds at most this many. The beam's whole
#: band solve (count, factorization, block Lanczos; 6 kHz) against PARDISO's (median of 4,
#: alternated, one process): 3123 dofs (``n w^2`` = 4.6e7) 0.061 s against 0.098 s; 9063
#: (1.35e8) 0.15 against 0.25 s; 54 195 at 200 elements along it (w = 320: 5.6e9) 7.7
#: against 3.5 s
BAND_MAX_FLOPS = 3e8
#: a pivot at most this fraction of its diagonal entry in ``A`` refuses the factorization:
#: its sign (and inverse) would be rounding
PIVOT_TOL = 1e-12


def _csr(A):
    """``A`` itself when it is CSR already (scipy keeps its sorted-indices flag per object)."""
    return A if sp.isspmatrix_csr(A) else sp.csr_matrix(A)


def half_bandwidth(A: sp.spmatrix) -> int:
    """Largest ``i - j`` over the stored entries ``A[i, j]`` with ``j <= i`` (A symmetric)."""
    A = _csr(A)
    rows = np.flatnonzero(np.diff(A.indptr))
    if len(rows) == 0:
        return 0
    if A.has_sorted_indices:
        first = A.indices[A.indptr[rows]]
    else:
        first = np.minimum.reduceat(A.indices, A.indptr[rows])
    return int(max(0, np.max(rows - first)))


@nb.njit(cache=True, nogil=True)
def _band_fill(indptr, indices, data, scale, B):
    """``B[j, i - j] += scale * A[i, j]`` for the stored ``A[i, j]``, ``0 <= i - j <= w``."""
    w1 = B.shape[1]
    for i in range(indptr.shape[0] - 1):
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if j <= i and i - j < w1:
                B[j, i - j] += scale * data[p]


#: floating-point liberties of the kernels: reassociation and fused multiply-adds, but NaN and
#: infinity stay visible (a pivot's check)
_FAST = {"reassoc", "contract", "nsz", "arcp"}


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _ldlt(B, diagonal, tol):
    """``A = L D L^T`` in place in the band ``B`` (n, w + 1) (module docstring). Returns the
    number of negative pivots, or -1 if a pivot is not finite or at most ``tol |A_kk|``
    (``diagonal``: ``A``'s diagonal, (n,))."""
    n, w1 = B.shape
    negatives = 0
    for k in range(n):
        d = B[k, 0]
        if not np.isfinite(d) or abs(d) <= tol * abs(diagonal[k]):
            return -1
        if d < 0.0:
            negatives += 1
        m = min(w1 - 1, n - 1 - k)
        for i in range(1, m + 1):
            f = B[k, i] / d
            for j in range(m - i + 1):
                B[k + i, j] -= f * B[k, i + j]
    return negatives


@nb.njit(cache=True, nogil=True, fastmath=_FAST)
def _ldlt_solve(B, X):
    """``X <- A^{-1} X`` for rows ``X`` (n, m) (one right-hand side per column), ``B`` the
    factorization by :func:`_ldlt`: ``y = L^{-1} x`` forward, ``D^{-1}``, then ``x_k = y_k /
    d_k - sum_i L_{k+i,k} x_{k+i}`` backward."""
    n, w1 = B.shape
    m = X.shape[1]
    for k in range(n):
        f0 = 1.0 / B[k, 0]
        for i in range(1, min(w1, n - k)):
            f = B[k, i] * f0
            for c in range(m):
                X[k + i, c] -= f * X[k, c]
    for k in range(n):
        f0 = 1.0 / B[k, 0]
        for c in range(m):
            X[k, c] *= f0
    for k in range(n - 1, -1, -1):
        f0 = 1.0 / B[k, 0]
        top = min(w1, n - k)
        for c in range(m):
            acc = 0.0
            for i in range(1, top):
                acc += B[k, i] * X[k + i, c]
            X[k, c] -= acc * f0


def band_ldlt(K: sp.spmatrix, M: sp.spmatrix | None = None, sigma: float = 0.0, out: np.ndarray | None = None):
    """``(B, negatives)``: the band ``L D L^T`` of ``K - sigma M`` (module docstring) and
    its negative pivots, or None when the band does not apply (:func:`band_width`) or a
    pivot is too small (:data:`PIVOT_TOL`).

    Parameters
    ----------
    K, M : (n, n) sparse symmetric (M optional: ``K`` alone).
    sigma : float
        The shift [rad^2/s^2].
    out : (n, w + 1) float array, optional
        Storage to factor in (another factorization's band of the same pencil, no longer
        needed): no fresh memory.
    """
    K = _csr(K)
    n = K.shape[0]
    if n == 0:
        return np.zeros((0, 1)), 0
    w = band_width(K, M)
    if w is None:
        return None
    if out is not None and out.shape == (n, w + 1) and out.dtype == np.float64 and out.flags.c_contiguous:
        B = out
        B[:] = 0.0
    else:
        B = np.zeros((n, w + 1))
    _band_fill(K.indptr, K.indices, K.data.astype(np.float64, copy=False), 1.0, B)
    if M is not None and sigma != 0.0:
        M = _csr(M)
        _band_fill(M.indptr, M.indices, M.data.astype(np.float64, copy=False), -float(sigma), B)
    negatives = _ldlt(B, B[:, 0].copy(), PIVOT_TOL)
    return None if negatives < 0 else (B, int(negatives))


def band_width(K: sp.spmatrix, M: sp.spmatrix | None = None) -> int | None:
    """Half-bandwidth ``w`` of ``K - sigma M`` when the band applies (:data:`BAND_MAX_FILL`,
    :data:`BAND_MAX_FLOPS`), else None."""
    K = _csr(K)
    n = K.shape[0]
    w = half_bandwidth(K) if M is None else max(half_bandwidth(K), half_bandwidth(M))
    if n * (w + 1.0) > BAND_MAX_FILL * 0.5 * (K.nnz + n) or n * float(w) ** 2 > BAND_MAX_FLOPS:
        return None
    return w


def band_count(K: sp.spmatrix, M: sp.spmatrix, lam: float) -> int | None:
    """Eigenvalues of ``K phi = lambda M phi`` below ``lam`` (Sylvester), or None
    (:func:`band_ldlt` refused)."""
    got = band_ldlt(K, M, lam)
    return None if got is None else got[1]


def band_solver(K: sp.spmatrix, M: sp.spmatrix | None = None, sigma: float = 0.0, out: np.ndarray | None = None):
    """``solve(Y)`` = ``(K - sigma M)^{-1} Y`` for a vector (n,) or a block (n, m), or None
    (:func:`band_ldlt` refused; ``out`` as there)."""
    got = band_ldlt(K, M, sigma, out)
    if got is None:
        return None
    B = got[0]

    def solve(Y):
        Y = np.asarray(Y, dtype=np.float64)
        X = np.array(Y.reshape(Y.shape[0], -1), order="C")
        _ldlt_solve(B, X)
        return X.reshape(Y.shape)

    return solve
