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

from .. import jit as _jit  # noqa: F401 (registers the kernel cache's stamps before the decorators below)

__all__ = ["quadratic_forms"]

#: products ``A_rp y_ip`` per thread at least (the split of :func:`quadratic_forms`)
QUADRATIC_PRODUCTS_PER_THREAD = 10_000_000


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
def _quadratic_forms(indptr, indices, data, Yt, out, r0, r1):
    """Rows ``r0:r1`` of ``A``'s share of the forms, added to ``out``."""
    k = Yt.shape[1]
    acc = np.empty(k)
    for r in range(r0, r1):
        row_combination(indptr, indices, data, Yt, r, acc)
        yr = Yt[r]
        for c in range(k):
            out[c] += yr[c] * acc[c]


def quadratic_forms(A: sp.spmatrix, Y: np.ndarray, threads: int = 1, columns: bool = False) -> np.ndarray:
    """``q_i = Y[i] @ A @ Y[i]`` for vectors stored as rows ``Y`` (k, n), or as columns
    (``columns=True``: ``Y`` (n, k), used as it is when C-contiguous).

    ``threads > 1`` splits the rows of ``A`` into that many ranges summed on threads (the
    kernel releases the GIL), each range of about equal non-zeros; the partial sums are
    added in the end. A 20 cm bowl's 120 quotients (34k dofs, 5.0M non-zeros of K) are
    worth two threads."""
    A = sp.csr_matrix(A)
    Y = np.asarray(Y, dtype=np.float64)
    indptr, indices = A.indptr, A.indices  # int32 or int64 as scipy has them (a cast wrote 2.8 MB for the beam)
    data, Yt = np.ascontiguousarray(A.data, dtype=np.float64), np.ascontiguousarray(Y if columns else Y.T)
    n = A.shape[0]
    # a thread is worth its start from a few million products on (below that, as for the
    # beam's 23 quotients, its start costs about as much as the work)
    threads = int(max(1, min(threads, A.nnz * Yt.shape[1] // QUADRATIC_PRODUCTS_PER_THREAD)))
    outs = np.zeros((threads, Yt.shape[1]))
    if threads == 1:
        _quadratic_forms(indptr, indices, data, Yt, outs[0], 0, n)
        return outs[0]
    from concurrent.futures import ThreadPoolExecutor

    # row ranges of equal numbers of non-zeros
    cuts = np.searchsorted(indptr, np.linspace(0, indptr[-1], threads + 1)).clip(0, n)
    cuts[0], cuts[-1] = 0, n

    def part(t):
        _quadratic_forms(indptr, indices, data, Yt, outs[t], cuts[t], cuts[t + 1])

    with ThreadPoolExecutor(threads - 1) as pool:
        futures = [pool.submit(part, t) for t in range(1, threads)]
        part(0)
        for f in futures:
            f.result()
    return outs.sum(axis=0)
