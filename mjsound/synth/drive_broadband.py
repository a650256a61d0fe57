"""The broadband part of actuator noise through the links' modes, where their resonance makes
it heard (:mod:`.drive_lines` renders everything else without running a mode).

The lines' rendering hears an actuator's broadband force ``a b y`` (``y`` unit noise
low-passed at ``f_c``) through its bodies' static response ``Im H(0)``. A lightly damped mode
``i`` also rings with the noise's part at its own frequency: its power there is
``|g_i|^2 S(theta_i) / (2 (1 - |p_i|^2))`` (a resonator ``z <- p (z + g x)`` driven by noise of
power spectrum ``S``: ``S(theta) = alpha^2 / |1 - (1 - alpha) e^{-j theta}|^2`` for the
one-pole low-pass, ``alpha = 1 - e^{-2 pi f_c / fs}``). Where that resonant power exceeds
:data:`RESONANT_ON` of everything the actuator makes heard (summed over the microphones;
back below :data:`RESONANT_OFF`), the actuator's broadband part goes through the modes as the
exact rendering does, but only through the fewest modes of each body holding all but
:data:`RESONANT_REST` of its resonant power (:func:`broadband_modes`); their static part stays
with the lines. Those modes run here, in the lines' kernel (:func:`broadband_resonant`: the
exact rendering's recursion ``z <- p z + f``, heard as ``Im(g z)`` at each microphone's
delay, into the pulse track); a mode whose force stops rings on over one more block, faded
out linearly (the exact rendering's modes ring out freely: the lines leave out that ring-out
for the tones too).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .bank_loops import FAST
from .drive_tones import noise_cutoff_hz
from .records import AIR
from .streams import SQRT3, noise_draw

__all__ = ["RESONANT_ON", "RESONANT_OFF", "RESONANT_REST", "broadband_modes", "broadband_force",
           "broadband_resonant"]

#: Fraction of an actuator's heard power in the modes' resonant response to its broadband
#: part above which that part goes through the modes (-10 dB) ...
RESONANT_ON = 0.1
#: ... and below which it goes back to the static response (-16 dB; between: as it was).
RESONANT_OFF = 0.025
#: The share of a body's resonant broadband power its dropped modes may hold (-20 dB).
RESONANT_REST = 0.01


@njit(cache=True)
def broadband_modes(act, lw, bg):
    """The modes that carry the broadband parts of the actuators ``lw.exact``: on each body
    with one, the fewest modes holding all but :data:`RESONANT_REST` of the body's resonant
    power (``bg.resonant``, :func:`.drive_weights.line_weights`) are kept (``bg.keep``: they run,
    :func:`broadband_resonant`); their static part stays with the lines: ``lw.B1[j]`` of an
    exact actuator is the static response of its bodies' other modes. Returns the modes kept."""
    sidx, sign, ptr, rows = act.sidx, act.sign, act.ptr, act.rows
    exact, static, resonant, keep, B = lw.exact, bg.static, bg.resonant, bg.keep, lw.B1
    nb, M, nmax = bg.gr.shape
    J = B.shape[0]
    for j in range(J):
        if exact[j]:
            for m in range(M):
                B[j, m] = 0.0
    kept = 0
    for b in range(nb):
        for k in range(nmax):
            keep[b, k] = False
        if sidx[b] < 0 or sign[b] == 0.0:
            continue
        on = False
        for i in range(ptr[b], ptr[b + 1]):
            if exact[rows[i] // 2]:
                on = True
        if not on:
            continue
        total = 0.0
        for k in range(nmax):
            total += resonant[b, k]
        rest = total
        while rest > RESONANT_REST * total:  # (the strongest left, until the rest is small)
            best = -1
            for k in range(nmax):
                if not keep[b, k] and (best < 0 or resonant[b, k] > resonant[b, best]):
                    best = k
            if best < 0 or resonant[b, best] <= 0.0:
                break
            keep[b, best] = True
            rest -= resonant[b, best]
            kept += 1
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            if exact[j]:
                coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
                for m in range(M):
                    for k in range(nmax):
                        if not keep[b, k]:
                            B[j, m] += coef * static[b, m, k]
    return kept


@njit(cache=True)
def broadband_force(act, lw, fs, F):
    """The broadband force ``a b y`` of each actuator ``lw.exact`` into ``F[j]`` (J, L), as
    :func:`.drive_tones.drive_tones` makes it (its noise state advances); the others' rows
    are left as they are."""
    J, L = F.shape
    comp_off, tones, noise, w0, w1, a0, a1 = act.comp_off, act.tones, act.noise, act.w0, act.w1, act.a0, act.a1
    two_pi = 2.0 * math.pi
    for j in range(J):
        if not lw.exact[j] or (a0[j] == 0.0 and a1[j] == 0.0):
            continue
        fc = noise_cutoff_hz(tones, comp_off, j, 0.5 * (w0[j] + w1[j]), fs)
        alpha = 1.0 - math.exp(-two_pi * fc / fs)
        state = np.uint64(noise[j].rng)
        y = noise[j].lp
        b = noise[j].broadband
        da = (a1[j] - a0[j]) / L
        for q in range(L):
            state, x = noise_draw(state)
            y = alpha * (x * SQRT3) + (1.0 - alpha) * y
            F[j, q] = (a0[j] + da * q) * b * y
        noise[j].rng = np.int64(state)
        noise[j].lp = y


@njit(cache=True, fastmath=FAST)
def _resonant_run(out, f, K, pr, pi, gin, hr, hi, ur, wr, wi):
    """``K`` modes over ``f``'s samples (L,): per sample ``w <- p (w + g f)`` (``g = gin``,
    the input gain), heard at microphone ``m`` as ``out[m] += Im(h_m w)`` (``h = hr + j hi``
    (M, K), its output factor), their states ``wr + j wi`` updated. A mode with ``ur = 0``
    fades out linearly over the samples (1 to 0), one with ``ur = 1`` does not. Four modes at
    a time, their states held in registers, so that their recursions overlap."""
    M, L = out.shape
    inv = 1.0 / L
    r = 0
    while r < K:
        n = min(4, K - r)
        a0r, a0i, p0r, p0i, g0 = wr[r], wi[r], pr[r], pi[r], gin[r]
        a1r = a1i = p1r = p1i = g1 = 0.0  # (absent modes of a short group: all 0)
        a2r = a2i = p2r = p2i = g2 = 0.0
        a3r = a3i = p3r = p3i = g3 = 0.0
        if n > 1:
            a1r, a1i, p1r, p1i, g1 = wr[r + 1], wi[r + 1], pr[r + 1], pi[r + 1], gin[r + 1]
        if n > 2:
            a2r, a2i, p2r, p2i, g2 = wr[r + 2], wi[r + 2], pr[r + 2], pi[r + 2], gin[r + 2]
        if n > 3:
            a3r, a3i, p3r, p3i, g3 = wr[r + 3], wi[r + 3], pr[r + 3], pi[r + 3], gin[r + 3]
        # (each microphone's output factors: the steady modes' and the fading ones' apart)
        H = np.zeros((M, 16))
        for m in range(M):
            for i in range(n):
                u = ur[r + i]
                H[m, 2 * i] = u * hr[m, r + i]
                H[m, 2 * i + 1] = u * hi[m, r + i]
                H[m, 8 + 2 * i] = (1.0 - u) * hr[m, r + i]
                H[m, 9 + 2 * i] = (1.0 - u) * hi[m, r + i]
        fading = False
        for i in range(n):
            fading = fading or ur[r + i] != 1.0
        if n == 1 and not fading:  # (a lone steady mode: its own loop)
            for m in range(M):
                c = H[m]
                o = out[m]
                h0r, h0i = c[0], c[1]
                xr, xi = a0r, a0i
                for q in range(L):
                    br = xr + g0 * f[q]
                    o[q] += h0r * xi + h0i * br
                    xr, xi = br * p0r - xi * p0i, xi * p0r + br * p0i
            for q in range(L):
                br = a0r + g0 * f[q]
                a0r, a0i = br * p0r - a0i * p0i, a0i * p0r + br * p0i
        elif not fading and M == 2:  # (the common case, two microphones: their factors in registers)
            c0, c1, c2, c3, c4, c5, c6, c7 = H[0, 0], H[0, 1], H[0, 2], H[0, 3], H[0, 4], H[0, 5], H[0, 6], H[0, 7]
            e0, e1, e2, e3, e4, e5, e6, e7 = H[1, 0], H[1, 1], H[1, 2], H[1, 3], H[1, 4], H[1, 5], H[1, 6], H[1, 7]
            o0 = out[0]
            o1 = out[1]
            for q in range(L):
                fq = f[q]
                b0r = a0r + g0 * fq
                b1r = a1r + g1 * fq
                b2r = a2r + g2 * fq
                b3r = a3r + g3 * fq
                o0[q] += c0 * a0i + c1 * b0r + c2 * a1i + c3 * b1r + c4 * a2i + c5 * b2r + c6 * a3i + c7 * b3r
                o1[q] += e0 * a0i + e1 * b0r + e2 * a1i + e3 * b1r + e4 * a2i + e5 * b2r + e6 * a3i + e7 * b3r
                a0r, a0i = b0r * p0r - a0i * p0i, a0i * p0r + b0r * p0i
                a1r, a1i = b1r * p1r - a1i * p1i, a1i * p1r + b1r * p1i
                a2r, a2i = b2r * p2r - a2i * p2i, a2i * p2r + b2r * p2i
                a3r, a3i = b3r * p3r - a3i * p3i, a3i * p3r + b3r * p3i
        elif not fading:  # (every mode of the group steady)
            for q in range(L):
                fq = f[q]
                b0r = a0r + g0 * fq
                b1r = a1r + g1 * fq
                b2r = a2r + g2 * fq
                b3r = a3r + g3 * fq
                for m in range(M):
                    h = H[m]
                    out[m, q] += h[0] * a0i + h[1] * b0r + h[2] * a1i + h[3] * b1r + h[4] * a2i + h[5] * b2r \
                        + h[6] * a3i + h[7] * b3r
                a0r, a0i = b0r * p0r - a0i * p0i, a0i * p0r + b0r * p0i
                a1r, a1i = b1r * p1r - a1i * p1i, a1i * p1r + b1r * p1i
                a2r, a2i = b2r * p2r - a2i * p2i, a2i * p2r + b2r * p2i
                a3r, a3i = b3r * p3r - a3i * p3i, a3i * p3r + b3r * p3i
        else:
            for q in range(L):
                fq = f[q]
                b0r = a0r + g0 * fq
                b1r = a1r + g1 * fq
                b2r = a2r + g2 * fq
                b3r = a3r + g3 * fq
                fade = (L - q) * inv
                for m in range(M):
                    h = H[m]
                    y = h[0] * a0i + h[1] * b0r + h[2] * a1i + h[3] * b1r + h[4] * a2i + h[5] * b2r + h[6] * a3i \
                        + h[7] * b3r
                    z = h[8] * a0i + h[9] * b0r + h[10] * a1i + h[11] * b1r + h[12] * a2i + h[13] * b2r \
                        + h[14] * a3i + h[15] * b3r
                    out[m, q] += y + z * fade
                a0r, a0i = b0r * p0r - a0i * p0i, a0i * p0r + b0r * p0i
                a1r, a1i = b1r * p1r - a1i * p1i, a1i * p1r + b1r * p1i
                a2r, a2i = b2r * p2r - a2i * p2i, a2i * p2r + b2r * p2i
                a3r, a3i = b3r * p3r - a3i * p3i, a3i * p3r + b3r * p3i
        wr[r], wi[r] = a0r, a0i
        if n > 1:
            wr[r + 1], wi[r + 1] = a1r, a1i
        if n > 2:
            wr[r + 2], wi[r + 2] = a2r, a2i
        if n > 3:
            wr[r + 3], wi[r + 3] = a3r, a3i
        r += n


@njit(cache=True)
def broadband_resonant(view, act, lw, bg, track, n0, F, fresh):
    """The kept modes (``bg.keep``, :func:`broadband_modes`) driven by their body's broadband
    force, and the modes fading out, over the block ``F`` covers (J, L), into the pulse track
    (:class:`.records.TrackState`; microphone ``m`` hears body ``b``'s sample ``n0 + q`` at
    ``n0 + q + bg.D[b, m]``; ring samples before the track's start are not written).

    A mode ``k`` of body ``b`` (pole ``p``) runs as the exact rendering's voices do
    (:func:`.bank_loops.bank_forced`), in the force's units: ``w <- p (w + g f)``, ``g`` its
    input gain (``bg.gin``: ``phi(x) . n / (fs wd)``), ``f`` the body's force (the sum of its
    exact actuators' ``F[j]`` with their sides' signs along its direction,
    :func:`.drive_tones.streams_write`), heard at microphone ``m`` as ``Im(h_m w)``, ``h_m``
    its output factor (``bg.gout``, times its direction factor towards an air microphone,
    ``bg.Fd``); a change of the output factor (the body moved) applies to the whole state, as
    it physically does, where the exact rendering's voices keep it per microphone. ``bg.z``
    carries the states over blocks (``fresh``: from 0). A mode no longer forced (kept and
    pushed in the last block: ``bg.level`` 1) runs one more block without force, faded out
    linearly over it, and stops. Returns the largest delay written [samples]."""
    acc, rec = track.acc, track.rec
    sidx, sign, ptr, rows, exact = act.sidx, act.sign, act.ptr, act.rows, lw.exact
    keep, z, level, D, Fd = bg.keep, bg.z, bg.level, bg.D, bg.Fd
    nb, M, nmax = bg.gr.shape
    M = min(M, acc.shape[0])
    J, L = F.shape
    mask = acc.shape[1] - 1
    first = rec[0].start
    f = np.empty(L)
    out = np.empty((M, L))
    idx = np.empty(nmax, np.int64)
    u = np.empty(nmax)
    pr = np.empty(nmax)
    pi = np.empty(nmax)
    gin = np.empty(nmax)
    hr = np.empty((M, nmax))
    hi = np.empty((M, nmax))
    wr = np.empty(nmax)
    wi = np.empty(nmax)
    dmax = 0
    for b in range(nb):
        s = sidx[b]
        if s < 0:
            continue
        if fresh:
            for k in range(nmax):
                level[b, k] = 0.0
                z[b, k] = 0.0
        K = 0
        for k in range(nmax):
            if keep[b, k] or level[b, k] > 0.0:
                idx[K] = k
                K += 1
        if K == 0:
            continue
        forced = False
        for q in range(L):
            f[q] = 0.0
        if sign[b] != 0.0:
            for i in range(ptr[b], ptr[b + 1]):
                j = rows[i] // 2
                if not exact[j] or (act.a0[j] == 0.0 and act.a1[j] == 0.0):
                    continue
                forced = True
                coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
                for q in range(L):
                    f[q] += coef * F[j, q]
        o = view.table[s].obj
        m0 = view.mode_off[o]
        directional = view.order[o] >= 0
        for r in range(K):
            k = idx[r]
            p = view.poles[m0 + k]
            pr[r] = p.real
            pi[r] = p.imag
            on = forced and keep[b, k]
            u[r] = 1.0 if on else 0.0
            gin[r] = bg.gin[b, k] if on else 0.0
            wr[r] = z[b, k].real
            wi[r] = z[b, k].imag
            for m in range(M):
                h = bg.gout[b, m, k]
                if directional and view.channels[m].owner == AIR:
                    h *= Fd[b, m, k]
                hr[m, r] = h.real
                hi[m, r] = h.imag
        for m in range(M):
            for q in range(L):
                out[m, q] = 0.0
        _resonant_run(out, f, K, pr, pi, gin, hr, hi, u, wr, wi)
        for r in range(K):
            k = idx[r]
            on = u[r] == 1.0
            level[b, k] = 1.0 if on else 0.0  # (a mode no longer forced has faded out: it stops)
            z[b, k] = complex(wr[r], wi[r]) if on else 0.0
        for m in range(M):
            off = n0 + D[b, m]
            dmax = max(dmax, D[b, m])
            lo = max(off, first)
            if off + L > lo:
                rr = rec[0]
                rr.pending_from = lo if rr.pending_until <= first else min(rr.pending_from, lo)
                rr.pending_until = max(rr.pending_until, off + L)
            for q in range(L):
                if off + q >= first:
                    acc[m, (off + q) & mask] += out[m, q]
    return dmax
