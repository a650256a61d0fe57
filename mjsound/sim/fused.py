r"""Several physics substeps in one numba call: ``mj_step`` called from numba, each followed
by the reader's and the drive's kernels (:func:`.drive.read_and_drive`) and, where impacts
start, their impulses and synthesizer events (:func:`_impact_events`).

Why: a gymnasium MuJoCo env steps ``frame_skip`` times per ``env.step``, and the sound must
read the contacts of every substep. Done from Python, each substep costs a Python loop turn,
the bindings' ``mj_step``, the contact views (``data.contact.geom`` ... are new numpy arrays on
every access) and one numba dispatch with ~40 arguments: about 25..30 us per substep on the
2-core machine of ``scripts/bench_env.py``, next to the ~50 us of an Ant-v5 ``mj_step``.
Here one numba call runs all substeps of an env step.

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
  differs (a MuJoCo build whose struct differs from its description) the layout is None and
  :class:`mjsound.sim.AudioSimulator` keeps its per-substep Python path.
* Impact records are written as rows (``ContactReader.add_records`` makes the objects after
  the call), and sliding / rolling rows for the event log likewise.
* A substep that needs Python stops the loop and is finished there: a sliding pair without a
  stream yet, a Hertz coefficient not known yet, a ring buffer too short, clamped forces (a
  warning), buffers too small, a clock that no longer matches ``data.time``, impacts while the
  event log fills. :func:`run_substeps` returns which substep and why.

Limitation: an ``mju_error`` inside ``mj_step`` (MuJoCo's fatal errors) cannot become a Python
exception through numba and ends the process; the bindings' path raises
``mujoco.FatalError`` instead. A full arena (too many contacts or constraints) is a MuJoCo
warning, not an error: checked with a 6 KB arena and six boxes, which step on with warnings.
``AudioSimulator(fused=False)`` (or the environment variable ``MJSOUND_FUSED=0``) keeps every
substep in Python.
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

from ..synth.synthesizer import MAX_AMPLITUDE
from .contacts import I_COLS, SI_OPEN, _impulses_grouped, _normal_jacobians, _record_rows
from .drive import follow_rows, impacts_to_synth, pose_rows, read_and_drive

__all__ = ["DONE", "PYTHON_AFTER", "PYTHON_DRIVE", "PYTHON_STEP", "mj_function_address", "mjdata_layout", "run_substeps",
           "struct_layout"]

#: :func:`run_substeps` codes: every substep done; substep ``i`` stepped but not read (Python
#: reads it: ``AudioSimulator.step``); substep ``i`` read, Python makes its impacts and the
#: rest; substep ``i`` read and its impacts made, Python queues what could not be queued
#: here (returned) and drives the pairs without a stream
DONE, PYTHON_STEP, PYTHON_AFTER, PYTHON_DRIVE = 0, 1, 2, 3

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
def _sync_poses(mic_mode, mic_src, mic_rows, mic_off, mics, gxpos, gxmat, dyn_geoms, dyn_idx, ppos, pR):
    """``AudioSimulator._sync_poses`` in numba: the microphones (``AudioSimulator._mic_args``)
    and the moving objects' poses to where they are now."""
    if mic_mode:
        follow_rows(mic_src, mic_rows, mic_off, mics)
    if dyn_idx.shape[0]:
        pose_rows(gxpos, gxmat, dyn_geoms, dyn_idx, ppos, pR)


@njit(cache=True)
def _impact_events(fn_solve, mp, dp, hits, starts, slots, t0, n0, kin, nv, cdof, scom, gbody, e_geom, tree_mass,
                   root_mass, jmax, CF, CI, rec, st, origin, fsi, mic_mode, mic_src, mic_rows, mic_off, mics, gxpos,
                   gxmat, dyn_geoms, dyn_idx, ppos, pR, geom_obj, coef_row, coef, gain_data, pts_c, QI, qkind, qre, qim,
                   qs):
    """A substep's impact events, as ``ContactReader._impacts`` and
    ``AudioSimulator._queue_impacts`` make them: impulses from one ``mj_solveM``, a record row
    each (``rec``, taken by :meth:`ContactReader.add_records` after the call), poses and
    microphones synced, the sounding sides queued (``qs``: the queue's count, pool used, next
    sample). Returns the impacts (columns ``I_*``) and whether they were queued (not when a
    Hertz coefficient is still unknown or an amplitude is out of range: Python does it)."""
    k = hits.shape[0]
    Jn = _normal_jacobians(hits, cdof, scom, gbody, kin[0], kin[1], kin[2], kin[3], kin[4], nv)
    MinvJt = np.empty((k, nv))
    if nv > 0 and k > 0:
        _call_solve(fn_solve, mp, dp, MinvJt.ctypes.data, Jn.ctypes.data, k)
    lam, stats, imp = _impulses_grouped(hits, Jn, MinvJt, starts, e_geom, tree_mass, root_mass, gbody, jmax)
    q = stats.shape[0]
    _record_rows(hits, starts, slots, stats, t0, CF, CI, rec[st[3]:st[3] + q])
    st[3] += q
    st[1] = 1  # an impact is open
    _sync_poses(mic_mode, mic_src, mic_rows, mic_off, mics, gxpos, gxmat, dyn_geoms, dyn_idx, ppos, pR)
    t_ev = max(t0 - origin / fsi, (n0 - origin) / fsi)
    pts, pts_off, shk, shk_off, mode_off, wd, w, lam_m, leps = gain_data
    c, fs, rmin, tol, rendered, grid = pts_c
    count, used, nxt, amax, missing = impacts_to_synth(imp, geom_obj, coef_row, coef, t_ev, pts, pts_off, shk,
                                                       shk_off, mode_off, wd, w, lam_m, leps, ppos, pR, mics, c, fs,
                                                       rmin, tol, rendered, grid, QI, qkind, qre, qim, qs[0], qs[1])
    if missing.shape[0] or not amax <= MAX_AMPLITUDE:
        return imp, False
    qs[0], qs[1] = count, used
    qs[2] = min(qs[2], nxt)
    st[4] += imp.shape[0]
    return imp, True


@njit(cache=True)
def run_substeps(fn_step, mp, dp, L, nstep, clk, clf, st, want_log,
                 pyramidal, cvel, scom, gxpos, gbody, broot, plane, ngeom, hkeys, hvals, CF, CI, prm, counts,
                 rows, srows, hits, onsets,
                 sidx, geom_obj, rough, length, fs, regain, rendered, slack, SF, SI, D, ring, missing,
                 geom, pos, frame, adr, dim,
                 fn_solve, kin, nv, cdof, e_geom, tree_mass, root_mass, jmax, rec,
                 mic_mode, mic_src, mic_rows, mic_off, mics, gxmat, dyn_geoms, dyn_idx, ppos, pR,
                 coef_row, coef, gain_data, pts_c, QI, qkind, qre, qim, qs, q_room, log_rows, log_t):
    """``mj_step`` then read, drive and make the impacts, ``nstep`` times, until a substep
    needs Python.

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
    st : (6,) int64, updated
        The reader's ``nslots``, ``any_open`` (0/1) and step counter; record rows written to
        ``rec``; impacts queued; sustained rows logged.
    want_log : bool
        The event log is not full: each substep's sustained rows are copied to ``log_rows``
        (with their time in ``log_t``) for ``AudioSimulator.event_log``, and substeps with
        impacts are finished in Python (which logs those).
    pyramidal ... onsets
        The reader's arguments of ``contacts._fused_kernel`` (its state and buffers).
    sidx ... missing
        The drive's arguments of :func:`.drive.drive_rows`.
    geom, pos, frame, adr, dim : buffers of at least ``len(rows)`` contacts
    fn_solve ... rec
        For impacts: the address of ``mj_solveM``, the reader's kinematic tree and masses
        (``ContactReader._impacts``), the record rows buffer (``REC_COLS`` wide).
    mic_mode ... pR
        ``AudioSimulator._sync_poses``: microphones (mode 0: fixed, 1: ``follow_rows`` of
        ``mic_src``) and the moving objects' poses.
    coef_row ... q_room
        ``AudioSimulator._queue_impacts``: Hertz coefficients, the synthesizer's gain data
        (9 arrays) and constants (6), its event queue arrays, ``qs`` (count, pool used, next
        sample; updated) and ``q_room`` (rows and pool entries per impacting contact).
    log_rows, log_t : (cap, R_COLS), (cap,) float
        Buffers for the logged sustained rows (a substep that does not fit goes to Python).

    Returns
    -------
    i : int
        Substeps finished here (``i < nstep``: substep ``i`` was stepped and needs Python;
        ``i == nstep``: the poses and microphones are synced to the last one).
    code : int
        :data:`DONE`, :data:`PYTHON_STEP` (read it from the start), :data:`PYTHON_AFTER`
        (read here; make its impacts and the rest) or :data:`PYTHON_DRIVE` (its impacts
        made here; queue ``imp`` if not empty, drive the pairs without a stream).
    out : tuple of 9 ints
        :func:`.drive.read_and_drive`'s outputs of substep ``i``.
    imp : (k, I_COLS) float
        Substep ``i``'s impacts that Python must queue (:data:`PYTHON_DRIVE`).
    """
    a0, b, den, fsi, k_start, origin = clk[0], clk[1], clk[2], clk[3], clk[4], clk[5]
    t_start, dt = clf[0], clf[1]
    none = (0, 0, 0, 0, 0, 0, 0, 0, 0)
    no_imp = np.empty((0, I_COLS))
    cap = min(rows.shape[0], geom.shape[0])
    for i in range(nstep):
        _call2(fn_step, mp, dp)
        k = k_start + i + 1
        if abs(carray(_f64_at(dp + L[L_TIME]), 1)[0] - (t_start + k * dt)) > 0.25 * dt:
            return i, PYTHON_STEP, none, no_imp  # data.time jumped: the clock re-anchors in Python
        ncon = carray(_i32_at(dp + L[L_NCON]), 1)[0]
        if ncon == 0:
            st[2] += 1
            if st[1]:  # an open impact closes: nothing touches
                for j in range(st[0]):
                    CI[SI_OPEN, j] = 0
                st[1] = 0
            continue
        if ncon > cap or st[0] + ncon > CF.shape[1]:
            return i, PYTHON_STEP, none, no_imp  # buffers grow in Python
        _gather_contacts(carray(_u64_at(dp + L[L_CONTACT]), 1)[0], ncon, L, geom, pos, frame, adr, dim)
        nefc = carray(_i32_at(dp + L[L_NEFC]), 1)[0]
        efc = carray(_f64_at(carray(_u64_at(dp + L[L_EFC_FORCE]), 1)[0]), max(nefc, 0))
        st[2] += 1
        num0 = (a0 + (k - 1) * b)
        num1 = num0 + b
        n0 = -((-num0 * fsi) // den)
        n1 = -((-num1 * fsi) // den)
        t0 = num0 / den
        out = read_and_drive(geom[:ncon], pos[:ncon], frame[:ncon], adr[:ncon], dim[:ncon], efc, pyramidal, cvel,
                             scom, gxpos, gbody, broot, plane, ngeom, hkeys, hvals, CF, CI, st[0], t0, num1 / den,
                             st[2], prm, counts, rows, srows, hits, onsets,
                             sidx, geom_obj, rough, length, fs, n0 - origin, n1 - origin, regain, rendered, slack,
                             SF, SI, D, ring, missing)
        st[0] = out[6]
        ns, nh, n_onset = out[1], out[2], out[5]
        if out[3] or out[4] or (want_log and (n_onset or st[5] + ns > log_rows.shape[0])):
            return i, PYTHON_AFTER, out, no_imp  # clamped forces (a warning), or the event log
        if want_log:
            for j in range(ns):
                log_rows[st[5] + j] = srows[j]
                log_t[st[5] + j] = t0
            st[5] += ns
        queued = True
        imp = no_imp
        if n_onset:
            if (st[3] + n_onset > rec.shape[0] or qs[0] + q_room[0] * nh > QI.shape[1]
                    or qs[1] + q_room[1] * nh > qre.shape[0]):
                return i, PYTHON_AFTER, out, no_imp  # (buffers grow in Python)
            imp, queued = _impact_events(fn_solve, mp, dp, hits[:nh], onsets[:n_onset + 1, 1], onsets[:n_onset, 0],
                                         t0, n0, kin, nv, cdof, scom, gbody, e_geom, tree_mass, root_mass, jmax, CF,
                                         CI, rec, st, origin, fsi, mic_mode, mic_src, mic_rows, mic_off, mics, gxpos,
                                         gxmat, dyn_geoms, dyn_idx, ppos, pR, geom_obj, coef_row, coef, gain_data,
                                         pts_c, QI, qkind, qre, qim, qs)
        if not queued or out[7] or out[8]:
            return i, PYTHON_DRIVE, out, (no_imp if queued else imp)
    # poses and microphones current for the render's stream gains (Synthesizer.poses_current)
    _sync_poses(mic_mode, mic_src, mic_rows, mic_off, mics, gxpos, gxmat, dyn_geoms, dyn_idx, ppos, pR)
    return nstep, DONE, none, no_imp
