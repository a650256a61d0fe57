r"""Quadratic forms ``y_i^T A y_i`` of many vectors with one sparse matrix.

The eigensolver's final eigenvalues are Rayleigh quotients ``y^T K y / y^T M y`` of its
Ritz vectors. ``einsum(Y, K @ Y.T)`` forms the whole product ``K Y^T`` (n x k) first; here
each row ``r`` of ``A`` is applied to all k vectors at once from a vector-contiguous copy
``Y^T`` and folded into the k sums right away,

.. math::  q_i = \sum_r y_{ir} \sum_p A_{r, j_p}\, y_{i j_p},

so the inner loop runs over k contiguous numbers and nothing of size n x k is written
(a 20 cm bowl, 34k dofs, 120 vectors: 0.22 s against 0.45 s).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

__all__ = ["quadratic_forms"]


@nb.njit(cache=True, nogil=True, inline="always")
def row_combination(indptr, indices, data, X, r, acc):
    """``acc = sum_p A[r, j_p] X[j_p]``: row ``r`` of the CSR matrix ``A`` applied to the
    rows of ``X`` (each row one node's / dof's numbers of all vectors, contiguous)."""
    for c in range(acc.shape[0]):
        acc[c] = 0.0
    for p in range(indptr[r], indptr[r + 1]):
        a = data[p]
        x = X[indices[p]]
        for c in range(acc.shape[0]):
            acc[c] += a * x[c]


@nb.njit(cache=True, nogil=True, fastmath=True)
def _quadratic_forms(indptr, indices, data, Yt, out):
    k = Yt.shape[1]
    acc = np.empty(k)
    for r in range(indptr.shape[0] - 1):
        row_combination(indptr, indices, data, Yt, r, acc)
        yr = Yt[r]
        for c in range(k):
            out[c] += yr[c] * acc[c]


def quadratic_forms(A: sp.spmatrix, Y: np.ndarray) -> np.ndarray:
    """``q_i = Y[i] @ A @ Y[i]`` for vectors stored as rows ``Y`` (k, n)."""
    A = sp.csr_matrix(A)
    Y = np.asarray(Y, dtype=np.float64)
    out = np.zeros(Y.shape[0])
    _quadratic_forms(A.indptr.astype(np.int64), A.indices.astype(np.int64),
                     np.ascontiguousarray(A.data, dtype=np.float64), np.ascontiguousarray(Y.T), out)
    return out
