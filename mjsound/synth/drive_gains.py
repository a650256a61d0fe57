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
the sub-sample rest ``dts_m = D_m / fs - r_m / c`` [s] as each mode's factor (its exp, cosine
and sine made again only when ``dts_m`` changed: a body at rest keeps them).

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
from .drive_tones import aim_at_drive
from .records import AIR
from .streams import nearest_sorted

__all__ = ["ANCHOR_TOL_M", "FACTOR_ZMAX", "FACTOR_TERMS", "factors_into", "delay_factors", "bodies_gains"]

#: How far [m] a drive's anchor may move in its body's frame before the nearest surface sample
#: is searched again (a joint's anchor is fixed in the body up to rounding; surface samples are
#: millimetres apart, so a micrometre changes the nearest one only between near ties).
ANCHOR_TOL_M = 1e-6


#: :func:`delay_factors` makes ``e^z`` by series for ``|Re z|, |Im z|`` up to this (a mode
#: below the Nyquist frequency over at most one sample has ``|Im z| <= pi``); a larger or
#: non-finite ``z`` takes libm's ``exp``, ``cos``, ``sin`` (as the exact rendering does).
FACTOR_ZMAX = 64.0

#: Terms of :func:`_even_odd`'s series on ``|u| <= 1``: those up to ``u^19``; the first left
#: out is below ``1 / 20! < 5e-19``, under an ulp of the result.
FACTOR_TERMS = 10


#: The series' coefficients ``1 / (2 i)!`` and ``1 / (2 i + 1)!``, ``i < FACTOR_TERMS``.
_EVEN = np.array([1.0 / math.factorial(2 * i) for i in range(FACTOR_TERMS)])
_ODD = np.array([1.0 / math.factorial(2 * i + 1) for i in range(FACTOR_TERMS)])


@njit(cache=True, inline="always", fastmath={"contract"})
def _even_odd(u, sgn):
    """``(cos u, sin u)`` (``sgn = -1``) or ``(cosh u, sinh u)`` (``sgn = 1``) for ``|u| <= 1``,
    by their series ``sum_i (sgn t)^i / (2 i)!`` and ``u sum_i (sgn t)^i / (2 i + 1)!``,
    ``t = u^2``, to :data:`FACTOR_TERMS` terms in Horner's form (a fused multiply-add a term:
    a loop over many ``u`` vectorises)."""
    t = sgn * u * u
    ev = _EVEN[FACTOR_TERMS - 1]
    od = _ODD[FACTOR_TERMS - 1]
    for i in range(FACTOR_TERMS - 2, -1, -1):
        ev = _EVEN[i] + t * ev
        od = _ODD[i] + t * od
    return ev, u * od


@njit(cache=True, inline="always", fastmath={"contract"})
def factors_into(lam, m0, n, dts, out, b, m):
    """``out[b, m, k] = e^{z_k}``, ``z_k = lam[m0 + k] dts``, ``k < n`` (``lam`` complex128
    [1/s], ``dts`` [s], ``out`` (B, M, nmax) complex128: indexed in place, no view made): where
    every ``|Re z|, |Im z| <= ``:data:`FACTOR_ZMAX`, by scaling and squaring,

        e^z = w^(2^s),   w = e^{z / 2^s} = (cosh x + sinh x) (cos y + j sin y),   x + j y = z / 2^s

    ``s`` the least with ``|x|, |y| <= 1`` for all ``k`` (the scaling is exact; the series:
    :func:`_even_odd`); else (one larger or not finite) ``e^{Re z} (cos Im z + j sin Im z)``
    for each. A squaring doubles the relative error: the factors hold a few ulps (``2^s``;
    ``s <= 2`` for ``|z| <= 4``). Unlike libm's ``exp``, ``cos``, ``sin`` (a call each per
    ``z``: numba has no vector forms of them without SVML) the loops vectorise."""
    zmax = 0.0
    for k in range(n):
        z = lam[m0 + k]
        a = max(abs(z.real * dts), abs(z.imag * dts))
        zmax = a if not a <= zmax else zmax  # (NaN: taken, so it fails the range below)
    if not zmax <= FACTOR_ZMAX:
        for k in range(n):
            z = lam[m0 + k]
            e = np.exp(z.real * dts)
            out[b, m, k] = complex(e * np.cos(z.imag * dts), e * np.sin(z.imag * dts))
        return
    s = 0
    p2 = 1.0
    while zmax * p2 > 1.0:
        s += 1
        p2 *= 0.5
    scale = dts * p2
    for k in range(n):
        z = lam[m0 + k]
        ch, sh = _even_odd(z.real * scale, 1.0)
        co, si = _even_odd(z.imag * scale, -1.0)
        e = ch + sh
        out[b, m, k] = complex(e * co, e * si)
    for _ in range(s):
        for k in range(n):
            out[b, m, k] = out[b, m, k] * out[b, m, k]


@njit(cache=True)
def delay_factors(lam, dts):
    """``e^{lam dts}`` ((n,) complex128) for poles ``lam`` ((n,) complex128 [1/s]) and a delay
    ``dts`` [s], as :func:`bodies_gains` makes them (:func:`factors_into`).

    Example: ``delay_factors(np.array([1j * np.pi]), 1.0)`` is ``[-1 + ~1e-16j]``.
    """
    n = lam.shape[0]
    out = np.empty((1, 1, n), np.complex128)
    factors_into(lam, 0, n, dts, out, 0, 0)
    return out[0, 0]


@njit(cache=True)
def bodies_gains(ks, act, bg, anchor, axis, k0, regain):
    """Per driven body ``b``: ``act.sign[b]`` (the strongest acting drive's side sign, +1 the
    joint's body, -1 its parent; 0 where no drive acts), its stream's point and direction
    (``streams.table[s].p, n``: what the exact broadband rendering's gains are made for), and
    its gains ``bg.gr + j bg.gi`` (B, M, nmax), as the input gain ``bg.gin`` (B, nmax) times
    the output factor ``bg.gout`` (B, M, nmax), and integer delays ``bg.D`` (B, M) [samples]
    (module docstring; 0 beyond its modes, and everywhere for a body whose object has no
    points or modes). Returns whether some body is driven. The delay factors made again
    (a moving body's ``dts`` changes every block): :func:`delay_factors`, a microphone's modes
    at once (their arguments ``lam_k dts`` in ``bg.gr, gi`` first).

    Parameters
    ----------
    ks : :class:`.records.SynthState` (objects, poses, microphones, channels, constants, streams)
    act : :class:`.drive_lines.Actuators` (``acting``, ``a1``: which drives act, how strongly)
    bg : :class:`.drive_lines.BodyGains` (``loc``, ``near``: each drive side's last searched
        anchor in its body's frame [m] (NaN: none yet) and its nearest sample; ``dts``,
        ``dfac``: the sub-sample delays [s] the delay factors were made for, and those)
    anchor, axis : (n_joints, 3) float64, MuJoCo's ``data.xanchor``, ``data.xaxis``
    """
    ob, cst, st = ks.objects, ks.consts[0], ks.streams
    sidx, ptr, rows, sign, drives = act.sidx, act.ptr, act.rows, act.sign, act.drives
    gr, gi, gin, gout, D, dfac, loc, near = bg.gr, bg.gi, bg.gin, bg.gout, bg.D, bg.dfac, bg.loc, bg.near
    nmax = gr.shape[2]
    M = min(gr.shape[1], ks.mics.shape[0])
    fs, c, rmin = cst.fs, cst.c, cst.rmin
    tol2 = ANCHOR_TOL_M * ANCHOR_TOL_M
    nrm = np.empty(3)
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
        sg, jt, due = aim_at_drive(rec, rows[best], drives, axis, anchor, k0, regain, nrm)
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
            v = nrm[q] * sg
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
        for m in range(M):
            owner = ks.channels[m].owner
            if owner != AIR:  # (a contact microphone: its own object only, no delay)
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
            r = r if r >= rmin else rmin  # (streams.mic_distance, without its view of the pose)
            ta = r / c
            Dm = np.int64(np.ceil(ta * fs - cst.tol)) if np.isfinite(ta) else 0
            if Dm < 0:
                Dm = 0
            D[b, m] = Dm
            dts = Dm / fs - ta
            if not (bg.dts[b, m] == dts):  # (the delay factors depend on dts alone: a body at rest keeps them)
                bg.dts[b, m] = dts
                factors_into(ob.lam, m0, n, dts, dfac, b, m)
            refl = ks.channels[m].w_off  # (>= 0: an image microphone, its reflection per mode)
            for k in range(n):
                h = ob.w[m0 + k] / r
                if refl >= 0:
                    h *= ks.chan_w[refl + m0 + k].real
                f = dfac[b, m, k]
                x = gin[b, k] * h * f.real
                y = gin[b, k] * h * f.imag
                ok = np.isfinite(x) and np.isfinite(y)
                gr[b, m, k] = x if ok else 0.0  # (a bad pose or point: silence, never NaN)
                gi[b, m, k] = y if ok else 0.0
                gout[b, m, k] = h * f if ok else 0.0
        for k in range(n):
            gin[b, k] = gin[b, k] if np.isfinite(gin[b, k]) else 0.0
    return any_driven
