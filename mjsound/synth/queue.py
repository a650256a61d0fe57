"""Pending excitation events of the synthesizer, in flat arrays.

An event sets (kind 0: adds ``a``; kind 1: marks a forcing source's modes active) the state of
one object's modes at one microphone at sample ``n``. Events wait here until the render whose
block holds their sample; :meth:`EventQueue.take` then hands them over, already placed in the
microphone banks of :func:`.kernels.render_all` and sorted by (microphone, sample), in one numba
call. Rows keep the object index (not a voice id), so a rebuilt voice layout or a removed
object needs no re-keying: rows whose object is gone (``vbase[obj] < 0``) are dropped at take.
Amplitudes live in one pool; row ``i`` owns ``pool[off[i] : off[i] + width[i]]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["EventQueue"]

NONE = 2**62  # "no pending event" sample


class EventQueue:
    """Growable flat store of pending events (see the module docstring).

    Example
    -------
    >>> q = EventQueue()
    >>> q.push(0, np.array([0]), np.array([5]), np.zeros(1, np.int8), np.ones((1, 3), complex))
    >>> q.next_sample
    5
    """

    def __init__(self, capacity: int = 64):
        self.count = 0
        self.pool_used = 0
        self.next_sample = NONE
        self._alloc(int(capacity), 16 * int(capacity))

    def _alloc(self, rows: int, pool: int) -> None:
        """Room for ``rows`` events and ``pool`` amplitudes (the queued ones kept)."""
        k, u = self.count, self.pool_used
        I, kind = np.zeros((5, rows), np.int64), np.zeros(rows, np.int8)  # I: object, mic, sample, offset, width
        re, im = np.zeros(pool), np.zeros(pool)
        if k:
            I[:, :k] = self.I[:, :k]
            kind[:k] = self.kind[:k]
            re[:u] = self.re[:u]
            im[:u] = self.im[:u]
        self.I, self.kind, self.re, self.im = I, kind, re, im

    def __len__(self) -> int:
        return self.count

    def clear(self) -> None:
        self.count = 0
        self.pool_used = 0
        self.next_sample = NONE

    def reserve(self, rows: int, pool: int) -> None:
        """Make room for ``rows`` more events with ``pool`` more amplitudes (numba kernels
        then append in place: :func:`.kernels.impacts_to_queue`)."""
        if self.count + rows > self.I.shape[1] or self.pool_used + pool > self.re.shape[0]:
            self._alloc(max(2 * self.I.shape[1], self.count + rows), max(2 * self.re.shape[0], 2 * (self.pool_used + pool)))

    def push(self, obj: int, mic: np.ndarray, sample: np.ndarray, kind: np.ndarray, amp: np.ndarray) -> None:
        """Queue ``k`` events of object index ``obj``: microphones ``mic`` (k,), samples
        ``sample`` (k,), kinds (k,) int8 and complex amplitudes ``amp`` (k, modes)."""
        k, w = amp.shape
        if k == 0:
            return
        self.reserve(k, k * w)
        r0, u0 = self.count, self.pool_used
        I = self.I
        I[0, r0:r0 + k] = obj
        I[1, r0:r0 + k] = mic
        I[2, r0:r0 + k] = sample
        I[3, r0:r0 + k] = u0 + w * np.arange(k)
        I[4, r0:r0 + k] = w
        self.kind[r0:r0 + k] = kind
        self.re[u0:u0 + k * w] = amp.real.ravel()
        self.im[u0:u0 + k * w] = amp.imag.ravel()
        self.count += k
        self.pool_used += k * w
        self.next_sample = min(self.next_sample, int(sample.min()))

    def keep(self, mask: np.ndarray) -> None:
        """Keep only the rows where ``mask`` (count,) is true (pool compacted)."""
        self.count, self.pool_used, self.next_sample = _compact(self.I, self.kind, self.re, self.im, self.count,
                                                                 np.ascontiguousarray(mask, np.bool_))

    def drop_object(self, obj: int) -> None:
        if self.count:
            self.keep(self.I[0, : self.count] != obj)

    def drop_mics(self, n_mics: int) -> None:
        """Forget events of microphones ``>= n_mics``."""
        if self.count:
            self.keep(self.I[1, : self.count] < n_mics)

    def take(self, end: int, vbase: np.ndarray, v_rel: np.ndarray, v_len: np.ndarray, n_mics: int, width: int):
        """Remove the events before sample ``end`` and return them for ``render_all``:
        ``(ptr (n_mics + 1,), sample (k,), kind (k,), re (k, width), im (k, width))``, rows sorted
        by (microphone, sample), ties in queue order; row ``i``'s amplitudes sit at columns
        ``v_rel[voice] ...`` of its microphone bank (voice = ``vbase[obj] + mic``)."""
        out = _take(self.I, self.kind, self.re, self.im, self.count, end, vbase, v_rel, v_len, n_mics, width)
        ptr, na, kd, re, im, self.count, self.pool_used, self.next_sample = out
        return ptr, na, kd, re, im


@njit(cache=True)
def _compact(I, kind, re, im, count, keep):
    """Move the kept rows (and their pool slices) to the front, in order. Returns
    ``(count, pool_used, next_sample)``."""
    k = 0
    u = 0
    nxt = NONE
    for i in range(count):
        if not keep[i]:
            continue
        o, w = I[3, i], I[4, i]
        for j in range(w):  # o >= u: moving down never overwrites a later row's values
            re[u + j] = re[o + j]
            im[u + j] = im[o + j]
        for c in range(3):
            I[c, k] = I[c, i]
        I[3, k] = u
        I[4, k] = w
        kind[k] = kind[i]
        if I[2, k] < nxt:
            nxt = I[2, k]
        u += w
        k += 1
    return k, u, nxt


@njit(cache=True)
def _take(I, kind, re, im, count, end, vbase, v_rel, v_len, n_mics, width):
    due = np.zeros(count, np.bool_)
    nd = 0
    lo = NONE
    for i in range(count):
        if I[2, i] < end:
            due[i] = True
            if vbase[I[0, i]] >= 0 and I[1, i] < n_mics:
                nd += 1
                if I[2, i] < lo:
                    lo = I[2, i]
    rows = np.empty(nd, np.int64)
    key = np.empty(nd, np.int64)
    span = 0
    j = 0
    for i in range(count):
        if due[i] and vbase[I[0, i]] >= 0 and I[1, i] < n_mics:
            rows[j] = i
            j += 1
            if I[2, i] - lo + 1 > span:
                span = I[2, i] - lo + 1
    for j in range(nd):
        i = rows[j]
        key[j] = I[1, i] * span + (I[2, i] - lo)
    order = np.argsort(key, kind="mergesort")  # stable: ties keep queue order
    ptr = np.zeros(n_mics + 1, np.int64)
    na = np.empty(nd, np.int64)
    kd = np.empty(nd, np.int8)
    out_re = np.zeros((nd, width))
    out_im = np.zeros((nd, width))
    for q in range(nd):
        i = rows[order[q]]
        m = I[1, i]
        ptr[m + 1] += 1
        na[q] = I[2, i]
        kd[q] = kind[i]
        v = vbase[I[0, i]] + m
        c0 = v_rel[v]
        w = min(I[4, i], v_len[v])
        o = I[3, i]
        for c in range(w):
            out_re[q, c0 + c] = re[o + c]
            out_im[q, c0 + c] = im[o + c]
    for m in range(n_mics):
        ptr[m + 1] += ptr[m]
    count, used, nxt = _compact(I, kind, re, im, count, ~due)
    return ptr, na, kd, out_re, out_im, count, used, nxt
