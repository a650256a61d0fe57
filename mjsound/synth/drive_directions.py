"""The direction factors of the driven links' modes, for the drive lines' weights, in float32
(:func:`.drive_weights.line_weights`; the exact rendering of contact sounds keeps its float64
path, :mod:`.directivity`).

Per driven body and air microphone (and its floor image) the weights need each mode's factor
``D_i(u) = sum_lm Y_lm(u) c_ilm`` (:mod:`.directivity`) at the direction ``u`` from the body to
the microphone, made again whenever ``u`` turned by more than the step: in Ant-v5 every block,
for 12 bodies and 2 microphones, order 10 (121 harmonics) and 68 modes. Both passes are made
cheaper here:

* **The harmonics of two directions at once** (:func:`sh_pair`): the recurrence of
  :func:`.directivity.real_sh` (its values to the last bit, then rounded to float32), the two
  directions' chains side by side.
* **The sums over the harmonics in float32, four modes at a time** (:func:`_chunk_factors`):
  each object's coefficients are copied once, when the synthesizer's direction fits are
  made (:func:`drive_directions`), into float32 blocks of four modes (their real parts, then
  their imaginary parts, each row the object's ``(L + 1)^2`` harmonics zero-padded to a
  multiple of 8). One pass over a block gives its four modes' factors at both directions
  (16 sums, fused multiply-adds): the harmonics read once per four modes and half the
  memory of float64 (in Ant-v5 82 kB a block instead of 130 kB, the padding included).

**Reference counts**: :func:`direction_factors` and its helpers are compiled without numba's
reference counting (``_nrt=False``: they allocate nothing; :mod:`.drive_gains`' docstring):
a call otherwise adds one to and drops one from the count of each array of the scene's
view it is handed, once per driven body and block.

**Error.** Each factor is a float32 sum of ``(L + 1)^2`` terms: its error is of the order of
``1e-7`` of the mode's RMS factor (``tests/test_drive_directions.py`` bounds it against the
float64 fit at ``1e-5``, at order 16), three orders of magnitude under the fits' own error
(:attr:`.directivity.DirectionFit.error`: up to 1 %, from the energy ``ORDER_TOL`` left
above each mode's order).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import uint64

from ..jit import njit, njit_inner
from .bank_loops import FAST, fmuladd
from .directivity import sh_tables
from .records import AIR

__all__ = ["CHUNK", "DriveDirections", "drive_directions", "sh_pair", "turned_directions", "apply_factors",
           "direction_factors"]

#: Modes per block of the float32 coefficients.
CHUNK = 4
#: A block's rows are padded to a multiple of this many harmonics.
PAD = 8


class DriveDirections(NamedTuple):
    """The drives' float32 copy of the direction fits (:func:`drive_directions`)."""

    coef: np.ndarray  # (k,) float32: per object its modes in blocks of CHUNK, each (2 CHUNK, K[o]): re rows, im rows
    off: np.ndarray  # (objects,) int64: each object's first block in coef (-1: no direction)
    K: np.ndarray  # (objects,) int64: each object's padded harmonics per row
    tab: np.ndarray  # (3, (top + 1)^2) float64: real_sh's factors (.directivity.sh_tables)
    sh: np.ndarray  # (2, Kmax) float32 scratch: two directions' harmonics (finite past an object's own: 0 x padding)
    F: np.ndarray  # (4 CHUNK,) float32 scratch: a block's factors


def _padded(k: int) -> int:
    return -(-k // PAD) * PAD


def drive_directions(dr, mode_off) -> DriveDirections:
    """The float32 blocks of :class:`.records.DirectionState` ``dr``'s fits (module docstring)
    for objects whose kept modes are ``mode_off[o] .. mode_off[o + 1]`` (the flat order of
    ``dr.msh_off``), and the scratch :func:`direction_factors` uses: made once per direction
    state.

    Examples
    --------
    >>> dd = drive_directions(dr, objects.mode_off)  # doctest: +SKIP  (a DirectionState, an ObjectTable)
    >>> dd.coef.dtype, dd.K[o]  # (object o of order 10: 121 harmonics, rows of 128)
    (dtype('float32'), 128)
    """
    order, msh_off = np.asarray(dr.order), np.asarray(dr.msh_off)
    top = max(int(order.max(initial=-1)), 0)
    off = np.full(len(order), -1, np.int64)
    K = np.zeros(len(order), np.int64)
    parts, at, g = [], 0, 0
    counts = np.diff(np.asarray(mode_off))[:len(order)]
    for o, n in enumerate(counts):
        L = int(order[o])
        if L >= 0:
            Kp = _padded((L + 1) ** 2)
            blk = np.zeros((-(-n // CHUNK), 2 * CHUNK, Kp), np.float32)
            for i in range(n):
                k0, k1 = msh_off[g + i], msh_off[g + i + 1]
                blk[i // CHUNK, i % CHUNK, :k1 - k0] = dr.coef_r[k0:k1]
                blk[i // CHUNK, CHUNK + i % CHUNK, :k1 - k0] = dr.coef_i[k0:k1]
            off[o], K[o] = at, Kp
            parts.append(blk.ravel())
            at += blk.size
        g += n
    coef = np.concatenate(parts) if parts else np.zeros(0, np.float32)
    return DriveDirections(coef, off, K, sh_tables(top), np.zeros((2, _padded((top + 1) ** 2)), np.float32),
                           np.zeros(4 * CHUNK, np.float32))


@njit(cache=True, _nrt=False)
def sh_pair(L, x0, y0, z0, x1, y1, z1, tab, Y0, Y1):
    """The real orthonormal harmonics up to degree ``L`` at the unit vectors ``(x0, y0, z0)``
    and ``(x1, y1, z1)`` into ``Y0`` and ``Y1`` (float32; ``Y[l^2 + l + m]``):
    :func:`.directivity.real_sh`'s recurrence with its factors ``tab``
    (:func:`.directivity.sh_tables`), the same products in the same order (its values to the
    last bit, then rounded to float32), the two directions' chains side by side (each step
    of one waits on the one before: two chains fill the time). The indices are unsigned: no
    negative-index test per load and store (about 30 % of the time of two ``real_sh``)."""
    t0, t1, t2 = tab[0], tab[1], tab[2]
    amm = 0.5 / np.sqrt(np.pi)
    Y0[0] = amm
    Y1[0] = amm
    pa2 = 0.0
    pa1 = amm
    pb2 = 0.0
    pb1 = amm
    for l in range(1, L + 1):  # m = 0
        i = uint64(l * l + l)
        a = t0[i]
        ab = a * t1[i]
        pa = (a * z0) * pa1 - ab * pa2
        pb = (a * z1) * pb1 - ab * pb2
        Y0[i] = pa
        Y1[i] = pb
        pa2 = pa1
        pa1 = pa
        pb2 = pb1
        pb1 = pb
    r2 = np.sqrt(2.0)
    ca = 1.0
    sa = 0.0
    cb = 1.0
    sb = 0.0
    for m_ in range(1, L + 1):
        m = uint64(m_)
        ca, sa = ca * x0 - sa * y0, ca * y0 + sa * x0
        cb, sb = cb * x1 - sb * y1, cb * y1 + sb * x1
        amm *= t2[m * m + 2 * m]
        rca = r2 * ca
        rsa = r2 * sa
        rcb = r2 * cb
        rsb = r2 * sb
        Y0[m * m + 2 * m] = amm * rca
        Y0[m * m] = amm * rsa
        Y1[m * m + 2 * m] = amm * rcb
        Y1[m * m] = amm * rsb
        pa2 = 0.0
        pa1 = amm
        pb2 = 0.0
        pb1 = amm
        for l in range(m_ + 1, L + 1):
            i = uint64(l * l + l)
            a = t0[i + m]
            ab = a * t1[i + m]
            pa = (a * z0) * pa1 - ab * pa2
            pb = (a * z1) * pb1 - ab * pb2
            pa2 = pa1
            pa1 = pa
            pb2 = pb1
            pb1 = pb
            Y0[i + m] = pa * rca
            Y0[i - m] = pa * rsa
            Y1[i + m] = pb * rcb
            Y1[i - m] = pb * rsb


@njit_inner(cache=True, fastmath=FAST, _nrt=False)
def _chunk_factors(Y0, Y1, C, K, F):
    """One block's four modes' factors at two directions, ``F[4 q + 2 d + (0, 1)]`` the real
    and imaginary parts of mode ``q`` at direction ``d``: ``sum_i Y_d[i] C[q, i]``, ``C[4 + q, i]``
    over the block's rows ``C`` (8 rows of ``K``, flat; module docstring), in float32."""
    zero = np.float32(0.0)
    r00 = r01 = r10 = r11 = r20 = r21 = r30 = r31 = zero
    i00 = i01 = i10 = i11 = i20 = i21 = i30 = i31 = zero
    for i in range(K):
        a = Y0[i]
        b = Y1[i]
        c0 = C[i]
        c1 = C[K + i]
        c2 = C[2 * K + i]
        c3 = C[3 * K + i]
        s0 = C[4 * K + i]
        s1 = C[5 * K + i]
        s2 = C[6 * K + i]
        s3 = C[7 * K + i]
        r00 = fmuladd(a, c0, r00)
        i00 = fmuladd(a, s0, i00)
        r01 = fmuladd(b, c0, r01)
        i01 = fmuladd(b, s0, i01)
        r10 = fmuladd(a, c1, r10)
        i10 = fmuladd(a, s1, i10)
        r11 = fmuladd(b, c1, r11)
        i11 = fmuladd(b, s1, i11)
        r20 = fmuladd(a, c2, r20)
        i20 = fmuladd(a, s2, i20)
        r21 = fmuladd(b, c2, r21)
        i21 = fmuladd(b, s2, i21)
        r30 = fmuladd(a, c3, r30)
        i30 = fmuladd(a, s3, i30)
        r31 = fmuladd(b, c3, r31)
        i31 = fmuladd(b, s3, i31)
    F[0], F[1], F[2], F[3] = r00, i00, r01, i01
    F[4], F[5], F[6], F[7] = r10, i10, r11, i11
    F[8], F[9], F[10], F[11] = r20, i20, r21, i21
    F[12], F[13], F[14], F[15] = r30, i30, r31, i31


@njit_inner(cache=True, inline="always")
def _floored(fr, fi, floor):
    """``fr + j fi`` with its magnitude at least ``floor`` (its phase kept; a 0 or NaN: ``floor``)."""
    a2 = fr * fr + fi * fi
    if not a2 >= floor * floor:
        if a2 > 0.0:
            c = floor / np.sqrt(a2)
            return complex(fr * c, fi * c)
        return complex(floor, 0.0)
    return complex(fr, fi)


@njit_inner(cache=True, _nrt=False)
def turned_directions(view, o, M, U, heard):
    """Which of the first ``M`` microphones hear object ``o``'s direction factors, and whose
    direction turned: ``heard[m]`` 0 (not an air microphone, or at the object's centre), 1
    (the factors made for ``U[m]`` are kept) or 2 (``u = R^T (mic - pos) / r`` turned by more
    than the step ``view.params[0].cos_step`` since ``U[m]``, or none was made: NaN; ``U[m]``
    set to ``u``, the factors to be made again). ``view``: a :class:`.drive_lines.SceneView`."""
    mics, pos, R, channels = view.mics, view.pos, view.R, view.channels
    cos_step = view.params[0].cos_step
    for m in range(M):
        heard[m] = 0.0
        if channels[m].owner != AIR:
            continue
        dx = mics[m, 0] - pos[o, 0]
        dy = mics[m, 1] - pos[o, 1]
        dz = mics[m, 2] - pos[o, 2]
        r = np.sqrt(dx * dx + dy * dy + dz * dz)
        if not r > 0.0:
            continue
        ux = (R[o, 0, 0] * dx + R[o, 1, 0] * dy + R[o, 2, 0] * dz) / r
        uy = (R[o, 0, 1] * dx + R[o, 1, 1] * dy + R[o, 2, 1] * dz) / r
        uz = (R[o, 0, 2] * dx + R[o, 1, 2] * dy + R[o, 2, 2] * dz) / r
        heard[m] = 1.0
        if not ux * U[m, 0] + uy * U[m, 1] + uz * U[m, 2] >= cos_step:  # (NaN: never made)
            U[m, 0] = ux
            U[m, 1] = uy
            U[m, 2] = uz
            heard[m] = 2.0


@njit_inner(cache=True, _nrt=False)
def apply_factors(xr, xi, n, M, Fd, heard):
    """``xr + j xi`` (M, :n) times the direction factors ``Fd`` (M, :n) at each microphone that
    hears them (``heard[m] != 0``: :func:`turned_directions`)."""
    for m in range(M):
        if heard[m] == 0.0:
            continue
        for k in range(n):
            f = Fd[m, k]
            gr = xr[m, k]
            gj = xi[m, k]
            xr[m, k] = gr * f.real - gj * f.imag
            xi[m, k] = gr * f.imag + gj * f.real


@njit(cache=True, _nrt=False)
def direction_factors(xr, xi, n, o, view, U, Fd, heard):
    """``xr + j xi`` (M, :n) (object ``o``'s modes, the first at ``m0`` of the flat order) times
    each mode's direction factor towards air microphone ``m`` now, as
    the float64 fits' sums (the tests' reference, ``tests/drive_directions_reference.py``: the same directions, step, floor and cache
    ``U``, ``Fd``; ``heard`` (>= M,) scratch), the factors from the float32 blocks
    ``view.dd`` (:class:`DriveDirections`): the microphones whose direction turned two at a
    time (:func:`sh_pair`, :func:`_chunk_factors`; an odd one paired with itself)."""
    mics, dd = view.mics, view.dd
    floor = view.params[0].floor
    L = view.order[o]
    coef, K, s0 = dd.coef, dd.K[o], dd.off[o]
    Y, F = dd.sh, dd.F
    M = min(xr.shape[0], mics.shape[0])
    turned_directions(view, o, M, U, heard)
    m = 0
    while m < M:
        while m < M and heard[m] != 2.0:
            m += 1
        if m >= M:
            break
        m1 = m + 1
        while m1 < M and heard[m1] != 2.0:
            m1 += 1
        mb = m1 if m1 < M else m
        sh_pair(L, U[m, 0], U[m, 1], U[m, 2], U[mb, 0], U[mb, 1], U[mb, 2], dd.tab, Y[0], Y[1])
        for k0 in range(0, n, 4):
            s = s0 + (k0 // 4) * 8 * K
            _chunk_factors(Y[0], Y[1], coef[s:s + 8 * K], K, F)
            for q in range(min(4, n - k0)):
                Fd[m, k0 + q] = _floored(np.float64(F[4 * q]), np.float64(F[4 * q + 1]), floor)
                Fd[mb, k0 + q] = _floored(np.float64(F[4 * q + 2]), np.float64(F[4 * q + 3]), floor)
        m = m1 + 1
    apply_factors(xr, xi, n, M, Fd, heard)
