"""`StreamTable`: the synthesizer's persistent sustained-contact streams (owner of their
:class:`.records.StreamState`; the kernels are in :mod:`.streams`), and the synthesizer's
methods that drive and render them (:class:`StreamMethods`)."""

from __future__ import annotations

import zlib

import numpy as np

from . import kernels
from .directivity import hear_directions
from .dispatch import EntryPoint
from .records import STREAM, STREAMS, SourceRows, StreamState
from .streams import any_due, stream_seed, streams_bank_rows, streams_gains

__all__ = ["StreamTable", "StreamMethods"]

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
        self._n = self.counts["n"]  # (a plain int64 view of the field: read on every render)
        self.state: StreamState | None = None
        #: an empty state of the same types (kernels that run before any stream exists)
        self.empty = self._make(0, 0, 1)

    @property
    def n(self) -> int:
        """Streams in use."""
        return int(self._n[0])

    def _make(self, cap, nmax, ring) -> StreamState:
        table = np.zeros(cap, STREAM)
        table["last"] = -(2**62)
        table["gupd"] = -(2**62)
        M = self.n_mics
        return StreamState(table, np.zeros((cap, M), np.int64), np.zeros((cap, M, nmax), self.dtype),
                           np.zeros((cap, M, nmax), self.dtype), np.zeros((cap, ring)), self.counts,
                           np.full((cap, M), np.nan), np.zeros((cap, M, 3, nmax)))

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
            if new.dfac.shape[3] == old.dfac.shape[3]:  # (else the new NaN delays make them again)
                new.dts[:n] = old.dts[:n]
                new.dfac[:n] = old.dfac[:n]
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
        row["rng"] = stream_seed(seed, obj, zlib.crc32(repr(key).encode()))  # (not hash(): varies by process)
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
            st.dts[:] = np.nan

    def grow_ring(self, need: int) -> None:
        """Rings of at least ``need`` samples (the next power of two)."""
        st = self.state
        self._alloc(len(st.table), st.gr.shape[2], 1 << (int(need) - 1).bit_length())

    def retire_object(self, obj: int) -> None:
        """Streams of object index ``obj`` stop (the object was removed)."""
        if self.n:
            t = self.state.table[: self.n]
            t["live"][t["obj"] == obj] = 0


class StreamMethods:
    """The stream methods of :class:`mjsound.synth.Synthesizer` (a mixin: it uses the
    synthesizer's ``_streams`` table, constants, bank and layout)."""

    def _streams_clear(self) -> None:
        """Forget all sustained-contact streams (their ringing modes keep ringing)."""
        st = getattr(self, "_streams", None)
        if st is not None and st.n_mics == self.n_channels:
            st.clear()  # (in place: the kernels' compiled entry points stay valid)
        else:
            self._streams = StreamTable(self.n_channels, self.dtype)
        if not hasattr(self, "_render_all_call"):
            # numba kernels called through their compiled entry points (no per-call typing)
            self._render_all_call = EntryPoint(kernels.render_all)
            self._render_streams_call = EntryPoint(kernels.render_streams)
            self._hear_call = EntryPoint(hear_directions)
        #: changes whenever the synthesizer forgets its streams (stream indices held elsewhere
        #: are stale then)
        self.streams_epoch = getattr(self, "streams_epoch", 0) + 1
        #: optional ``on_regain()`` called once before the gains of due streams are computed
        #: (a driver updates the poses and the microphones there), unless ``poses_current``
        #: says the driver has just done so
        self.on_regain = getattr(self, "on_regain", None)
        self.poses_current = False
        #: render blocks without forcing sources in one numba call (same sound to float32
        #: rounding: 1.5e-6 of the peak on Ant-v5; False: one call per stage)
        self.fused_streams = True
        self._zero = self.dtype.type(0)  # (the bank dtype's 0: fixes the kernels' accumulator type)

    def _streams_regain(self, n) -> None:
        """Gains of the streams marked due (from their last point and normal, the objects'
        poses and the microphones after ``on_regain``), then make sure the ring holds a block
        plus the delays."""
        st = self._streams.state
        if any_due(st):
            if self.on_regain is not None and not self.poses_current:
                self.on_regain()
            dmax = streams_gains(self.kernel_state())
            need = int(dmax) + n + 1
            if need > st.ring.shape[1]:
                self._streams.grow_ring(need)

    def _render_streams(self, start, n, out) -> bool:
        """Render a block without forcing sources in one numba call
        (:func:`.kernels.render_streams`: due gains, due events, stream rows,
        :func:`.kernels.render_all`); the same samples as taking the events, then
        :meth:`_streams_bank_rows`, then ``render_all``. Returns whether every sample is finite."""
        may_regain = self.on_regain is None or self.poses_current
        zero = self._zero
        while True:
            code = self._render_streams_call((self.kernel_state(), self._bank, self._layout), start, n, may_regain,
                                             out, zero)
            if code == kernels.RENDERED or code == kernels.RENDERED_NONFINITE:
                return code == kernels.RENDERED
            if code == kernels.REGAIN_FIRST:
                self.on_regain()
                may_regain = True
            else:  # the ring must hold the block plus the delays
                self._streams.grow_ring(code)

    def _streams_bank_rows(self, start, end) -> SourceRows:
        self._streams_regain(end - start)
        return SourceRows(*streams_bank_rows(self._streams.state, self._layout, start, end, self.dtype.type(0)))

    def stream(self, key, name) -> int:
        """Index of the persistent sustained-contact stream ``key`` (any hashable, e.g.
        ``(geom1, geom2, struck geom)``) on object ``name``, created on first use (a driver
        then drives it in numba: :func:`.streams.stream_drive`)."""
        ob = self._get(name)
        nmax = max([len(o.keep) for o in self._objects.values()], default=0)
        return self._streams.index(key, ob.index, nmax, self.seed, self.samples_rendered)

    def grow_stream_ring(self, need: int) -> None:
        """Stream rings of at least ``need`` samples."""
        self._streams.grow_ring(need)

    def stream_tables(self):
        """``(state, consts)``: the streams' state table and the synthesizer's constants record,
        what a kernel that writes into streams takes (the actuators'
        :func:`mjsound.synth.drive_tones.streams_write`)."""
        return self._streams.state, self._consts

    @property
    def n_streams(self) -> int:
        """Persistent streams in use."""
        return self._streams.n
