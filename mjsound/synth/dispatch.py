"""Call a numba kernel through its compiled entry point, without numba's per-call typing.

numba's dispatcher finds the compiled version of a kernel from the types of its arguments on
every call; for tuples and structured arrays it does so in Python (a structured dtype's
record type is rebuilt each time: about a tenth of a millisecond per array). The per-step and render
kernels take their state as named records, so they are called through :class:`EntryPoint`:
the types are computed only when one of the state objects is replaced. The step kernel's
state, about a hundred arrays, crosses packed into one table (:class:`PackedEntry`).
"""

from __future__ import annotations

from ..jit import compile_lock
from .packing import pack, state_typeof

__all__ = ["EntryPoint", "PackedEntry"]


class EntryPoint:
    """``fn(*state, *args)`` for a numba dispatcher ``fn``: the compiled entry point is looked
    up again only when an object of ``state`` is not the one it was looked up for. ``args``
    must keep the same numba types from call to call (arrays of the same dtype, dimensions and
    contiguity, scalars of the same kind): the callers pass freshly made arrays of fixed types
    there (a block's output, its events)."""

    __slots__ = ("fn", "_key", "_entry", "_keep")

    def __init__(self, fn):
        self.fn = fn
        self._key = None
        self._entry = None
        self._keep = None

    def __call__(self, state: tuple, *args):
        key = tuple(map(id, state))
        if key == self._key:
            return self._entry(*state, *args)
        self._key = None
        if self.fn.overloads:
            out = self.fn(*state, *args)
        else:  # (its first call here: compiled once by one of the processes starting together)
            with compile_lock(self.fn):
                out = self.fn(*state, *args)
        self._keep = state  # (keeps the ids unique while they are the key)
        self._entry = self.fn.overloads[tuple(state_typeof(a) for a in (*state, *args))].entry_point
        self._key = key  # (last: an interrupt before it leaves no stale key)
        return out



class PackedEntry:
    """``fn(table, layout, *args)`` for a numba dispatcher ``fn`` whose state crosses as one
    table (:func:`mjsound.synth.packing.pack`; ``fn`` rebuilds it with
    :func:`~mjsound.synth.packing.unpack`), called as ``entry(state, *args)`` through an
    :class:`EntryPoint`: ``state`` is packed again only when one of its objects is not the one
    packed last, and the packed objects are kept alive while their table is in use. ``args``
    as for :class:`EntryPoint`. A call unboxes the table, not every array of the state."""

    __slots__ = ("_call", "_key", "_keep", "_packed", "_entry")

    def __init__(self, fn):
        self._call = EntryPoint(fn)
        self._key = None
        self._keep = self._packed = self._entry = None

    def __call__(self, state: tuple, *args):
        if tuple(map(id, state)) == self._key:  # (the packed table is current: its entry point directly)
            return self._entry(*self._packed, *args)
        self._key = None
        self._keep = state  # (its arrays' memory is what the table describes)
        self._packed = pack(state)  # (table, layout)
        out = self._call(self._packed, *args)
        self._entry = self._call._entry
        self._key = tuple(map(id, state))  # (last: an interrupt before it leaves no stale key)
        return out
