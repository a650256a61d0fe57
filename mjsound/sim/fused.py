r"""MuJoCo reached from numba: ``mj_step`` / ``mj_solveM`` through their C addresses and the
step's contacts read from the ``mjData`` struct, so that the step kernel (:mod:`.step`) can
run several physics substeps in one numba call.

Why: a gymnasium MuJoCo env steps ``frame_skip`` times per ``env.step``, and the sound must
read the contacts of every substep. Done from Python, each substep costs a Python loop turn,
the bindings' ``mj_step``, the contact views (``data.contact.geom`` ... are new numpy arrays on
every access) and a numba dispatch; here one numba call runs all substeps of an env step.

How:

* MuJoCo's C ``mj_step`` and ``mj_solveM`` are called through their addresses (``ctypes``
  looks them up in the ``libmujoco`` the bindings load, :func:`mj_function_address` checks
  their signatures against ``mujoco.introspect``): :func:`_call2` and :func:`_call_solve` cast
  the address to a function pointer in the compiled code, so nothing process-specific is
  frozen into numba's on-disk cache.
* The step's contacts and constraint forces are read from the ``mjData`` struct itself:
  ``ncon``, ``nefc``, ``time``, the ``contact`` and ``efc_force`` pointers. Their byte offsets
  follow from MuJoCo's own description of its structs (``mujoco.introspect``) with C's
  alignment rules (:func:`struct_layout`), and :func:`mjdata_layout` checks every offset against
  the bindings' views of a live ``MjData`` with contacts before anything uses them. If any
  differs (a MuJoCo build whose struct differs from its description) the layout is None,
  :func:`mj_link` says so (``layout_ok`` 0) and Python copies each step's contacts in and
  calls ``mj_step`` itself (the same kernel then runs one substep per call).

Limitation: an ``mju_error`` inside ``mj_step`` (MuJoCo's fatal errors) cannot become a Python
exception through numba and ends the process; the bindings' path raises
``mujoco.FatalError`` instead. A full arena (too many contacts or constraints) is a MuJoCo
warning, not an error: checked with a 6 KB arena and six boxes, which step on with warnings.
``AudioSimulator(fused=False)`` (or the environment variable ``MJSOUND_FUSED=0``) keeps every
``mj_step`` and contact read in Python.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.extending import intrinsic

from ..jit import njit_inner
from .records import MJ

__all__ = ["mj_function_address", "mjdata_layout", "mj_link", "struct_layout", "gather_contacts", "data_ncon",
           "data_time", "data_efc_force", "mj_step_now", "mj_solve_now"]

# the offsets vector of mjdata_layout (checked there; mj_link names them in an MJ record):
# mjData offsets, then mjContact's size and field offsets [bytes]
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


#: the C functions called from numba, with the parameter types they are called with
_C_SIGNATURES = {"mj_step": ("const mjModel *", "mjData *"),
                 "mj_solveM": ("const mjModel *", "mjData *", "mjtNum *", "const mjtNum *", "int")}


@functools.lru_cache(maxsize=4)
def mj_function_address(name: str) -> int:
    """Address of MuJoCo's C function ``name`` (``mj_step``, ``mj_solveM``) in the
    ``libmujoco`` that the bindings use, after checking its parameters against
    ``mujoco.introspect.functions`` (a different signature raises: no fused path then)."""
    import mujoco
    from mujoco.introspect import functions

    params = tuple(str(p.type) for p in functions.FUNCTIONS[name].parameters)
    if params != _C_SIGNATURES[name] or str(functions.FUNCTIONS[name].return_type) != "void":
        raise TypeError(f"{name}{params} is not {name}{_C_SIGNATURES[name]}")
    here = os.path.dirname(mujoco.__file__)
    libs = sorted(glob.glob(os.path.join(here, "libmujoco.so*")) + glob.glob(os.path.join(here, "libmujoco*.dylib"))
                  + glob.glob(os.path.join(here, "mujoco.dll")))
    if not libs:
        raise OSError(f"no libmujoco next to {here}")
    return ctypes.cast(getattr(ctypes.CDLL(libs[0]), name), ctypes.c_void_p).value


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


@intrinsic
def _call_solve(typingctx, fn, m, d, x, y, n):
    """``fn(m, d, x, y, n)`` for the address ``fn`` of ``void mj_solveM(const mjModel*,
    mjData*, mjtNum* x, const mjtNum* y, int n)`` (all addresses as integers)."""
    if not all(isinstance(t, types.Integer) for t in (fn, m, d, x, y, n)):
        return None
    sig = types.void(fn, m, d, x, y, n)

    def codegen(context, builder, signature, args):
        vp, dp, i32 = ir.IntType(8).as_pointer(), ir.DoubleType().as_pointer(), ir.IntType(32)
        f = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [vp, vp, dp, dp, i32]).as_pointer())
        builder.call(f, [builder.inttoptr(args[1], vp), builder.inttoptr(args[2], vp), builder.inttoptr(args[3], dp),
                         builder.inttoptr(args[4], dp), builder.trunc(args[5], i32)])
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


@njit_inner(cache=True)
def gather_contacts(mj, buf, ncon):
    """Copy the fields the reader needs of the mjData's first ``ncon`` contacts (read from
    the struct at ``mj.data`` with the offsets of :func:`mj_link`) into the buffers ``buf``."""
    L = mj[0]
    cp = carray(_u64_at(L.data + L.contact), 1)[0]
    size = L.contact_size
    f = carray(_f64_at(cp), (ncon * size) // 8)
    i = carray(_i32_at(cp), (ncon * size) // 4)
    geom, pos, frame, adr, dim = buf.geom, buf.pos, buf.frame, buf.efc_address, buf.dim
    for c in range(ncon):
        of = (c * size + L.c_pos) // 8
        for j in range(3):
            pos[c, j] = f[of + j]
        of = (c * size + L.c_frame) // 8
        for j in range(9):
            frame[c, j] = f[of + j]
        oi = (c * size + L.c_geom) // 4
        geom[c, 0] = i[oi]
        geom[c, 1] = i[oi + 1]
        dim[c] = i[(c * size + L.c_dim) // 4]
        adr[c] = i[(c * size + L.c_efc_address) // 4]


@njit_inner(cache=True)
def data_ncon(mj):
    """``mjData.ncon`` read from the struct."""
    L = mj[0]
    return carray(_i32_at(L.data + L.ncon), 1)[0]


@njit_inner(cache=True)
def data_time(mj):
    """``mjData.time`` read from the struct [s]."""
    L = mj[0]
    return carray(_f64_at(L.data + L.time), 1)[0]


@njit_inner(cache=True)
def data_efc_force(mj):
    """``mjData.efc_force`` (nefc,) read from the struct (a view of MuJoCo's array)."""
    L = mj[0]
    nefc = carray(_i32_at(L.data + L.nefc), 1)[0]
    return carray(_f64_at(carray(_u64_at(L.data + L.efc_force), 1)[0]), max(nefc, 0))


@njit_inner(cache=True)
def mj_step_now(mj):
    """``mj_step(model, data)`` through its C address."""
    L = mj[0]
    _call2(L.step_fn, L.model, L.data)


@njit_inner(cache=True)
def mj_solve_now(mj, x, y, n):
    """``mj_solveM(model, data, x, y, n)``: ``x = M^-1 y`` for ``n`` rows (C-contiguous
    (n, nv) float64 arrays), through its C address."""
    L = mj[0]
    _call_solve(L.solve_fn, L.model, L.data, x.ctypes.data, y.ctypes.data, n)


def mj_link(model, data, use_c: bool = True) -> np.ndarray:
    """The :data:`.records.MJ` record of ``model`` / ``data``: C addresses (0 where not
    available or ``use_c`` is False) and the struct offsets (``layout_ok`` 0 when they could
    not be checked: Python then copies the contacts in and steps)."""
    rec = np.zeros(1, MJ)
    r = rec[0]
    r["model"], r["data"] = model._address, data._address
    if not use_c:
        return rec
    try:
        r["step_fn"], r["solve_fn"] = mj_function_address("mj_step"), mj_function_address("mj_solveM")
    except (OSError, TypeError, KeyError, AttributeError):
        return rec
    L = mjdata_layout()
    if L is not None:
        for name, i in (("ncon", L_NCON), ("nefc", L_NEFC), ("time", L_TIME), ("contact", L_CONTACT),
                        ("efc_force", L_EFC_FORCE), ("contact_size", L_CSIZE), ("c_pos", L_CPOS),
                        ("c_frame", L_CFRAME), ("c_geom", L_CGEOM), ("c_dim", L_CDIM),
                        ("c_efc_address", L_CEFCADR)):
            r[name] = L[i]
        r["layout_ok"] = 1
    return rec
