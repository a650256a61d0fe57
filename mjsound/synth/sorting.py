"""A stable argsort in plain numba (numpy's ``argsort(kind="mergesort")`` costs seconds of
compilation per process with a cold cache; any stable sort gives the same permutation)."""

from __future__ import annotations

import numpy as np

from ..jit import njit_inner

__all__ = ["stable_argsort", "stable_argsort_into"]


@njit_inner(cache=True)
def stable_argsort(keys):
    """Indices that sort ``keys`` (n,) int64 ascending, equal keys in their original order
    (bottom-up merge sort, O(n log n))."""
    n = keys.shape[0]
    return stable_argsort_into(keys, np.empty(n, np.int64), np.empty(n, np.int64))


@njit_inner(cache=True)
def stable_argsort_into(keys, a, b):
    """:func:`stable_argsort` of ``keys`` (n,) in the working arrays ``a`` and ``b`` (each at
    least n long, int64): returns the first n entries of whichever holds the result."""
    n = keys.shape[0]
    a = a[:n]
    b = b[:n]
    for i in range(n):
        a[i] = i
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if keys[a[j]] < keys[a[i]]:
                    b[k] = a[j]
                    j += 1
                else:
                    b[k] = a[i]
                    i += 1
                k += 1
            while i < mid:
                b[k] = a[i]
                i += 1
                k += 1
            while j < hi:
                b[k] = a[j]
                j += 1
                k += 1
        a, b = b, a
        width *= 2
    return a
