"""A kernel's state (a nested tuple of arrays) crossing into numba as one table.

numba unboxes every array argument on every call: it checks the object, allocates a memory
record that holds a reference to it and releases both when the call returns. The per-step
kernels take their state as named records, :class:`typing.NamedTuple` s of arrays, about a
hundred arrays in all, and that unboxing was most of the fixed cost of a call. Here the state
is described once, when an owner replaces one of its records, by a table with one row per
leaf (:data:`PACKED`: the array's address, shape and strides, or an integer's value), and the
kernel's entry rebuilds the same named tuples from it (:func:`unpack`), as arrays over the
same memory, without a memory record: reading and writing them inside the kernel is
reading and writing the owners' arrays, and numba's reference counting skips them.

The table is only valid while the arrays it describes live and keep their memory:
:class:`mjsound.synth.dispatch.PackedEntry` keeps the state objects alive with their table
and packs again whenever one of them is replaced (an owner grows a buffer by making a new
record; no array of the package is resized in place).

Example
-------
>>> import numpy as np, numba
>>> from typing import NamedTuple
>>> class Pair(NamedTuple):
...     a: np.ndarray
...     n: int
>>> state = (Pair(np.arange(3.0), 2), np.zeros(2))
>>> table, layout = pack(state)
>>> @numba.njit
... def total(table, layout):
...     pair, out = unpack(table, layout)
...     out[0] = pair.a[: pair.n].sum()
>>> total(table, layout); float(state[1][0])
1.0
"""

from __future__ import annotations

import numpy as np
from numba import from_dtype, typeof, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

__all__ = ["PACKED", "MAX_NDIM", "pack", "unpack", "state_typeof"]

#: Most dimensions of a packed array.
MAX_NDIM = 4

#: One leaf of a packed state: an array's data address, dimensions, shape and strides [bytes],
#: or (``ndim`` -1) an integer's ``value``.
PACKED = np.dtype([("addr", np.int64), ("ndim", np.int64), ("value", np.int64), ("shape", np.int64, (MAX_NDIM,)),
                   ("strides", np.int64, (MAX_NDIM,))])


def _leaves(x, path: str, out: list) -> None:
    if isinstance(x, tuple):
        names = getattr(x, "_fields", None) or [str(i) for i in range(len(x))]
        for name, v in zip(names, x):
            _leaves(v, f"{path}.{name}", out)
    else:
        out.append((path, x))


#: numba's type of an array, by what :func:`numba.typeof` reads of it (its dtype, dimensions,
#: contiguity and writeability; a structured dtype's record type took about 0.1 ms to build)
_ARRAY_TYPES: dict = {}
#: numba's type of a tuple, by its class and its elements' types (numba interns types, so the
#: same element types are the same objects: their ids, kept alive by the tuple type, are the key)
_TUPLE_TYPES: dict = {}


def state_typeof(x) -> types.Type:
    """``numba.typeof(x)`` for a state (nested tuples and NamedTuples of arrays and integers),
    with the array and tuple types memoised: the same type numba computes, in microseconds instead of
    the milliseconds typing a hundred arrays afresh takes (each time an owner replaces a
    record, :class:`mjsound.synth.dispatch.PackedEntry` packs and types the state again)."""
    if type(x) is np.ndarray:
        dt, fl = x.dtype, x.flags
        key = (dt, dt.isalignedstruct, x.ndim, fl.c_contiguous, fl.f_contiguous, fl.writeable)
        t = _ARRAY_TYPES.get(key)
        if t is None:
            t = _ARRAY_TYPES[key] = typeof(x)
        return t
    if isinstance(x, tuple):
        elems = [state_typeof(v) for v in x]
        key = (type(x), *map(id, elems))
        t = _TUPLE_TYPES.get(key)
        if t is None:
            t = _TUPLE_TYPES[key] = types.BaseTuple.from_types(elems, type(x))
        return t
    return typeof(x)


def pack(state: tuple) -> tuple[np.ndarray, types.Type]:
    """The table of ``state`` (a tuple, nested tuples and NamedTuples of arrays and integers)
    and its numba type, for :func:`unpack`.

    Returns
    -------
    table : (leaves,) PACKED
        Depth-first, in field order.
    layout : numba type
        ``numba.typeof(state)`` (:func:`state_typeof`): passed to the kernel, it tells
        :func:`unpack` what to build.
    """
    leaves = []
    _leaves(state, "state", leaves)
    n = len(leaves)
    addr, ndim, value = [0] * n, [0] * n, [0] * n
    shape = np.zeros((n, MAX_NDIM), np.int64)
    strides = np.zeros((n, MAX_NDIM), np.int64)
    for i, (path, a) in enumerate(leaves):
        if isinstance(a, np.ndarray):
            if a.ndim > MAX_NDIM:
                raise ValueError(f"pack: {path} has {a.ndim} dimensions; at most {MAX_NDIM} can be packed")
            addr[i], ndim[i] = a.ctypes.data, a.ndim
            shape[i, : a.ndim] = a.shape
            strides[i, : a.ndim] = a.strides
        elif isinstance(a, (int, np.integer)) and not isinstance(a, (bool, np.bool_)):
            ndim[i], value[i] = -1, int(a)
        else:
            raise TypeError(f"pack: {path} is a {type(a).__name__}; a packed state holds arrays and integers only")
    table = np.zeros(n, PACKED)
    table["addr"], table["ndim"], table["value"] = addr, ndim, value
    table["shape"], table["strides"] = shape, strides
    return table, state_typeof(state)


_OFFSET = {name: PACKED.fields[name][1] // 8 for name in ("addr", "value", "shape", "strides")}
_PACKED_TYPE = from_dtype(PACKED)
_ROW = PACKED.itemsize // 8


@intrinsic
def unpack(typingctx, table, layout):
    """``unpack(table, layout)`` in a kernel: the state :func:`pack` described, rebuilt as
    the nested tuples of ``layout`` whose arrays view the packed arrays' memory (no memory
    record: numba does not count references to them)."""
    if not (isinstance(table, types.Array) and table.ndim == 1 and table.dtype == _PACKED_TYPE
            and isinstance(layout, types.TypeRef)):
        return None
    ty = layout.instance_type
    n_leaves = sum(1 for _ in _leaf_types(ty))

    def codegen(context, builder, sig, args):
        tab = make_array(sig.args[0])(context, builder, value=args[0])
        rows = builder.extract_value(tab.shape, 0)
        with cgutils.if_unlikely(builder, builder.icmp_signed("!=", rows, context.get_constant(types.intp, n_leaves))):
            context.call_conv.return_user_exc(builder, ValueError, (
                f"unpack: the table has another number of rows than the {n_leaves} leaves of its layout",))
        # (the table read as int64 words: row r's field f at r * _ROW + _OFFSET[f])
        words = builder.bitcast(tab.data, context.get_value_type(types.int64).as_pointer())
        intp = context.get_value_type(types.intp)
        row = [0]

        def word(r, field, i=0):
            return builder.load(builder.gep(words, [context.get_constant(types.intp, r * _ROW + _OFFSET[field] + i)]))

        def build(t):
            if isinstance(t, types.BaseTuple):
                return context.make_tuple(builder, t, [build(e) for e in t.types])
            r = row[0]
            row[0] += 1
            if isinstance(t, types.Array):
                ary = make_array(t)(context, builder)
                data_t = context.get_data_type(t.dtype)
                populate_array(ary, data=builder.inttoptr(word(r, "addr"), data_t.as_pointer()),
                               shape=cgutils.pack_array(builder, [word(r, "shape", i) for i in range(t.ndim)], ty=intp),
                               strides=cgutils.pack_array(builder, [word(r, "strides", i) for i in range(t.ndim)], ty=intp),
                               itemsize=context.get_constant(types.intp, context.get_abi_sizeof(data_t)), meminfo=None)
                return ary._getvalue()
            return context.cast(builder, word(r, "value"), types.int64, t)  # (an Integer: typing checked)

        return build(ty)

    for t in _leaf_types(ty):
        if not isinstance(t, (types.Array, types.Integer)) or (isinstance(t, types.Array) and t.ndim > MAX_NDIM):
            return None
    return ty(table, layout), codegen


def _leaf_types(t):
    if isinstance(t, types.BaseTuple):
        for e in t.types:
            yield from _leaf_types(e)
    else:
        yield t
