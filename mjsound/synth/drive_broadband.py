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
exact rendering does (:func:`broadband_write`), but only through the fewest modes of each body
holding all but :data:`RESONANT_REST` of its resonant power (:func:`broadband_modes`: the
stream's other gains are 0, so those modes do not run); their static part stays with the lines.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .drive_tones import noise_cutoff_hz
from .streams import SQRT3, noise_draw, ring_need, stream_gains, stream_written

__all__ = ["RESONANT_ON", "RESONANT_OFF", "RESONANT_REST", "broadband_modes", "broadband_force",
           "broadband_write"]

#: Fraction of an actuator's heard power in the modes' resonant response to its broadband
#: part above which that part goes through the modes (-10 dB) ...
RESONANT_ON = 0.1
#: ... and below which it goes back to the static response (-16 dB; between: as it was).
RESONANT_OFF = 0.025
#: The share of a body's resonant broadband power its dropped modes may hold (-20 dB).
RESONANT_REST = 0.01


@njit(cache=True)
def broadband_modes(ks, act, lw, bg):
    """The modes that carry the broadband parts of the actuators ``lw.exact``: on each body
    with one, its stream's gains are made now (:func:`.streams.stream_gains`, at the point and
    along the direction :func:`.drive_gains.bodies_gains` set) and the fewest modes holding all
    but :data:`RESONANT_REST` of the body's resonant power (``bg.resonant``,
    :func:`.drive_lines.line_weights`) keep them, the others get 0 (they do not run); their
    static part stays with the lines: ``lw.B1[j]`` of an exact actuator is the static
    response of its bodies' other modes. Every driven stream's gains are marked done (none
    is made elsewhere). Returns the modes kept."""
    st, ob = ks.streams, ks.objects
    gr, gi = st.gr, st.gi
    sidx, sign, ptr, rows = act.sidx, act.sign, act.ptr, act.rows
    exact, static, resonant, keep, B = lw.exact, bg.static, bg.resonant, bg.keep, lw.B1
    nb, M, nmax = bg.gr.shape
    M = min(M, gr.shape[1])
    nmax = min(nmax, gr.shape[2])
    J = B.shape[0]
    for j in range(J):
        if exact[j]:
            for m in range(M):
                B[j, m] = 0.0
    kept = 0
    for b in range(nb):
        s = sidx[b]
        for k in range(keep.shape[1]):
            keep[b, k] = False
        if s < 0:
            continue
        st.table[s].due = 0
        if sign[b] == 0.0:
            continue
        on = False
        for i in range(ptr[b], ptr[b + 1]):
            if exact[rows[i] // 2]:
                on = True
        if not on:
            continue  # (its stream is not written: its gains are not heard)
        o = st.table[s].obj
        if not st.table[s].live or o + 1 >= ob.pts_off.shape[0] or ob.pts_off[o + 1] <= ob.pts_off[o] \
                or ob.mode_off[o + 1] <= ob.mode_off[o]:
            continue
        stream_gains(ks, s, o)
        for m in range(st.D.shape[1]):
            if st.D[s, m] > st.counts[0].dmax:
                st.counts[0].dmax = st.D[s, m]
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
        for m in range(M):
            for k in range(nmax):
                if not keep[b, k]:
                    gr[s, m, k] = 0.0
                    gi[s, m, k] = 0.0
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


@njit(cache=True)
def broadband_write(streams, consts, act, lw, k0, F):
    """The broadband forces ``F`` (J, L) of the actuators ``lw.exact`` (:func:`broadband_force`)
    summed per driven body with its side's sign along the body's stream direction
    (``act.sign``, :func:`.drive_gains.bodies_gains`) into the stream's ring on synth samples
    ``[k0, k0 + L)``. Returns 0, or the ring length needed first (nothing written then)."""
    sidx, ptr, rows, sign, exact, a0, a1 = act.sidx, act.ptr, act.rows, act.sign, lw.exact, act.a0, act.a1
    J, L = F.shape
    k1 = k0 + L
    cap = streams.ring.shape[1]
    for b in range(sidx.shape[0]):
        if sidx[b] >= 0 and sign[b] != 0.0:
            need = ring_need(streams, consts, sidx[b], k1)
            if need > cap:
                return need
    ring = streams.ring
    mask = cap - 1
    for b in range(sidx.shape[0]):
        s = sidx[b]
        if s < 0 or sign[b] == 0.0:
            continue
        live = False
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            if exact[j] and (a0[j] != 0.0 or a1[j] != 0.0):
                live = True
        if not live:
            continue
        st = streams.table[s]
        k = st.gen
        if k < k1 - cap:
            k = k1 - cap
        while k < k0:
            ring[s, k & mask] = 0.0
            k += 1
        for q in range(L):
            ring[s, (k0 + q) & mask] = 0.0
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            if not exact[j] or (a0[j] == 0.0 and a1[j] == 0.0):
                continue
            f = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
            for q in range(L):
                ring[s, (k0 + q) & mask] += f * F[j, q]
        stream_written(st, k0, k1)
    return 0
