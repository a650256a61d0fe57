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

import numpy as np

from ..jit import njit
from .drive_tones import aim_at_drive
from .records import AIR
from .streams import mic_distance, nearest_sorted

__all__ = ["ANCHOR_TOL_M", "bodies_gains"]

#: How far [m] a drive's anchor may move in its body's frame before the nearest surface sample
#: is searched again (a joint's anchor is fixed in the body up to rounding; surface samples are
#: millimetres apart, so a micrometre changes the nearest one only between near ties).
ANCHOR_TOL_M = 1e-6


@njit(cache=True)
def bodies_gains(ks, act, bg, anchor, axis, k0, regain):
    """Per driven body ``b``: ``act.sign[b]`` (the strongest acting drive's side sign, +1 the
    joint's body, -1 its parent; 0 where no drive acts), its stream's point and direction
    (``streams.table[s].p, n``: what the exact broadband rendering's gains are made for), and
    its gains ``bg.gr + j bg.gi`` (B, M, nmax), as the input gain ``bg.gin`` (B, nmax) times
    the output factor ``bg.gout`` (B, M, nmax), and integer delays ``bg.D`` (B, M) [samples]
    (module docstring; 0 beyond its modes, and everywhere for a body whose object has no
    points or modes). Returns whether some body is driven.

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
    gr, gi, gout, D, dfac, loc, near = bg.gr, bg.gi, bg.gout, bg.D, bg.dfac, bg.loc, bg.near
    nmax = gr.shape[2]
    M = min(gr.shape[1], ks.mics.shape[0])
    fs, c, rmin = cst.fs, cst.c, cst.rmin
    tol2 = ANCHOR_TOL_M * ANCHOR_TOL_M
    nrm = np.empty(3)
    gq = np.empty(nmax)
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
            bg.gin[b, k] = 0.0
        if n == 0:
            continue
        m0 = ob.mode_off[o]
        pos = ks.pos[o]
        R = ks.R[o]
        pl0 = pl1 = pl2 = d0 = d1 = d2 = 0.0
        for q in range(3):
            x = anchor[jt, q] - pos[q]
            pl0 += x * R[q, 0]
            pl1 += x * R[q, 1]
            pl2 += x * R[q, 2]
            v = rec.n[q]
            d0 += v * R[q, 0]
            d1 += v * R[q, 1]
            d2 += v * R[q, 2]
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
        for k in range(n):
            G = d0 * shk[sb + k] + d1 * shk[sb + n + k] + d2 * shk[sb + 2 * n + k]
            gq[k] = G / (fs * ob.wd[m0 + k])
            bg.gin[b, k] = gq[k] if np.isfinite(gq[k]) else 0.0
        for m in range(M):
            owner = ks.channels[m].owner
            if owner != AIR:  # (a contact microphone: its own object only, no delay)
                w_off = ks.channels[m].w_off
                for k in range(n):
                    if owner == o:
                        h = ks.chan_w[w_off + k]
                        a = gq[k] * h
                        ok = np.isfinite(a.real) and np.isfinite(a.imag)
                        gr[b, m, k] = a.real if ok else 0.0
                        gi[b, m, k] = a.imag if ok else 0.0
                        gout[b, m, k] = h if ok else 0.0
                    else:
                        gr[b, m, k] = 0.0
                        gi[b, m, k] = 0.0
                        gout[b, m, k] = 0.0
                continue
            r = mic_distance(ks.mics, m, pos, rmin)
            ta = r / c
            Dm = np.int64(np.ceil(ta * fs - cst.tol)) if np.isfinite(ta) else 0
            if Dm < 0:
                Dm = 0
            D[b, m] = Dm
            dts = Dm / fs - ta
            fresh = not (bg.dts[b, m] == dts)  # (the delay factors depend on dts alone: a body at rest keeps them)
            bg.dts[b, m] = dts
            refl = ks.channels[m].w_off  # (>= 0: an image microphone, its reflection per mode)
            for k in range(n):
                if fresh:
                    z = ob.lam[m0 + k] * dts
                    e = np.exp(z.real)
                    dfac[b, m, k] = complex(e * np.cos(z.imag), e * np.sin(z.imag))
                h = ob.w[m0 + k] / r
                if refl >= 0:
                    h *= ks.chan_w[refl + m0 + k].real
                f = dfac[b, m, k]
                x = gq[k] * h * f.real
                y = gq[k] * h * f.imag
                ok = np.isfinite(x) and np.isfinite(y)
                gr[b, m, k] = x if ok else 0.0  # (a bad pose or point: silence, never NaN)
                gi[b, m, k] = y if ok else 0.0
                gout[b, m, k] = h * f if ok else 0.0
    return any_driven
