"""Call a numba kernel through its compiled entry point, without numba's per-call typing.

numba's dispatcher finds the compiled version of a kernel from the types of its arguments on
every call; for tuples and structured arrays it does so in Python (a structured dtype's
record type is rebuilt each time: about a tenth of a millisecond per array). The per-step and render
kernels take their state as named records, so they are called through :class:`EntryPoint`:
the types are computed only when one of the state objects is replaced. The step kernel's
state, about a hundred arrays, crosses packed into one table (:class:`PackedEntry`).
"""

from __future__ import annotations

from operator import is_

from ..jit import compile_lock
from .packing import pack, state_typeof

__all__ = ["EntryPoint", "PackedEntry"]


class EntryPoint:
    """``fn(*state, *args)`` for a numba dispatcher ``fn``: the compiled entry point is looked
    up again only when an object of ``state`` is not the one it was looked up for. ``args``
    must keep the same numba types from call to call (arrays of the same dtype, dimensions and
    contiguity, scalars of the same kind): the callers pass freshly made arrays of fixed types
    there (a block's output, its events)."""

    __slots__ = ("fn", "_entry", "_keep")

    def __init__(self, fn):
        self.fn = fn
        self._entry = None
        self._keep = None  # (the state the entry point was looked up for; None: none yet)

    def __call__(self, state: tuple, *args):
        keep = self._keep
        # (the very objects of last time, compared one by one)
        if keep is not None and len(state) == len(keep) and all(map(is_, state, keep)):
            return self._entry(*state, *args)
        self._keep = None
        if self.fn.overloads:
            out = self.fn(*state, *args)
        else:  # (its first call here: compiled once by one of the processes starting together)
            with compile_lock(self.fn):
                out = self.fn(*state, *args)
        self._entry = self.fn.overloads[tuple(state_typeof(a) for a in (*state, *args))].entry_point
        self._keep = state  # (last: an interrupt before it leaves no stale state)
        return out


class PackedEntry:
    """``fn(table, layout, *args)`` for a numba dispatcher ``fn`` whose state crosses as one
    table (:func:`mjsound.synth.packing.pack`; ``fn`` rebuilds it with
    :func:`~mjsound.synth.packing.unpack`), called as ``entry(state, *args)`` through an
    :class:`EntryPoint`: ``state`` is packed again only when one of its objects is not the one
    packed last, and the packed objects are kept alive while their table is in use. ``args``
    as for :class:`EntryPoint`. A call unboxes the table, not every array of the state."""

    __slots__ = ("_call", "_keep", "_packed", "_entry")

    def __init__(self, fn):
        self._call = EntryPoint(fn)
        self._keep = None
        self._packed = self._entry = None

    def __call__(self, state: tuple, *args):
        keep = self._keep
        # (the packed table is current: its entry point directly)
        if keep is not None and len(state) == len(keep) and all(map(is_, state, keep)):
            return self._entry(*self._packed, *args)
        self._keep = None
        self._packed = pack(state)  # (table, layout)
        out = self._call(self._packed, *args)
        self._entry = self._call._entry
        self._keep = state  # (its arrays' memory is what the table describes; set last: see EntryPoint)
        return out
