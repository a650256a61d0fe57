"""`StreamTable`: the synthesizer's persistent sustained-contact streams (owner of their
:class:`.records.StreamState`; the kernels are in :mod:`.streams`)."""

from __future__ import annotations

import zlib

import numpy as np

from .records import STREAM, STREAMS, StreamState
from .streams import stream_seed

__all__ = ["StreamTable"]

#: Ring buffer length of a stream [samples] (power of two; grows for long blocks/delays).
RING = 4096
#: Ring samples kept free for a stream's delay growing between gain updates [samples].
RING_SLACK = 1024


class StreamTable:
    """Streams keyed by any hashable (e.g. ``(geom1, geom2, struck geom)``), created on first
    use; :attr:`state` is None until the first one exists.

    Parameters
    ----------
    n_mics : int
        Microphones (columns of the delays and gains).
    dtype : numpy dtype
        Gain precision (the bank's state dtype).
    """

    def __init__(self, n_mics: int, dtype):
        self.n_mics = int(n_mics)
        self.dtype = np.dtype(dtype)
        self.keys: dict = {}
        self.counts = np.zeros(1, STREAMS)
        self.state: StreamState | None = None
        #: an empty state of the same types (kernels that run before any stream exists)
        self.empty = self._make(0, 0, 1)

    @property
    def n(self) -> int:
        """Streams in use."""
        return int(self.counts[0]["n"])

    def _make(self, cap, nmax, ring) -> StreamState:
        table = np.zeros(cap, STREAM)
        table["last"] = -(2**62)
        table["gupd"] = -(2**62)
        M = self.n_mics
        return StreamState(table, np.zeros((cap, M), np.int64), np.zeros((cap, M, nmax), self.dtype),
                           np.zeros((cap, M, nmax), self.dtype), np.zeros((cap, ring)), self.counts)

    def _alloc(self, cap, nmax, ring) -> None:
        """Room for ``cap`` streams of up to ``nmax`` modes with rings of ``ring`` samples
        (every existing sample keeps its slot ``k & (ring - 1)``)."""
        old = self.state
        new = self._make(cap, nmax, ring)
        n = self.n
        if old is not None and n:
            new.table[:n] = old.table[:n]
            new.D[:n] = old.D[:n]
            new.gr[:n, :, : old.gr.shape[2]] = old.gr[:n]
            new.gi[:n, :, : old.gi.shape[2]] = old.gi[:n]
            ro = old.ring.shape[1]
            for j in range(n):
                g = int(old.table[j]["gen"])
                ks = np.arange(max(g - ro, 0), g)
                new.ring[j, ks & (ring - 1)] = old.ring[j, ks & (ro - 1)]
        self.state = new

    def index(self, key, obj: int, nmax: int, seed: int, rendered: int) -> int:
        """Index of stream ``key`` on object index ``obj``, created on first use (seeded from the
        synthesizer ``seed``, the object and the key, so the noise does not depend on the order
        streams appear); ``nmax``: the widest object's modes, ``rendered``: samples rendered."""
        j = self.keys.get(key)
        if j is not None:
            return j
        st = self.state
        n = self.n
        if st is None or n == len(st.table) or st.gr.shape[2] < nmax:
            cap = 8 if st is None else max(len(st.table), 4) * (2 if n == len(st.table) else 1)
            self._alloc(cap, nmax, RING if st is None else st.ring.shape[1])
            st = self.state
        j = n
        self.counts[0]["n"] = n + 1
        self.keys[key] = j
        row = st.table[j]
        row["live"] = 1
        row["obj"] = obj
        seed = stream_seed(seed, obj, zlib.crc32(repr(key).encode()))  # not hash(): varies by process
        row["rng"] = np.array([seed], np.uint64).view(np.int64)[0]
        row["gen"] = rendered
        return j

    def clear(self) -> None:
        """Forget every stream, keeping the arrays (as new: zero state and rings)."""
        self.keys = {}
        self.counts[:] = 0
        st = self.state
        if st is not None:
            st.table[:] = 0
            st.table["last"] = -(2**62)
            st.table["gupd"] = -(2**62)
            st.D[:] = 0
            st.gr[:] = 0
            st.gi[:] = 0
            st.ring[:] = 0

    def grow_ring(self, need: int) -> None:
        """Rings of at least ``need`` samples (the next power of two)."""
        st = self.state
        self._alloc(len(st.table), st.gr.shape[2], 1 << (int(need) - 1).bit_length())

    def retire_object(self, obj: int) -> None:
        """Streams of object index ``obj`` stop (the object was removed)."""
        if self.n:
            t = self.state.table[: self.n]
            t["live"][t["obj"] == obj] = 0
