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

    __slots__ = ("fn", "entry", "_keep")

    def __init__(self, fn):
        self.fn = fn
        self.entry = None  #: the compiled entry point for the state last called with
        self._keep = None  # (the state the entry point was looked up for; None: none yet)

    def __call__(self, state: tuple, *args):
        keep = self._keep
        # (the very objects of last time, compared one by one)
        if keep is not None and len(state) == len(keep) and all(map(is_, state, keep)):
            return self.entry(*state, *args)
        self._keep = None
        self.entry = compiled_entry(self.fn, (*state, *args))
        out = self.entry(*state, *args)
        self._keep = state  # (last: an interrupt before it leaves no stale state)
        return out


def compiled_entry(fn, args: tuple):
    """The compiled entry point of numba dispatcher ``fn`` for the types of ``args``
    (:func:`mjsound.synth.packing.state_typeof`), compiled or loaded from numba's cache the
    first time (under the kernel's lock: one of the processes starting together compiles it)."""
    key = tuple(state_typeof(a) for a in args)
    found = fn.overloads.get(key)
    if found is None:
        with compile_lock(fn):
            fn.compile(key)
        found = fn.overloads[key]
    return found.entry_point


class PackedEntry:
    """``fn(table, layout, *args)`` for a numba dispatcher ``fn`` whose state crosses as one
    table (:func:`mjsound.synth.packing.pack`; ``fn`` rebuilds it with
    :func:`~mjsound.synth.packing.unpack`), called as ``entry(state, *args)``: ``state`` is
    packed again only when one of its objects is not the one packed last (:meth:`bind`), and
    the packed objects are kept alive while their table is in use. ``args`` as for
    :class:`EntryPoint`. A call unboxes the table, not every array of the state.

    A caller on a hot path may do what :meth:`__call__` does itself (compare the state with
    :attr:`state`, :meth:`bind` when it differs, call :attr:`entry` on :attr:`packed`), saving
    a Python frame (:meth:`mjsound.sim.driver.StepDriver.substeps`)."""

    __slots__ = ("fn", "state", "packed", "entry")

    def __init__(self, fn):
        self.fn = fn
        self.state = None  #: the state :attr:`packed` describes (None: nothing packed yet)
        self.packed = None  #: ``(table, layout)`` of :attr:`state`
        self.entry = None  #: the compiled entry point for :attr:`packed` and the args' types

    def bind(self, state: tuple, *args) -> None:
        """Pack ``state`` and find the compiled entry point for it and ``args``' types."""
        self.state = None
        packed = pack(state)
        self.entry = compiled_entry(self.fn, (*packed, *args))
        self.packed = packed
        self.state = state  # (its arrays' memory is what the table describes; set last: see EntryPoint)

    def __call__(self, state: tuple, *args):
        keep = self.state
        if keep is None or len(state) != len(keep) or not all(map(is_, state, keep)):
            self.bind(state, *args)
        return self.entry(*self.packed, *args)
