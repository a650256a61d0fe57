"""The driven bodies' gains for the lines' rendering (:mod:`.drive_lines`), made once per block.

A driven body ``b`` (object ``o``, pose ``pos, R``) is pushed at the anchor ``p`` of its
strongest acting drive (the largest force scale), along that drive's direction ``n`` times
its side's sign (:func:`.drive_tones.drive_direction`; as :func:`.drive_tones.streams_write`
aims the exact rendering's stream). Its gain per mode ``k`` at microphone ``m`` is the
sliding streams' (:func:`.streams.stream_gains`, the exact rendering's):

    G_k = phi_k(x) . R^T n,   x the surface sample nearest to R^T (p - pos),
    g_mk = G_k / (fs wd_k) w_k / r_m e^{lam_k dts_m}   (air; an image microphone times its reflection),
    g_mk = G_k / (fs wd_k) c_mk                        (a contact microphone on o, c its weights; 0 on others),

(an input gain ``G_k / (fs wd_k)`` times an output factor per microphone), with the integer
delay ``D_m = ceil(r_m fs / c)`` [samples] (0 at a contact microphone) and
the sub-sample rest ``dts_m = D_m / fs - r_m / c`` [s] as each mode's factor ``e^{lam_k dts_m}``
(a moving body's ``dts_m`` changes every block: made each time, all of a body's at once by a
series that vectorises, :func:`exp_in_place`, instead of libm's exp, cosine and sine a mode).

**Reference counts**: :func:`bodies_gains` is compiled without numba's reference counting
(``_nrt=False``; it allocates nothing): a kernel taking the state records otherwise adds one
to and drops one from the count of every array they hold (~100, an atomic add each) at each
call, and again for each view it makes.

**The anchor is fixed in the body** (a hinge's anchor is fixed in both bodies it joins; a
slide's in the joint's body), so the nearest surface sample is searched again only when the
anchor moved more than :data:`ANCHOR_TOL_M` in the body's frame since the last search for
that drive side (kept per side in ``BodyGains.loc`` / ``near``); every block refreshes only
the direction in the body's frame and the microphones' distances.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .bank_loops import fma
from .drive_tones import aim_at_drive
from .records import AIR
from .streams import nearest_sorted

__all__ = ["ANCHOR_TOL_M", "FACTOR_RANGE", "FACTOR_TERMS", "exp_in_place", "delay_factors", "bodies_gains"]

#: How far [m] a drive's anchor may move in its body's frame before the nearest surface sample
#: is searched again (a joint's anchor is fixed in the body up to rounding; surface samples are
#: millimetres apart, so a micrometre changes the nearest one only between near ties).
ANCHOR_TOL_M = 1e-6


#: :func:`exp_in_place` makes ``e^z`` as ``(e^{z/4})^4`` by series where every ``|Re z|, |Im z|``
#: is at most this (a mode below the Nyquist frequency over at most one sample has ``|Im z| <
#: pi``; its damping ``|Re z| <= 4`` while under 4 fs [1/s]); else by libm's ``exp``, ``cos``,
#: ``sin`` (as the exact rendering does).
FACTOR_RANGE = 4.0

#: Terms of :func:`_even_odd`'s series on ``|u| <= 1``: those up to ``u^19``; the first left
#: out is below ``1 / 20! < 5e-19``, under an ulp of the result.
FACTOR_TERMS = 10


#: The series' coefficients ``1 / (2 i)!`` and ``1 / (2 i + 1)!``, ``i < FACTOR_TERMS``.
_EVEN = np.array([1.0 / math.factorial(2 * i) for i in range(FACTOR_TERMS)])
_ODD = np.array([1.0 / math.factorial(2 * i + 1) for i in range(FACTOR_TERMS)])


@njit(cache=True, inline="always")
def _even_odd(u, sgn):
    """``(cos u, sin u)`` (``sgn = -1``) or ``(cosh u, sinh u)`` (``sgn = 1``) for ``|u| <= 1``,
    by their series ``sum_i (sgn t)^i / (2 i)!`` and ``u sum_i (sgn t)^i / (2 i + 1)!``,
    ``t = u^2``, to :data:`FACTOR_TERMS` terms in Horner's form, a fused multiply-add a term
    (:func:`.bank_loops.fma`, explicit: a kernel inlined into another is compiled with the
    caller's flags, so ``fastmath={"contract"}`` here was lost in :func:`bodies_gains`, which
    multiplied and added apart: twice the operations and the latency); a loop over many ``u``
    vectorises."""
    t = sgn * u * u
    ev = _EVEN[FACTOR_TERMS - 1]
    od = _ODD[FACTOR_TERMS - 1]
    for i in range(FACTOR_TERMS - 2, -1, -1):
        ev = fma(t, ev, _EVEN[i])
        od = fma(t, od, _ODD[i])
    return ev, u * od


@njit(cache=True, inline="always")
def exp_in_place(z):
    """``z = e^z`` for each of ``z`` ((n,) complex128, written in place): where every ``|Re z|,
    |Im z| <= ``:data:`FACTOR_RANGE`, by scaling and squaring,

        e^z = w^4,   w = e^{z / 4} = (cosh x + sinh x) (cos y + j sin y),   x + j y = z / 4,

    (the scaling is exact; the series: :func:`_even_odd`), in one loop that vectorises (over
    the real and imaginary parts as float64 pairs); else (one larger or not finite)
    ``e^{Re z} (cos Im z + j sin Im z)`` for each, by libm (a call each per ``z``: numba has
    no vector forms without SVML). The two squarings make the factors' relative error a few
    ulps (``tests/test_drive_gains.py``: under 3e-15)."""
    n = z.shape[0]
    v = z.view(np.float64)  # (re, im pairs: numba's complex loads and stores do not vectorise)
    out = 0
    for q in range(n):  # (a count, not a branch: the check vectorises too)
        out += not (abs(v[2 * q]) <= FACTOR_RANGE and abs(v[2 * q + 1]) <= FACTOR_RANGE)
    if out:
        for q in range(n):
            x, y = v[2 * q], v[2 * q + 1]
            e = np.exp(x)
            v[2 * q] = e * np.cos(y)
            v[2 * q + 1] = e * np.sin(y)
        return
    for q in range(n):
        ch, sh = _even_odd(v[2 * q] * 0.25, 1.0)
        co, si = _even_odd(v[2 * q + 1] * 0.25, -1.0)
        e = ch + sh
        wr, wi = e * co, e * si
        wr, wi = wr * wr - wi * wi, 2.0 * wr * wi
        v[2 * q] = wr * wr - wi * wi
        v[2 * q + 1] = 2.0 * wr * wi


@njit(cache=True)
def delay_factors(lam, dts):
    """``e^{lam dts}`` ((n,) complex128) for poles ``lam`` ((n,) complex128 [1/s]) and a delay
    ``dts`` [s], as :func:`bodies_gains` makes them (:func:`exp_in_place`).

    Example: ``delay_factors(np.array([1j * np.pi]), 1.0)`` is ``[-1 + ~1e-16j]``.
    """
    z = lam * dts
    exp_in_place(z)
    return z


@njit(cache=True, _nrt=False)
def bodies_gains(ks, act, bg, anchor, axis, k0, regain):
    """Per driven body ``b``: ``act.sign[b]`` (the strongest acting drive's side sign, +1 the
    joint's body, -1 its parent; 0 where no drive acts), its stream's point and direction
    (``streams.table[s].p, n``: what the exact broadband rendering's gains are made for), and
    its gains ``bg.gr + j bg.gi`` (B, M, nmax), as the input gain ``bg.gin`` (B, nmax) times
    the output factor ``bg.gout`` (B, M, nmax), and integer delays ``bg.D`` (B, M) [samples]
    (module docstring; 0 beyond its modes, and everywhere for a body whose object has no
    points or modes). Returns whether some body is driven. The delay factors: each air
    microphone's arguments ``lam_k dts_m`` into the body's row of ``bg.dfac`` (packed:
    microphone ``m``'s modes at ``m n``), then :func:`exp_in_place` of them all.

    Parameters
    ----------
    ks : :class:`.records.SynthState` (objects, poses, microphones, channels, constants, streams)
    act : :class:`.drive_lines.Actuators` (``acting``, ``a1``: which drives act, how strongly)
    bg : :class:`.drive_lines.BodyGains` (``loc``, ``near``: each drive side's last searched
        anchor in its body's frame [m] (NaN: none yet) and its nearest sample; ``dts``: the
        sub-sample delays [s] of the last gains made; ``dfac``: their factors, packed)
    anchor, axis : (n_joints, 3) float64, MuJoCo's ``data.xanchor``, ``data.xaxis``
    """
    ob, cst, st = ks.objects, ks.consts[0], ks.streams
    sidx, ptr, rows, sign, drives = act.sidx, act.ptr, act.rows, act.sign, act.drives
    gr, gi, gin, gout, D, dfac, loc, near = bg.gr, bg.gi, bg.gin, bg.gout, bg.D, bg.dfac, bg.loc, bg.near
    nmax = gr.shape[2]
    M = min(gr.shape[1], ks.mics.shape[0])
    fs, c, rmin = cst.fs, cst.c, cst.rmin
    tol2 = ANCHOR_TOL_M * ANCHOR_TOL_M
    any_driven = False
    for b in range(sidx.shape[0]):
        sign[b] = 0.0
        s = sidx[b]
        if s < 0:
            continue
        best = -1
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            if act.acting[j] and (best < 0 or act.a1[j] > act.a1[rows[best] // 2]):
                best = i
        if best < 0:
            continue
        rec = st.table[s]
        # (the direction made into the record's own n, which stream_aim then turns by the side's sign)
        sg, jt, due = aim_at_drive(rec, rows[best], drives, axis, anchor, k0, regain, rec.n)
        sign[b] = sg
        any_driven = True
        if not due:
            continue  # (its gains are made every ``regain`` samples, as the exact rendering's)
        rec.due = 0  # (made here, not by the synthesizer)
        o = rec.obj
        n = 0
        if rec.live and o + 1 < ob.pts_off.shape[0] and ob.pts_off[o + 1] > ob.pts_off[o]:
            n = ob.mode_off[o + 1] - ob.mode_off[o]
        for m in range(gr.shape[1]):
            D[b, m] = 0
            for k in range(n, nmax):
                gr[b, m, k] = 0.0
                gi[b, m, k] = 0.0
                gout[b, m, k] = 0.0
        for k in range(n, nmax):
            gin[b, k] = 0.0
        if n == 0:
            continue
        m0 = ob.mode_off[o]
        pl0 = pl1 = pl2 = d0 = d1 = d2 = 0.0
        for q in range(3):  # (no views made in this loop: each costs a reference count's atomic add and drop)
            x = anchor[jt, q] - ks.pos[o, q]
            pl0 += x * ks.R[o, q, 0]
            pl1 += x * ks.R[o, q, 1]
            pl2 += x * ks.R[o, q, 2]
            v = rec.n[q]
            d0 += v * ks.R[o, q, 0]
            d1 += v * ks.R[o, q, 1]
            d2 += v * ks.R[o, q, 2]
        e0 = pl0 - loc[best, 0]
        e1 = pl1 - loc[best, 1]
        e2 = pl2 - loc[best, 2]
        if not e0 * e0 + e1 * e1 + e2 * e2 <= tol2:  # (NaN: never searched)
            p0, p1 = ob.pts_off[o], ob.pts_off[o + 1]
            near[best] = nearest_sorted(ob.pts[p0:p1], ob.pts_index[p0:p1], ob.pts_axis[o], pl0, pl1, pl2)
            loc[best, 0] = pl0
            loc[best, 1] = pl1
            loc[best, 2] = pl2
        sb = ob.shk_off[o] + 3 * near[best] * n  # (shapes of o: flat (points, 3, modes))
        shk = ob.shk
        for k in range(n):  # (the input gains as made, until the microphones' gains are: then 0 where not finite)
            G = d0 * shk[sb + k] + d1 * shk[sb + n + k] + d2 * shk[sb + 2 * n + k]
            gin[b, k] = G / (fs * ob.wd[m0 + k])
        # the delay factors: first each air microphone's arguments z = lam dts (0 at a contact
        # microphone), packed (microphone m's modes at m n), then e^z for all of them at once
        fac = dfac[b].reshape(dfac.shape[1] * nmax)  # (a view of the body's row: no copy)
        for m in range(M):
            if ks.channels[m].owner != AIR:  # (a contact microphone: its own object only, no delay)
                for k in range(n):
                    fac[m * n + k] = 0.0
                continue
            dx = ks.mics[m, 0] - ks.pos[o, 0]
            dy = ks.mics[m, 1] - ks.pos[o, 1]
            dz = ks.mics[m, 2] - ks.pos[o, 2]
            r = np.sqrt(dx * dx + dy * dy + dz * dz)
            r = r if r >= rmin else rmin  # (streams.mic_distance, without its view of the pose)
            ta = r / c
            Dm = np.int64(np.ceil(ta * fs - cst.tol)) if np.isfinite(ta) else 0
            if Dm < 0:
                Dm = 0
            D[b, m] = Dm
            dts = Dm / fs - ta
            bg.dts[b, m] = dts
            for k in range(n):
                fac[m * n + k] = ob.lam[m0 + k] * dts
        exp_in_place(fac[:M * n])
        for m in range(M):
            owner = ks.channels[m].owner
            if owner != AIR:
                w_off = ks.channels[m].w_off
                for k in range(n):
                    if owner == o:
                        h = ks.chan_w[w_off + k]
                        a = gin[b, k] * h
                        ok = np.isfinite(a.real) and np.isfinite(a.imag)
                        gr[b, m, k] = a.real if ok else 0.0
                        gi[b, m, k] = a.imag if ok else 0.0
                        gout[b, m, k] = h if ok else 0.0
                    else:
                        gr[b, m, k] = 0.0
                        gi[b, m, k] = 0.0
                        gout[b, m, k] = 0.0
                continue
            dx = ks.mics[m, 0] - ks.pos[o, 0]
            dy = ks.mics[m, 1] - ks.pos[o, 1]
            dz = ks.mics[m, 2] - ks.pos[o, 2]
            r = np.sqrt(dx * dx + dy * dy + dz * dz)
            r = r if r >= rmin else rmin
            refl = ks.channels[m].w_off  # (>= 0: an image microphone, its reflection per mode)
            for k in range(n):
                h = ob.w[m0 + k] / r
                if refl >= 0:
                    h *= ks.chan_w[refl + m0 + k].real
                f = fac[m * n + k]
                x = gin[b, k] * h * f.real
                y = gin[b, k] * h * f.imag
                ok = np.isfinite(x) and np.isfinite(y)
                gr[b, m, k] = x if ok else 0.0  # (a bad pose or point: silence, never NaN)
                gi[b, m, k] = y if ok else 0.0
                gout[b, m, k] = h * f if ok else 0.0
        for k in range(n):
            gin[b, k] = gin[b, k] if np.isfinite(gin[b, k]) else 0.0
    return any_driven
