"""A state packed into one table (mjsound.synth.packing) is the same state inside a kernel."""

from typing import NamedTuple

import numba
import numpy as np
import pytest

from mjsound.synth.dispatch import PackedEntry
from mjsound.synth.packing import MAX_NDIM, pack, state_typeof, unpack

REC = np.dtype([("n", np.int64), ("x", np.float64), ("v", np.float64, (3,))])


class Inner(NamedTuple):
    rec: np.ndarray  # (1,) REC
    grid: np.ndarray  # (2, 3) float32


class Outer(NamedTuple):
    inner: Inner
    flags: np.ndarray  # bool
    width: int


@numba.njit
def _touch(table, layout, scale):
    """Read every leaf by name and write through the arrays: returns what a plain function of
    the same state returns."""
    outer, view = unpack(table, layout)
    r = outer.inner.rec[0]
    r.n += outer.width
    r.x = r.v[0] + r.v[1] * r.v[2]
    outer.inner.grid[1, 2] = scale * outer.inner.grid.sum()
    s = 0.0
    for i in range(view.shape[0]):
        s += view[i]
    view[0] = -1.0
    return s + np.sum(outer.flags)


def _touch_plain(state, scale):
    outer, view = state
    r = outer.inner.rec[0]
    r["n"] += outer.width
    r["x"] = r["v"][0] + r["v"][1] * r["v"][2]
    outer.inner.grid[1, 2] = scale * outer.inner.grid.sum()
    s = float(view.sum())
    view[0] = -1.0
    return s + float(outer.flags.sum())


def _state():
    rec = np.zeros(1, REC)
    rec[0]["n"], rec[0]["v"] = 5, (1.0, 2.0, 3.0)
    grid = np.arange(6, dtype=np.float32).reshape(2, 3)
    base = np.arange(10.0)
    return Outer(Inner(rec, grid), np.array([True, False, True]), 7), base[1::3]  # (a strided view)


def test_unpack_rebuilds_the_named_tuples_over_the_same_memory():
    """Fields, shapes, strides (a non-contiguous view), record fields and an integer leaf come
    back by name; writes in the kernel land in the packed arrays, as a plain function's do."""
    got, want = _state(), _state()
    table, layout = pack(got)
    assert len(table) == 5 and layout == numba.typeof(got)
    assert _touch(table, layout, 0.5) == _touch_plain(want, 0.5)
    assert got[0].inner.rec.tobytes() == want[0].inner.rec.tobytes() and got[0].inner.rec[0]["n"] == 12
    np.testing.assert_array_equal(got[0].inner.grid, want[0].inner.grid)
    np.testing.assert_array_equal(got[1], want[1])
    assert got[1][0] == -1.0 and got[1].base[1] == -1.0  # (the view's own memory)


def test_packed_entry_packs_again_only_when_the_state_is_replaced():
    """PackedEntry keeps one table while the state objects stay the same, packs a new one when
    an owner replaces a record (a grown buffer), and keeps the packed objects alive."""
    entry = PackedEntry(_touch)
    state = _state()
    entry(state, 1.0)
    table = entry.packed[0]
    entry(state, 1.0)
    assert entry.packed[0] is table
    grown = (state[0]._replace(flags=np.ones(5, bool)), state[1])
    want = (grown[0]._replace(inner=Inner(grown[0].inner.rec.copy(), grown[0].inner.grid.copy())), grown[1].copy())
    assert entry(grown, 0.0) == _touch_plain(want, 0.0)  # (the new flags are read)
    assert entry.packed[0] is not table and entry.state is grown


def test_pack_refuses_what_it_cannot_describe():
    """Leaves other than arrays and integers, and arrays of too many dimensions, are refused
    with the path of the leaf."""
    with pytest.raises(TypeError, match=r"state\.0\.inner\.grid is a float"):
        pack((Outer(Inner(np.zeros(1, REC), 1.5), np.zeros(1, bool), 3),))
    with pytest.raises(ValueError, match=f"at most {MAX_NDIM}"):
        pack((np.zeros((1,) * (MAX_NDIM + 1)),))
    with pytest.raises(TypeError, match=r"state\.1 is a bool"):
        pack((np.zeros(1), True))


def test_unpack_refuses_a_table_of_another_layout():
    """A table that does not describe the layout (another number of leaves) raises instead of
    reading past its end; a table of another dtype does not type."""
    table, layout = pack(_state())
    with pytest.raises(ValueError, match="5 leaves"):
        _touch(table[:4], layout, 1.0)
    with pytest.raises(numba.core.errors.TypingError):
        _touch(np.zeros(5), layout, 1.0)


def test_state_typeof_is_numbas_typeof_for_every_kind_of_leaf():
    """The memoised type of a state is numba's own, and arrays that numba types differently
    (read-only, Fortran order, strided, another record dtype, aligned or not) stay apart."""
    # (equal as numpy dtypes, and hashed alike: numba's record types differ in alignment)
    aligned = np.dtype([("a", np.float64), ("b", np.float64)], align=True)
    packed = np.dtype([("a", np.float64), ("b", np.float64)])
    assert aligned == packed
    ro = np.zeros(4)
    ro.flags.writeable = False
    leaves = (np.zeros(4), ro, np.zeros((3, 2), order="F"), np.zeros((4, 4))[:, 1], np.zeros(2, aligned),
              np.zeros(2, packed), np.zeros((2, 3), np.float32), np.zeros(1, REC), 7, np.int32(3))
    states = [_state(), leaves, (leaves, _state()), ()]
    for _ in range(2):  # (the second time from the memo)
        for st in states:
            assert state_typeof(st) == numba.typeof(st)
    assert len({state_typeof(x) for x in leaves[:6]}) == 6
    # a new state of the same kinds of arrays: the same (interned) type, as numba's
    assert state_typeof(_state()) is state_typeof(_state())
    table, layout = pack(_state())
    assert layout == numba.typeof(_state())
