r"""Shifted matrices ``A(sigma) = K - sigma M`` of one pencil on the stiffness's own pattern.

The eigensolver factors ``K - sigma M`` for two or more shifts (the Sylvester count at the
band top, the Lanczos shift). Every discretization here assembles ``M`` on node pairs that
``K`` couples too, so ``M``'s entries are a subset of ``K``'s: with ``pos[q]`` the place of
``M``'s entry ``q`` among ``K``'s (found once, :func:`_pattern_positions`),

.. math::  A(\sigma)_p = K_p - \sigma \sum_{q:\ pos_q = p} M_q,

one pass over ``K``'s values; the result shares ``K``'s index arrays. scipy's ``K - sigma
* M`` (a scaled copy of ``M``, then a general sparse sum into arrays sized for ``nnz(K) +
nnz(M)``) wrote 1.6k fresh pages for the beam's 3123 dofs where this writes the 0.65k of
the values; a page first written in a process costs a fault (``scripts/bench_modal.py
--vs-skfem``). A pencil whose ``M`` is not within ``K``'s pattern falls back to scipy's sum.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp

from .. import jit as _jit  # noqa: F401 (registers the kernel cache's stamps before the decorators below)

__all__ = ["Pencil"]


@nb.njit(cache=True, nogil=True)
def _pattern_positions(k_indptr, k_indices, m_indptr, m_indices, pos):
    """``pos[q]``: the index among ``K``'s stored entries of ``M``'s entry ``q`` (same row
    and column; both CSR with sorted columns). Returns False if one is not stored in ``K``."""
    for i in range(m_indptr.shape[0] - 1):
        p = k_indptr[i]
        end = k_indptr[i + 1]
        for q in range(m_indptr[i], m_indptr[i + 1]):
            c = m_indices[q]
            while p < end and k_indices[p] < c:
                p += 1
            if p == end or k_indices[p] != c:
                return False
            pos[q] = p
    return True


@nb.njit(cache=True, nogil=True)
def _shifted_values(k_data, m_data, pos, sigma, out):
    """``out = K - sigma M`` on ``K``'s pattern (``pos`` from :func:`_pattern_positions`)."""
    for p in range(k_data.shape[0]):
        out[p] = k_data[p]
    for q in range(pos.shape[0]):
        out[pos[q]] -= sigma * m_data[q]


class Pencil:
    """``pencil(sigma)``: ``K - sigma M`` as CSR (module docstring).

    Parameters
    ----------
    K, M : (n, n) sparse
        Stiffness and mass; converted to CSR with sorted columns if they are not.
    """

    def __init__(self, K: sp.spmatrix, M: sp.spmatrix):
        self._K, self._M, self._pos = K, M, False  # the pattern is matched on the first call

    @property
    def pos(self):
        """Places of ``M``'s entries among ``K``'s (int64, (nnz(M),)), or None when ``M``
        has an entry ``K`` does not store."""
        if self._pos is False:
            self.K, self.M = self._canonical(self._K), self._canonical(self._M)
            self._pos = None
            if self.K.shape == self.M.shape:
                pos = np.empty(self.M.nnz, np.int64)
                if _pattern_positions(self.K.indptr, self.K.indices, self.M.indptr, self.M.indices, pos):
                    self._pos = pos
        return self._pos

    @staticmethod
    def _canonical(A):
        A = sp.csr_matrix(A)
        if not A.has_sorted_indices:
            A = A.sorted_indices()
        return A

    def __call__(self, sigma: float) -> sp.csr_matrix:
        if self.pos is None:  # (matches the pattern first)
            return sp.csr_matrix(self.K - sigma * self.M)
        data = np.empty_like(self.K.data, dtype=np.float64)
        _shifted_values(self.K.data.astype(np.float64, copy=False), self.M.data.astype(np.float64, copy=False),
                        self.pos, float(sigma), data)
        A = sp.csr_matrix((data, self.K.indices, self.K.indptr), shape=self.K.shape)
        A.has_sorted_indices = True
        return A
