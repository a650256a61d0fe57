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
for the tones too), heard from its pole's powers ``w p^t`` rather than run sample by sample.

Cost: the forced modes' recursion (four modes at a time, :func:`modes_run`) is most of a
block's time; a block with no mode running returns after a pass over the flags.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from .bandlimited import ring_add
from .bank_loops import FAST
from .drive_tones import noise_cutoff_hz
from .records import AIR
from .streams import SQRT3, noise_draw

__all__ = ["RESONANT_ON", "RESONANT_OFF", "RESONANT_REST", "ROUTE_HOLD_S", "broadband_route", "broadband_modes",
           "broadband_force", "broadband_resonant"]

#: Fraction of an actuator's heard power in the modes' resonant response to its broadband
#: part above which that part goes through the modes (-10 dB) ...
RESONANT_ON = 0.1
#: ... and below which it goes back to the static response (-16 dB; between: as it was).
RESONANT_OFF = 0.025
#: The share of a body's resonant broadband power its dropped modes may hold (-20 dB).
RESONANT_REST = 0.01
#: How long [s] the share must stay below :data:`RESONANT_OFF` before the broadband part goes
#: back to the static response. A line crossing one of its links' resonances is briefly loud
#: (the share falls while the tone peaks), but the noise's resonant part is still heard at the
#: modes' own frequencies, far from the tone: switching it off for the crossing left a gap
#: of the links' high noise (8 ms, 40 dB down at 8-12 kHz, on the driven arm of
#: ``scripts/arm_demo.py --preset servo``). A block longer than this (an env step's: Ant-v5,
#: 50 ms) switches at its first block below, as without a hold: the route is chosen at a
#: block's end, which a crossing inside the block does not reach.
ROUTE_HOLD_S = 0.025


@njit(cache=True)
def broadband_route(lw, L, fs):
    """Whether each actuator's broadband part goes through the modes this block
    (``lw.exact``), from its resonant power and everything it makes heard (``lw.power``,
    :func:`.drive_weights.line_weights`): on once the resonant share exceeds
    :data:`RESONANT_ON`; off once it has stayed below :data:`RESONANT_OFF` for longer than
    :data:`ROUTE_HOLD_S` (``lw.held`` (J,) int64: the samples it has been below while on,
    this block of ``L`` samples included; a ``held`` of another length: no hold).

    Parameters
    ----------
    lw : :class:`.drive_lines.LineWeights`
    L : int, the block's samples; fs : float [Hz]
    """
    exact, power, held = lw.exact, lw.power, lw.held
    hold = held.shape[0] == exact.shape[0]
    limit = ROUTE_HOLD_S * fs
    for j in range(exact.shape[0]):
        res, total = power[j, 0], power[j, 1]
        low = exact[j] and not res > RESONANT_OFF * total
        if low and hold and held[j] + L <= limit:
            held[j] += L  # (below, but not for long yet: a resonance crossing)
            continue
        exact[j] = res > (RESONANT_OFF if exact[j] else RESONANT_ON) * total
        if hold:
            held[j] = 0

#: Samples per pass of :func:`broadband_resonant` (its modes' states over them: 64 kB at 32 modes).
CHUNK = 128


@njit(cache=True)
def broadband_modes(act, lw, bg):
    """The modes that carry the broadband parts of the actuators ``lw.exact``: on each body
    with one, the fewest modes holding all but :data:`RESONANT_REST` of the body's resonant
    power (``bg.resonant``, :func:`.drive_weights.line_weights`) are kept (``bg.keep``: they run,
    :func:`broadband_resonant`); their static part stays with the lines: ``lw.B1[j]`` of an
    exact actuator, as :func:`.drive_weights.line_weights` and
    :func:`.drive_housing.housing_weights` made it (its bodies' whole static response and the
    housing's airborne part), less the static response of the modes kept. Returns the modes
    kept."""
    sidx, sign, ptr, rows = act.sidx, act.sign, act.ptr, act.rows
    exact, static, resonant, keep, B = lw.exact, bg.static, bg.resonant, bg.keep, lw.B1
    nb, M, nmax = bg.gr.shape
    left = np.empty(nmax)  # (a body's resonant powers not yet kept: those kept are set to -1)
    h = np.empty(M)
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
            left[k] = resonant[b, k]
            total += resonant[b, k]
        for m in range(M):
            h[m] = 0.0
        rest = total
        while rest > RESONANT_REST * total:  # (the strongest left, until the rest is small)
            best = 0
            for k in range(1, nmax):
                if left[k] > left[best]:
                    best = k
            if left[best] <= 0.0:
                break
            keep[b, best] = True
            left[best] = -1.0
            rest -= resonant[b, best]
            kept += 1
            for m in range(M):
                h[m] += static[b, m, best]
        for i in range(ptr[b], ptr[b + 1]):  # (the modes kept leave the exact actuators' static part)
            j = rows[i] // 2
            if exact[j]:
                coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
                for m in range(M):
                    B[j, m] -= coef * h[m]
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
def modes_run(X, f, s, n, row, pr, pi, gin, wr, wi):
    """``K`` modes (``K = pr.shape[0]``, a multiple of 4) over samples ``s <= q < s + n`` of
    ``f`` (rows, L): mode ``k`` driven by row ``row[k]`` of ``f`` with input gain ``gin[k]``,
    per sample ``b = w + g f[q]`` (the input on the real part) and ``w <- p b``; its heard
    state ``(Im b, Re b)`` (``Im b = Im w``) into ``X[2 k, q - s], X[2 k + 1, q - s]``, its
    state ``wr + j wi`` updated. Four modes at a time, their states held in registers, so
    that their recursions overlap (a mode with ``p = g = 0`` and its state 0 fills a group:
    it writes zeros)."""
    K = pr.shape[0]
    for r in range(0, K, 4):
        a0r, a0i, p0r, p0i, g0 = wr[r], wi[r], pr[r], pi[r], gin[r]
        a1r, a1i, p1r, p1i, g1 = wr[r + 1], wi[r + 1], pr[r + 1], pi[r + 1], gin[r + 1]
        a2r, a2i, p2r, p2i, g2 = wr[r + 2], wi[r + 2], pr[r + 2], pi[r + 2], gin[r + 2]
        a3r, a3i, p3r, p3i, g3 = wr[r + 3], wi[r + 3], pr[r + 3], pi[r + 3], gin[r + 3]
        f0, f1, f2, f3 = f[row[r], s:], f[row[r + 1], s:], f[row[r + 2], s:], f[row[r + 3], s:]
        x0i, x0r, x1i, x1r = X[2 * r], X[2 * r + 1], X[2 * r + 2], X[2 * r + 3]
        x2i, x2r, x3i, x3r = X[2 * r + 4], X[2 * r + 5], X[2 * r + 6], X[2 * r + 7]
        for q in range(n):
            b0r = a0r + g0 * f0[q]
            b1r = a1r + g1 * f1[q]
            b2r = a2r + g2 * f2[q]
            b3r = a3r + g3 * f3[q]
            x0i[q] = a0i
            x0r[q] = b0r
            x1i[q] = a1i
            x1r[q] = b1r
            x2i[q] = a2i
            x2r[q] = b2r
            x3i[q] = a3i
            x3r[q] = b3r
            a0r, a0i = b0r * p0r - a0i * p0i, a0i * p0r + b0r * p0i
            a1r, a1i = b1r * p1r - a1i * p1i, a1i * p1r + b1r * p1i
            a2r, a2i = b2r * p2r - a2i * p2i, a2i * p2r + b2r * p2i
            a3r, a3i = b3r * p3r - a3i * p3i, a3i * p3r + b3r * p3i
        wr[r], wi[r], wr[r + 1], wi[r + 1] = a0r, a0i, a1r, a1i
        wr[r + 2], wi[r + 2], wr[r + 3], wi[r + 3] = a2r, a2i, a3r, a3i


@njit(cache=True, fastmath=FAST)
def modes_heard(out, X, n, k0, k1, hr, hi, steady, s, L):
    """Add ``sum_k Im(h_k b_k)`` over the modes ``k0 <= k < k1`` of :func:`modes_run`'s ``X``
    (``Im(h b) = hr Im b + hi Re b``) into ``out[:n]``, sample ``t`` being the block's
    ``s + t`` of ``L``: a mode not ``steady`` is faded out linearly over the block
    (``(L - s - t) / L``: 1 to 0)."""
    inv = 1.0 / L
    for k in range(k0, k1):
        c, d = hr[k], hi[k]
        xi, xr = X[2 * k], X[2 * k + 1]
        if steady[k]:
            for t in range(n):
                out[t] += c * xi[t] + d * xr[t]
        else:
            for t in range(n):
                out[t] += (c * xi[t] + d * xr[t]) * ((L - s - t) * inv)


@njit(cache=True, fastmath=FAST)
def modes_heard_pair(o0, o1, X, n, k0, k1, h, m, steady, s, L):
    """:func:`modes_heard` for microphones ``m`` and ``m + 1`` at once (into ``o0[:n]``,
    ``o1[:n]``; ``h`` (2 M, K): rows ``2 m, 2 m + 1`` the real and imaginary output factors
    of microphone ``m``): each mode's states are read once for both microphones."""
    inv = 1.0 / L
    c0, d0, c1, d1 = h[2 * m], h[2 * m + 1], h[2 * m + 2], h[2 * m + 3]
    a = o0[:n]
    b = o1[:n]
    for k in range(k0, k1):
        xi, xr = X[2 * k, :n], X[2 * k + 1, :n]
        e0, f0, e1, f1 = c0[k], d0[k], c1[k], d1[k]
        if steady[k]:
            for t in range(n):
                a[t] += e0 * xi[t] + f0 * xr[t]
                b[t] += e1 * xi[t] + f1 * xr[t]
        else:
            for t in range(n):
                fade = (L - s - t) * inv
                a[t] += (e0 * xi[t] + f0 * xr[t]) * fade
                b[t] += (e1 * xi[t] + f1 * xr[t]) * fade


@njit(cache=True, inline="always")
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
    linearly over it, and stops. Returns the largest delay written [samples].

    Every body's modes run together, four at a time (:func:`modes_run`: a lone mode's
    recursion is bound by its latency, four overlap), over chunks of :data:`CHUNK` samples;
    each body's are heard from the chunk, two microphones at a time at its own delays, into
    one buffer per microphone (:func:`modes_heard_pair`, :func:`modes_heard`), which goes
    into the ring once (:func:`ring_add`).

    A block with no mode running costs a pass over the flags (``bg.keep``, ``bg.level``):
    the rest (:func:`resonant_run`) unpacks the records, whose arrays' reference counts
    cost more than that pass, and allocates five arrays (the modes' parameters and indices,
    the bodies' forces, the chunk's states, the microphones' buffers)."""
    sidx, keep, z, level = act.sidx, bg.keep, bg.z, bg.level
    nb, nmax = keep.shape
    K = 0
    for b in range(nb):
        if sidx[b] < 0:
            continue
        if fresh:
            for k in range(nmax):
                level[b, k] = 0.0
                z[b, k] = 0.0
        for k in range(nmax):
            if keep[b, k] or level[b, k] > 0.0:
                K += 1
    if K == 0:
        return 0
    return resonant_run(view, act, lw, bg, track, n0, F, K)


@njit(cache=True, fastmath=FAST)
def pole_powers(pw, p):
    """``p^t`` into ``pw`` (2, n: real and imaginary parts, ``0 <= t < n``, ``n`` a power of
    two) by doubling (``p^{T + t} = p^t p^T``: each pass vectorised, not a recursion
    sample by sample); returns ``p^n``."""
    n = pw.shape[1]
    re, im = pw[0], pw[1]
    re[0], im[0] = 1.0, 0.0
    qr, qi = p.real, p.imag  # (p^T)
    T = 1
    while T < n:
        for t in range(T):
            re[T + t] = re[t] * qr - im[t] * qi
            im[T + t] = re[t] * qi + im[t] * qr
        qr, qi = qr * qr - qi * qi, 2.0 * qr * qi
        T *= 2
    return complex(qr, qi)


@njit(cache=True, fastmath=FAST)
def free_heard(o, pw, pc, u, fade):
    """Add a free mode's ring-out heard at one microphone, ``Im(u p^q) fade[q]`` for
    ``0 <= q < L`` (``L = fade.shape[0]``; ``u = h w``, ``w`` its state at the block's start),
    into ``o[:L]``: over chunks of ``T = pw.shape[1]`` samples, ``p^t`` (``t < T``) from
    :func:`pole_powers` and ``u`` carried from chunk to chunk by ``pc = p^T``."""
    L, T = fade.shape[0], pw.shape[1]
    re, im = pw[0], pw[1]
    for s in range(0, L, T):
        n = min(T, L - s)
        a, fd = o[s:s + n], fade[s:s + n]
        ur, ui = u.real, u.imag
        for t in range(n):
            a[t] += (ui * re[t] + ur * im[t]) * fd[t]
        u *= pc


@njit_inner(cache=True, inline="always")
def resonant_run(view, act, lw, bg, track, n0, F, K):
    """:func:`broadband_resonant` of a block with ``K > 0`` modes running (their states
    already zeroed where the block is fresh). Returns the largest delay written [samples].

    The modes forced (kept, on a body some exact actuator pushes) run the recursion
    (:func:`modes_run`); the others only ring out, faded over the block: their state is
    ``w p^t`` from the block's, which needs no recursion: each is heard from the pole's powers
    over a chunk (:func:`pole_powers`, :func:`free_heard`: vectorised over the samples), the
    state carried from chunk to chunk by ``p^{CHUNK}``."""
    acc, rec = track.acc, track.rec
    sidx, sign, ptr, rows, exact = act.sidx, act.sign, act.ptr, act.rows, lw.exact
    keep, z, level, D, Fd = bg.keep, bg.z, bg.level, bg.D, bg.Fd
    nb, M, nmax = bg.gr.shape
    M = min(M, acc.shape[0])
    J, L = F.shape
    first = rec[0].start
    I = np.zeros(4 * K + 3 * nb + 1 + 2 * M, np.int64)
    idx, body, row, steady = I[:K], I[K:2 * K], I[2 * K:3 * K], I[3 * K:4 * K]
    forced, heard = I[4 * K:4 * K + nb], I[4 * K + nb:4 * K + 2 * nb]
    kb = I[4 * K + 2 * nb:4 * K + 3 * nb + 1]  # (body b's forced modes: kb[b]:kb[b + 1])
    lo_d, hi_d = I[4 * K + 3 * nb + 1:4 * K + 3 * nb + 1 + M], I[4 * K + 3 * nb + 1 + M:]
    Ks = 0  # (the forced modes, every body's in one run)
    nf = 0  # (the bodies with forced modes: their forces, rows of f)
    for b in range(nb):
        if sidx[b] < 0:
            continue
        if sign[b] != 0.0:
            for i in range(ptr[b], ptr[b + 1]):
                j = rows[i] // 2
                if exact[j] and not (act.a0[j] == 0.0 and act.a1[j] == 0.0):
                    forced[b] = 1
        c = 0
        for k in range(nmax):
            if keep[b, k] or level[b, k] > 0.0:
                heard[b] = 1
                if forced[b] == 1 and keep[b, k]:
                    c += 1
        Ks += c
        nf += 1 if c > 0 else 0
    Kp = (Ks + 3) // 4 * 4  # (groups of four: the rest filled with silent modes)
    P = np.zeros((5 + 2 * M, Kp))  # (rows: pole re, im, input gain, state re, im; per microphone h re, im)
    pr, pi, gin, wr, wi, h = P[0], P[1], P[2], P[3], P[4], P[5:]
    f = np.zeros((nf, L))
    Ks = 0
    nf = 0
    for b in range(nb):
        kb[b] = Ks
        s = sidx[b]
        if s < 0 or forced[b] == 0:
            continue
        c = 0
        for k in range(nmax):
            c += 1 if keep[b, k] else 0
        if c == 0:
            continue
        fb = f[nf]
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            if not exact[j] or (act.a0[j] == 0.0 and act.a1[j] == 0.0):
                continue
            coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
            Fj = F[j]
            for q in range(L):
                fb[q] += coef * Fj[q]
        o = view.table[s].obj
        m0 = view.mode_off[o]
        directional = view.order[o] >= 0
        for k in range(nmax):
            if not keep[b, k]:
                continue
            p = view.poles[m0 + k]
            idx[Ks] = k
            body[Ks] = b
            row[Ks] = nf
            pr[Ks] = p.real
            pi[Ks] = p.imag
            steady[Ks] = 1
            gin[Ks] = bg.gin[b, k]
            wr[Ks] = z[b, k].real
            wi[Ks] = z[b, k].imag
            for m in range(M):
                hm = bg.gout[b, m, k]
                if directional and view.channels[m].owner == AIR:
                    hm *= Fd[b, m, k]
                h[2 * m, Ks] = hm.real
                h[2 * m + 1, Ks] = hm.imag
            Ks += 1
        nf += 1
    kb[nb] = Ks
    # each microphone's samples from its nearest body's delay on, every body at its own
    for m in range(M):
        lo_d[m] = 1 << 62
    for b in range(nb):
        if heard[b] == 1:
            for m in range(M):
                lo_d[m] = min(lo_d[m], D[b, m])
                hi_d[m] = max(hi_d[m], D[b, m])
    spread = 0
    for m in range(M):
        spread = max(spread, hi_d[m] - lo_d[m])
    out = np.zeros((M, L + spread))
    CH = min(L, CHUNK)
    if Ks > 0:
        X = np.empty((2 * Kp, CH))
        for s in range(0, L, CHUNK):  # (a chunk's states stay in the first-level cache)
            n = min(CHUNK, L - s)
            modes_run(X, f, s, n, row, pr, pi, gin, wr, wi)
            for b in range(nb):
                if kb[b + 1] > kb[b]:
                    for m in range(0, M - 1, 2):
                        e0 = D[b, m] - lo_d[m] + s
                        e1 = D[b, m + 1] - lo_d[m + 1] + s
                        modes_heard_pair(out[m, e0:], out[m + 1, e1:], X, n, kb[b], kb[b + 1], h, m, steady, s, L)
                    if M % 2 == 1:
                        m = M - 1
                        e = D[b, m] - lo_d[m] + s
                        modes_heard(out[m, e:e + n], X, n, kb[b], kb[b + 1], h[2 * m], h[2 * m + 1], steady, s, L)
    if Ks < K:  # (the free modes: ringing out, faded as modes_heard fades them)
        pw = np.empty((2, CHUNK))
        fade = np.empty(L)
        inv = 1.0 / L
        for q in range(L):
            fade[q] = (L - q) * inv
        for b in range(nb):
            if heard[b] == 0:
                continue
            o = view.table[sidx[b]].obj
            m0 = view.mode_off[o]
            directional = view.order[o] >= 0
            for k in range(nmax):
                if not (keep[b, k] or level[b, k] > 0.0) or (forced[b] == 1 and keep[b, k]):
                    continue
                pc = pole_powers(pw, view.poles[m0 + k])
                for m in range(M):
                    hm = bg.gout[b, m, k]
                    if directional and view.channels[m].owner == AIR:
                        hm *= Fd[b, m, k]
                    free_heard(out[m, D[b, m] - lo_d[m]:], pw, pc, hm * z[b, k], fade)
                level[b, k] = 0.0  # (faded out: it stops)
                z[b, k] = 0.0
    for r in range(Ks):
        b, k = body[r], idx[r]
        level[b, k] = 1.0
        z[b, k] = complex(wr[r], wi[r])
    rr = rec[0]
    dmax = 0
    for m in range(M):
        off = n0 + lo_d[m]
        dmax = max(dmax, hi_d[m])
        n = L + hi_d[m] - lo_d[m]
        lo = max(off, first)
        if off + n > lo:
            rr.pending_from = lo if rr.pending_until <= first else min(rr.pending_from, lo)
            rr.pending_until = max(rr.pending_until, off + n)
        ring_add(acc, m, off, first, out[m, :n])
    return dmax
