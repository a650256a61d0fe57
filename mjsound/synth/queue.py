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

from ..jit import njit
from .dispatch import EntryPoint
from .records import EVENT, QUEUE, EventRows, QueueState
from .sorting import stable_argsort

__all__ = ["EventQueue", "take_due"]

NONE = 2**62  # "no pending event" sample


class EventQueue:
    """Growable flat store of pending events (see the module docstring): a table of
    :data:`.records.EVENT` rows, an amplitude pool and the :data:`.records.QUEUE` counters
    (:attr:`state`: what numba kernels append to).

    Example
    -------
    >>> q = EventQueue()
    >>> q.push(0, np.array([0]), np.array([5]), np.zeros(1, np.int8), np.ones((1, 3), complex))
    >>> q.next_sample
    5
    """

    def __init__(self, capacity: int = 64):
        self._take = None
        self.counts = np.zeros(1, QUEUE)
        self.counts[0]["next_sample"] = NONE
        # plain int64 views of the fields (read on every render: a structured scalar costs more)
        self._count, self._next = self.counts["count"], self.counts["next_sample"]
        self.state = None
        self._alloc(int(capacity), 16 * int(capacity))

    @property
    def count(self) -> int:
        """Events waiting."""
        return int(self._count[0])

    @property
    def pool_used(self) -> int:
        """Pool entries in use."""
        return int(self.counts[0]["pool_used"])

    @property
    def next_sample(self) -> int:
        """Earliest pending sample (:data:`NONE` when empty)."""
        return int(self._next[0])

    def _alloc(self, rows: int, pool: int) -> None:
        """Room for ``rows`` events and ``pool`` amplitudes (the queued ones kept)."""
        k, u = self.count, self.pool_used
        events = np.zeros(rows, EVENT)
        re, im = np.zeros(pool), np.zeros(pool)
        if k:
            events[:k] = self.events[:k]
            re[:u] = self.re[:u]
            im[:u] = self.im[:u]
        self.events, self.re, self.im = events, re, im
        self.state = QueueState(events, re, im, self.counts)

    def __len__(self) -> int:
        return self.count

    def clear(self) -> None:
        self._set(0, 0, NONE)

    def _set(self, count, used, nxt) -> None:
        c = self.counts[0]
        c["count"], c["pool_used"], c["next_sample"] = count, used, nxt

    def reserve(self, rows: int, pool: int) -> None:
        """Make room for ``rows`` more events with ``pool`` more amplitudes (numba kernels
        then append in place: :func:`.kernels.impacts_to_queue`)."""
        if self.count + rows > len(self.events) or self.pool_used + pool > self.re.shape[0]:
            self._alloc(max(2 * len(self.events), self.count + rows), max(2 * self.re.shape[0], 2 * (self.pool_used + pool)))

    def push(self, obj: int, mic: np.ndarray, sample: np.ndarray, kind: np.ndarray, amp: np.ndarray) -> None:
        """Queue ``k`` events of object index ``obj``: microphones ``mic`` (k,), samples
        ``sample`` (k,), kinds (k,) int8 and complex amplitudes ``amp`` (k, modes)."""
        k, w = amp.shape
        if k == 0:
            return
        self.reserve(k, k * w)
        r0, u0 = self.count, self.pool_used
        ev = self.events[r0:r0 + k]
        ev["obj"] = obj
        ev["mic"] = mic
        ev["sample"] = sample
        ev["offset"] = u0 + w * np.arange(k)
        ev["width"] = w
        ev["kind"] = kind
        self.re[u0:u0 + k * w] = amp.real.ravel()
        self.im[u0:u0 + k * w] = amp.imag.ravel()
        self._set(r0 + k, u0 + k * w, min(self.next_sample, int(sample.min())))

    def keep(self, mask: np.ndarray) -> None:
        """Keep only the rows where ``mask`` (count,) is true (pool compacted)."""
        _compact(self.state, np.ascontiguousarray(mask, np.bool_))

    def drop_object(self, obj: int) -> None:
        if self.count:
            self.keep(self.events["obj"][: self.count] != obj)

    def drop_mics(self, n_mics: int) -> None:
        """Forget events of microphones ``>= n_mics``."""
        if self.count:
            self.keep(self.events["mic"][: self.count] < n_mics)

    def take(self, end: int, vbase: np.ndarray, v_rel: np.ndarray, v_len: np.ndarray, n_mics: int,
             width: int) -> EventRows:
        """Remove the events before sample ``end`` and return them for ``render_all``:
        :class:`.records.EventRows` ``(ptr (n_mics + 1,), sample (k,), kind (k,), re (k, width),
        im (k, width))``, rows sorted by (microphone, sample), ties in queue order; row ``i``'s
        amplitudes sit at columns ``v_rel[voice] ...`` of its microphone bank (voice =
        ``vbase[obj] + mic``)."""
        # (a plain tuple crosses back from numba: boxing a NamedTuple runs Python code, where a
        # pending Ctrl-C made numba crash)
        if self._take is None:
            self._take = EntryPoint(take_due)  # (no per-call typing of the structured arrays)
        return EventRows(*self._take((self.state,), int(end), vbase, v_rel, v_len, int(n_mics), int(width)))


@njit(cache=True)
def _compact(q, keep):
    """Move the kept rows (and their pool slices) to the front, in order; updates the
    counters."""
    ev, re, im = q.events, q.re, q.im
    count = q.counts[0].count
    k = 0
    u = 0
    nxt = NONE
    for i in range(count):
        if not keep[i]:
            continue
        o, w = ev[i].offset, ev[i].width
        for j in range(w):  # o >= u: moving down never overwrites a later row's values
            re[u + j] = re[o + j]
            im[u + j] = im[o + j]
        ev[k].obj = ev[i].obj
        ev[k].mic = ev[i].mic
        ev[k].sample = ev[i].sample
        ev[k].offset = u
        ev[k].width = w
        ev[k].kind = ev[i].kind
        if ev[k].sample < nxt:
            nxt = ev[k].sample
        u += w
        k += 1
    c = q.counts[0]
    c.count = k
    c.pool_used = u
    c.next_sample = nxt


@njit(cache=True)
def take_due(q, end, vbase, v_rel, v_len, n_mics, width):
    """:meth:`EventQueue.take` in numba: removes the events of queue ``q``
    (:class:`.records.QueueState`) before sample ``end`` and returns the fields of
    :class:`.records.EventRows` as a plain tuple."""
    ev, re, im = q.events, q.re, q.im
    count = q.counts[0].count
    due = np.zeros(count, np.bool_)
    nd = 0
    lo = NONE
    for i in range(count):
        if ev[i].sample < end:
            due[i] = True
            if vbase[ev[i].obj] >= 0 and ev[i].mic < n_mics:
                nd += 1
                if ev[i].sample < lo:
                    lo = ev[i].sample
    rows = np.empty(nd, np.int64)
    key = np.empty(nd, np.int64)
    span = 0
    j = 0
    for i in range(count):
        if due[i] and vbase[ev[i].obj] >= 0 and ev[i].mic < n_mics:
            rows[j] = i
            j += 1
            if ev[i].sample - lo + 1 > span:
                span = ev[i].sample - lo + 1
    for j in range(nd):
        i = rows[j]
        key[j] = ev[i].mic * span + (ev[i].sample - lo)
    order = stable_argsort(key)  # stable: ties keep queue order
    ptr = np.zeros(n_mics + 1, np.int64)
    na = np.empty(nd, np.int64)
    kd = np.empty(nd, np.int8)
    out_re = np.zeros((nd, width))
    out_im = np.zeros((nd, width))
    for p in range(nd):
        i = rows[order[p]]
        m = ev[i].mic
        ptr[m + 1] += 1
        na[p] = ev[i].sample
        kd[p] = ev[i].kind
        v = vbase[ev[i].obj] + m
        c0 = v_rel[v]
        w = min(ev[i].width, v_len[v])
        o = ev[i].offset
        for c in range(w):
            out_re[p, c0 + c] = re[o + c]
            out_im[p, c0 + c] = im[o + c]
    for m in range(n_mics):
        ptr[m + 1] += ptr[m]
    _compact(q, ~due)
    return ptr, na, kd, out_re, out_im  # (a plain tuple: see take)
