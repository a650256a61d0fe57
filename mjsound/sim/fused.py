r"""Several physics substeps in one numba call: ``mj_step`` called from numba, each followed
by the reader's and the drive's kernels (:func:`.drive.read_and_drive`).

Why: a gymnasium MuJoCo env steps ``frame_skip`` times per ``env.step``, and the sound must
read the contacts of every substep. Done from Python, each substep costs a Python loop turn,
the bindings' ``mj_step``, the contact views (``data.contact.geom`` ... are new numpy arrays on
every access) and one numba dispatch with ~40 arguments: about 25..30 us per substep on the
2-core machine of ``scripts/bench_env.py``, next to the ~50 us of an Ant-v5 ``mj_step``.
Here one numba call runs all substeps of an env step.

How:

* MuJoCo's C ``mj_step`` is called through its address (``ctypes`` looks it up in the
  ``libmujoco`` the bindings load): :func:`_call2` casts the address to a function pointer in
  the compiled code, so nothing process-specific is frozen into numba's on-disk cache.
* The step's contacts and constraint forces are read from the ``mjData`` struct itself:
  ``ncon``, ``nefc``, ``time``, the ``contact`` and ``efc_force`` pointers. Their byte offsets
  follow from MuJoCo's own description of its structs (``mujoco.introspect``) with C's
  alignment rules (:func:`struct_layout`), and :func:`mjdata_layout` checks every offset against
  the bindings' views of a live ``MjData`` with contacts before anything uses them. If any
  differs (a MuJoCo build whose struct differs from its description) the layout is None and
  :class:`mjsound.sim.AudioSimulator` keeps its per-substep Python path.
* A substep that needs Python stops the loop and is finished there: an impact onset (its
  impulse needs ``mj_solveM``), a sliding pair without a stream yet, a ring buffer too short,
  clamped forces (a warning), buffers too small for the contact count, a clock that no longer
  matches ``data.time``. :func:`run_substeps` returns which substep and why.

Limitation: an ``mju_error`` inside ``mj_step`` (e.g. MuJoCo's stack overflowing on a huge
scene) cannot become a Python exception through numba and ends the process; the bindings'
path raises ``mujoco.FatalError`` instead. ``AudioSimulator(fused=False)`` (or the
environment variable ``MJSOUND_FUSED=0``) keeps every substep in Python.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from .contacts import SI_OPEN
from .drive import read_and_drive

__all__ = ["DONE", "PYTHON_AFTER", "PYTHON_STEP", "mj_step_address", "mjdata_layout", "run_substeps", "struct_layout"]

#: :func:`run_substeps` codes: every substep done; substep ``i`` stepped but not read (Python
#: reads it: ``AudioSimulator.step``); substep ``i`` read, Python finishes it (its outputs
#: are returned)
DONE, PYTHON_STEP, PYTHON_AFTER = 0, 1, 2

# layout vector L: mjData offsets, then mjContact's size and field offsets [bytes]
L_NCON, L_NEFC, L_TIME, L_CONTACT, L_EFC_FORCE, L_CSIZE, L_CPOS, L_CFRAME, L_CGEOM, L_CDIM, L_CEFCADR = range(11)
_DATA_FIELDS = ("ncon", "nefc", "time", "contact", "efc_force")
_CONTACT_FIELDS = ("pos", "frame", "geom", "dim", "efc_address")

# C sizes of the scalar types in MuJoCo's structs (LP64: Linux, macOS; Windows' long is not used)
_SCALAR = {"int": 4, "unsigned int": 4, "float": 4, "double": 8, "char": 1, "unsigned char": 1, "mjtNum": 8,
           "mjtByte": 1, "mjtBool": 1, "mjtSize": 8, "size_t": 8, "uint64_t": 8, "uintptr_t": 8, "int64_t": 8}


def struct_layout(name: str) -> tuple[dict, int, int]:
    """Byte offsets of the fields of MuJoCo struct ``name``, its size and alignment.

    From ``mujoco.introspect.structs`` (the description the bindings are generated from) with
    C's rules: each field at the next multiple of its alignment, the size rounded up to the
    largest alignment; pointers 8 bytes, enums 4, arrays of structs as their elements."""
    from mujoco.introspect import ast_nodes, structs

    def size_align(t):
        if isinstance(t, ast_nodes.PointerType):
            return 8, 8
        if isinstance(t, ast_nodes.ArrayType):
            s, a = size_align(t.inner_type)
            return s * int(np.prod([int(e) for e in t.extents])), a
        if isinstance(t, ast_nodes.ValueType):
            if t.name in _SCALAR:
                return _SCALAR[t.name], _SCALAR[t.name]
            if t.name in structs.STRUCTS:
                _, s, a = struct_layout(t.name)
                return s, a
            if t.name.startswith("mjt"):  # an enum
                return 4, 4
        raise TypeError(f"struct_layout: no C size for {t}")

    off, align, out = 0, 1, {}
    for f in structs.STRUCTS[name].fields:
        s, a = size_align(f.type)
        off = -(-off // a) * a
        out[f.name] = off
        off += s
        align = max(align, a)
    return out, -(-off // align) * align, align


def _addr(a: np.ndarray) -> int:
    return int(a.__array_interface__["data"][0])


@functools.lru_cache(maxsize=1)
def mjdata_layout() -> np.ndarray | None:
    """The offsets vector ``L`` (``L_*``) for this MuJoCo build, or None when the struct
    description and the bindings disagree (then the fused path is not used).

    Checked on a private model stepped until a box rests on a plane (contacts and constraint
    forces exist): every offset used must give the bindings' value or address."""
    try:
        import mujoco

        data_off, _, _ = struct_layout("mjData")
        con_off, con_size, _ = struct_layout("mjContact")
        m = mujoco.MjModel.from_xml_string(
            "<mujoco><worldbody><geom type='plane' size='1 1 .1'/><body pos='0 0 .05'><freejoint/>"
            "<geom type='box' size='.05 .05 .05'/></body></worldbody></mujoco>")
        d = mujoco.MjData(m)
        for _ in range(20):
            mujoco.mj_step(m, d)
        if d.ncon < 2 or d.nefc < 1:
            return None
        L = np.array([data_off[f] for f in _DATA_FIELDS] + [con_size] + [con_off[f] for f in _CONTACT_FIELDS],
                     np.int64)
        raw = np.frombuffer(ctypes.string_at(d._address, int(max(L[:L_CSIZE])) + 8), np.uint8)

        def at(off, dtype):
            return raw[off: off + np.dtype(dtype).itemsize].view(dtype)[0]

        con = d.contact
        base = _addr(con.dist)
        ok = (at(L[L_NCON], np.int32) == d.ncon and at(L[L_NEFC], np.int32) == d.nefc
              and at(L[L_TIME], np.float64) == d.time and at(L[L_CONTACT], np.uint64) == base
              and at(L[L_EFC_FORCE], np.uint64) == _addr(d.efc_force) and con.pos.strides[0] == con_size
              and all(_addr(getattr(con, f)) - base == L[L_CPOS + i] for i, f in enumerate(_CONTACT_FIELDS))
              and at(data_off["qpos"], np.uint64) == _addr(d.qpos) and at(data_off["cdof"], np.uint64) == _addr(d.cdof))
        return L if ok else None
    except Exception:  # any mismatch in the description: keep the Python path
        return None


@functools.lru_cache(maxsize=1)
def mj_step_address() -> int:
    """Address of MuJoCo's C ``mj_step`` in the ``libmujoco`` that the bindings use."""
    import mujoco

    here = os.path.dirname(mujoco.__file__)
    libs = sorted(glob.glob(os.path.join(here, "libmujoco.so*")) + glob.glob(os.path.join(here, "libmujoco*.dylib"))
                  + glob.glob(os.path.join(here, "mujoco.dll")))
    if not libs:
        raise OSError(f"no libmujoco next to {here}")
    return ctypes.cast(ctypes.CDLL(libs[0]).mj_step, ctypes.c_void_p).value


@intrinsic
def _call2(typingctx, fn, a, b):
    """``fn(a, b)`` for the address ``fn`` of a C function ``void f(void*, void*)``."""
    if not all(isinstance(t, types.Integer) for t in (fn, a, b)):
        return None
    sig = types.void(fn, a, b)

    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        f = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [vp, vp]).as_pointer())
        builder.call(f, [builder.inttoptr(args[1], vp), builder.inttoptr(args[2], vp)])
        return context.get_dummy_value()

    return sig, codegen


def _pointer_cast(dtype):
    @intrinsic
    def cast(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None
        sig = types.CPointer(dtype)(addr)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(dtype)))

        return sig, codegen

    return cast


_f64_at = _pointer_cast(types.float64)
_i32_at = _pointer_cast(types.int32)
_u64_at = _pointer_cast(types.uint64)


@njit(cache=True)
def _gather_contacts(cp, ncon, L, geom, pos, frame, adr, dim):
    """Copy the fields the reader needs of ``ncon`` contacts at address ``cp`` (mjContact
    array) into contiguous buffers."""
    size = L[L_CSIZE]
    f = carray(_f64_at(cp), (ncon * size) // 8)
    i = carray(_i32_at(cp), (ncon * size) // 4)
    for c in range(ncon):
        of = (c * size + L[L_CPOS]) // 8
        for j in range(3):
            pos[c, j] = f[of + j]
        of = (c * size + L[L_CFRAME]) // 8
        for j in range(9):
            frame[c, j] = f[of + j]
        oi = (c * size + L[L_CGEOM]) // 4
        geom[c, 0] = i[oi]
        geom[c, 1] = i[oi + 1]
        dim[c] = i[(c * size + L[L_CDIM]) // 4]
        adr[c] = i[(c * size + L[L_CEFCADR]) // 4]


@njit(cache=True)
def run_substeps(fn_step, mp, dp, L, nstep, clk, clf, st, want_rows,
                 pyramidal, cvel, scom, gxpos, gbody, broot, plane, ngeom, hkeys, hvals, CF, CI, prm, counts,
                 rows, srows, hits, onsets,
                 sidx, geom_obj, rough, length, fs, regain, rendered, slack, SF, SI, D, ring, missing,
                 geom, pos, frame, adr, dim):
    """``mj_step`` then read and drive, ``nstep`` times, until a substep needs Python.

    Parameters
    ----------
    fn_step, mp, dp : int
        Address of ``mj_step``, of the ``mjModel`` and the ``mjData``.
    L : (11,) int64
        :func:`mjdata_layout`.
    clk : (6,) int64
        The sample clock (``SampleClock``): ``a0, b, den, fs`` (step ``k`` starts at
        ``(a0 + k b) / den`` seconds, its first sample is ``ceil((a0 + k b) fs / den)``), the
        step count ``k`` before the first substep, and the synthesizer's origin sample.
    clf : (2,) float
        ``t_start, timestep`` [s] (``data.time`` must stay within a quarter step of the count).
    st : (3,) int64, updated
        The reader's ``nslots``, ``any_open`` (0/1) and step counter.
    want_rows : bool
        Sustained rows are wanted in Python (the event log is not full): a substep with
        some is finished there.
    pyramidal ... onsets
        The reader's arguments of ``contacts._fused_kernel`` (its state and buffers).
    sidx ... missing
        The drive's arguments of :func:`.drive.drive_rows`.
    geom, pos, frame, adr, dim : buffers of at least ``len(rows)`` contacts

    Returns
    -------
    i : int
        Substeps finished here (``i < nstep``: substep ``i`` was stepped and needs Python).
    code : int
        :data:`DONE`, :data:`PYTHON_STEP` (read it from the start) or :data:`PYTHON_AFTER`
        (read here; the reader's outputs follow for Python to finish).
    out : tuple of 9 ints
        :func:`.drive.read_and_drive`'s outputs of substep ``i`` (:data:`PYTHON_AFTER`).
    """
    a0, b, den, fsi, k_start, origin = clk[0], clk[1], clk[2], clk[3], clk[4], clk[5]
    t_start, dt = clf[0], clf[1]
    none = (0, 0, 0, 0, 0, 0, 0, 0, 0)
    cap = min(rows.shape[0], geom.shape[0])
    for i in range(nstep):
        _call2(fn_step, mp, dp)
        k = k_start + i + 1
        if abs(carray(_f64_at(dp + L[L_TIME]), 1)[0] - (t_start + k * dt)) > 0.25 * dt:
            return i, PYTHON_STEP, none  # data.time jumped: the clock re-anchors in Python
        ncon = carray(_i32_at(dp + L[L_NCON]), 1)[0]
        if ncon == 0:
            st[2] += 1
            if st[1]:  # an open impact closes: nothing touches
                for j in range(st[0]):
                    CI[SI_OPEN, j] = 0
                st[1] = 0
            continue
        if ncon > cap or st[0] + ncon > CF.shape[1]:
            return i, PYTHON_STEP, none  # buffers grow in Python
        _gather_contacts(carray(_u64_at(dp + L[L_CONTACT]), 1)[0], ncon, L, geom, pos, frame, adr, dim)
        nefc = carray(_i32_at(dp + L[L_NEFC]), 1)[0]
        efc = carray(_f64_at(carray(_u64_at(dp + L[L_EFC_FORCE]), 1)[0]), max(nefc, 0))
        st[2] += 1
        num0 = (a0 + (k - 1) * b)
        num1 = num0 + b
        n0 = -((-num0 * fsi) // den)
        n1 = -((-num1 * fsi) // den)
        out = read_and_drive(geom[:ncon], pos[:ncon], frame[:ncon], adr[:ncon], dim[:ncon], efc, pyramidal, cvel,
                             scom, gxpos, gbody, broot, plane, ngeom, hkeys, hvals, CF, CI, st[0], num0 / den,
                             num1 / den, st[2], prm, counts, rows, srows, hits, onsets,
                             sidx, geom_obj, rough, length, fs, n0 - origin, n1 - origin, regain, rendered, slack,
                             SF, SI, D, ring, missing)
        st[0] = out[6]
        if out[3] or out[4] or out[5] or out[7] or out[8] or (want_rows and out[1]):
            return i, PYTHON_AFTER, out
    return nstep, DONE, none
