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

Cost: the forced modes' recursion (:func:`modes_run`) and their hearing
(:func:`modes_heard_pair`) are most of a block's time. The recursion runs in its real
second-order form (two fused multiply-adds a sample, one on its path, instead of the complex
form's five multiplies), four modes at a time; a block with no mode running returns after a
pass over the flags.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from .bandlimited import ring_add
from .bank_loops import FAST, fma, fmuladd
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


@njit(cache=True, inline="always")
def _two_product(a, b):
    """``a b = p + e`` exactly: ``p`` the rounded product, ``e`` its rounding error."""
    p = a * b
    return p, fma(a, b, -p)


@njit(cache=True)
def real_coefficients(p):
    """:func:`modes_run`'s coefficients of a mode with pole ``p``: ``a1 = 2 Re p`` (exact)
    and ``a2 = -|p|^2`` rounded once (from its exact sum of two floats: :func:`_two_product`
    and a two-sum). The roots of ``z^2 - a1 z - a2`` move from ``p`` by about ``ulp(a2) / (2
    Im p)`` when ``a2`` is rounded: a drift of the mode's phase by that much a sample over
    its ring (3e-13 of its scale over 300 samples at 20 Hz of 48 kHz, ``Im p = 0.0026``, the
    lowest the synthesizer keeps: ``tests/test_drive_broadband.py``; about 2e-9 after a
    second; carrying ``a2``'s rounding error as a third term would take a third multiply-add
    a sample for 3e-14)."""
    h1, l1 = _two_product(p.real, p.real)
    h2, l2 = _two_product(p.imag, p.imag)
    s = h1 + h2
    t = s - h1
    return 2.0 * p.real, -(s + ((h1 - (s - t)) + (h2 - t) + l1 + l2))


@njit(cache=True, _nrt=False)
def modes_run(S, f, s, n, row, a1, a2, u, v):
    """``K`` modes (``K = a1.shape[0]``, a multiple of 4) over samples ``s <= q < s + n`` of
    ``f`` (rows, L), each as a real second-order recursion: a mode ``w <- p (w + g f)``
    driven by row ``row[k]`` of ``f`` has ``sigma_q = Im w_q``

        sigma_{q+1} = 2 Re p sigma_q - |p|^2 sigma_{q-1} + Im p g f_q

    (``p^2 - 2 Re p p + |p|^2 = 0``; the input is real: ``Im p g f_q`` is its part in
    ``Im w_{q+1}``); run here in units of its input gain, ``x_q = sigma_q / (Im p g)``:
    ``x_{q+1} = a1 x_q + a2 x_{q-1} + f_q``, ``a1 = 2 Re p``, ``a2 = -|p|^2``
    (:func:`real_coefficients`). Writes ``x_{s+t}`` into ``S[k, t]``, ``0 <= t <= n`` (the
    last, ``x_{s+n}``, is also the next chunk's first: :func:`modes_heard_pair` hears sample
    ``t`` from ``S[k, t]`` and ``S[k, t + 1]``); ``u, v`` hold ``(x_{s-1}, x_s)`` and are
    advanced to ``(x_{s+n-1}, x_{s+n})``.

    Four modes at a time, in registers, each new value ``fma(a1, x_q, fma(a2, x_{q-1},
    f_q))``: two fused multiply-adds a sample (the complex recursion takes five multiplies),
    one on the recursion's path (the complex form has two). A mode with ``a1 = a2 = 0``, its
    state 0 and a row of zeros fills a group: it writes zeros."""
    K = a1.shape[0]
    for r in range(0, K, 4):
        c0, d0, u0, v0 = a1[r], a2[r], u[r], v[r]
        c1, d1, u1, v1 = a1[r + 1], a2[r + 1], u[r + 1], v[r + 1]
        c2, d2, u2, v2 = a1[r + 2], a2[r + 2], u[r + 2], v[r + 2]
        c3, d3, u3, v3 = a1[r + 3], a2[r + 3], u[r + 3], v[r + 3]
        f0, f1, f2, f3 = f[row[r], s:], f[row[r + 1], s:], f[row[r + 2], s:], f[row[r + 3], s:]
        x0, x1, x2, x3 = S[r], S[r + 1], S[r + 2], S[r + 3]
        for q in range(n):
            x0[q] = v0
            x1[q] = v1
            x2[q] = v2
            x3[q] = v3
            t0 = fma(c0, v0, fma(d0, u0, f0[q]))
            t1 = fma(c1, v1, fma(d1, u1, f1[q]))
            t2 = fma(c2, v2, fma(d2, u2, f2[q]))
            t3 = fma(c3, v3, fma(d3, u3, f3[q]))
            u0, v0 = v0, t0
            u1, v1 = v1, t1
            u2, v2 = v2, t2
            u3, v3 = v3, t3
        x0[n] = v0
        x1[n] = v1
        x2[n] = v2
        x3[n] = v3
        u[r], v[r], u[r + 1], v[r + 1] = u0, v0, u1, v1
        u[r + 2], v[r + 2], u[r + 3], v[r + 3] = u2, v2, u3, v3


@njit(cache=True, fastmath=FAST, _nrt=False)
def modes_heard(out, m, e, S, n, k0, k1, h):
    """Add ``sum_k Im(h_k b_k)`` over the modes ``k0 <= k < k1`` of :func:`modes_run`'s ``S``
    into ``out[m, e:e + n]`` (``b_q = w_q + g f_q``, the state with the sample's input, as
    the exact rendering's voices hear it; ``h`` (2 M, K): rows ``2 m, 2 m + 1`` microphone
    ``m``'s ``A, B``): ``b_{q+1} = p b_q + g f_{q+1}`` has ``Im b_{q+1} = Im p Re b_q +
    Re p Im b_q``, so ``Re b_q = (sigma_{q+1} - Re p sigma_q) / Im p`` and, in the units of
    :func:`modes_run` (``x = sigma / c``, ``c = Im p g``),

        Im(h b_q) = A x_q + B x_{q+1},   B = c Im h / Im p,   A = c Re h - B Re p."""
    a, A, B = out[m, e:e + n], h[2 * m], h[2 * m + 1]
    for k in range(k0, k1):
        c, d = A[k], B[k]
        x, y = S[k, :n], S[k, 1:n + 1]
        for t in range(n):
            a[t] = fmuladd(d, y[t], fmuladd(c, x[t], a[t]))


@njit(cache=True, fastmath=FAST, _nrt=False)
def modes_heard_pair(out, m, e0, e1, S, n, k0, k1, h):
    """:func:`modes_heard` for microphones ``m`` and ``m + 1`` at once (into ``out[m, e0:e0 +
    n]``, ``out[m + 1, e1:e1 + n]``): each mode's states are read once for both
    microphones, two modes a pass over the buffers (each product a multiply-add of its
    own, :func:`.bank_loops.fmuladd`). Compiled without reference counts (``_nrt=False``:
    it allocates nothing; the views it makes would each add to and drop from the counts)."""
    c0, d0, c1, d1 = h[2 * m], h[2 * m + 1], h[2 * m + 2], h[2 * m + 3]
    a = out[m, e0:e0 + n]
    b = out[m + 1, e1:e1 + n]
    k = k0
    while k + 1 < k1:
        x, y, xx, yy = S[k, :n], S[k, 1:n + 1], S[k + 1, :n], S[k + 1, 1:n + 1]
        e0_, f0, e1_, f1 = c0[k], d0[k], c1[k], d1[k]
        g0, h0, g1, h1 = c0[k + 1], d0[k + 1], c1[k + 1], d1[k + 1]
        for t in range(n):
            a[t] = fmuladd(h0, yy[t], fmuladd(g0, xx[t], fmuladd(f0, y[t], fmuladd(e0_, x[t], a[t]))))
            b[t] = fmuladd(h1, yy[t], fmuladd(g1, xx[t], fmuladd(f1, y[t], fmuladd(e1_, x[t], b[t]))))
        k += 2
    if k < k1:
        x, y = S[k, :n], S[k, 1:n + 1]
        e0_, f0, e1_, f1 = c0[k], d0[k], c1[k], d1[k]
        for t in range(n):
            a[t] = fmuladd(f0, y[t], fmuladd(e0_, x[t], a[t]))
            b[t] = fmuladd(f1, y[t], fmuladd(e1_, x[t], b[t]))


@njit(cache=True, inline="always")
def real_state(p, c, w):
    """:func:`modes_run`'s state ``(x_{-1}, x_0)`` of a mode (pole ``p``, unit ``c = Im p g``)
    whose complex state is ``w``: ``x_0 = Im w / c`` and ``x_{-1} = Im b_{-1} / c``, ``b_{-1}
    = w / p`` (``w = p b_{-1}``)."""
    x = w / c
    return (x / p).imag, x.imag


@njit(cache=True, inline="always")
def complex_state(p, c, u, v):
    """The complex state ``w_L = p b_{L-1}`` of a mode from :func:`modes_run`'s last two
    values ``(u, v) = (x_{L-1}, x_L)``: ``Im b_{L-1} = c u``, ``Re b_{L-1} = c (v - Re p u) /
    Im p`` (:func:`modes_heard`)."""
    return p * complex((v - p.real * u) / p.imag, u) * c


@njit(cache=True, inline="always")
def heard_factors(p, c, h):
    """:func:`modes_heard`'s factors ``(A, B)`` of a mode (pole ``p``, unit ``c``) heard as
    ``Im(h b)``: ``B = c Im h / Im p``, ``A = c Re h - B Re p``."""
    hc = h * c
    B = hc.imag / p.imag
    return hc.real - B * p.real, B


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

    Every body's modes run together, four at a time, each as the real recursion of ``Im w``
    (:func:`modes_run`: a lone mode's recursion is bound by its latency, four overlap; the
    complex state is made from the real one's last two values at the block's end, ``w_L =
    p b_{L-1}``, and the real one from ``w`` at its start, ``Im w_0`` and ``Im(w_0 / p)``),
    over chunks of :data:`CHUNK` samples; each body's are heard from the chunk, two
    microphones at a time at its own delays, into one buffer per microphone
    (:func:`modes_heard_pair`, :func:`modes_heard`), which goes into the ring once
    (:func:`ring_add`). The real form's rounding differs from the complex recursion's by a
    few ulps of the state per sample (``tests/test_drive_broadband.py``: within 1e-12 of it;
    on Ant-v5 and FetchPickAndPlace-v4 the audio within 1e-15 of the complex recursion's);
    it divides by ``Im p``, which the synthesizer's modes never make 0 (it keeps the
    underdamped modes below ``0.45 fs``).

    A block with no mode running costs a pass over the flags (``bg.keep``, ``bg.level``):
    the rest (:func:`resonant_run`) unpacks the records, whose arrays' reference counts
    cost more than that pass, and allocates five arrays (the modes' parameters and indices,
    the bodies' forces, the chunk's states, the microphones' buffers) and, with modes
    ringing out, two more (their pole's powers, the fade)."""
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
def free_heard(out, m, e, pw, pc, u, fade):
    """Add a free mode's ring-out heard at one microphone, ``Im(u p^q) fade[q]`` for
    ``0 <= q < L`` (``L = fade.shape[0]``; ``u = h w``, ``w`` its state at the block's start),
    into ``out[m, e:e + L]``: over chunks of ``T = pw.shape[1]`` samples, ``p^t`` (``t < T``) from
    :func:`pole_powers` and ``u`` carried from chunk to chunk by ``pc = p^T``."""
    L, T = fade.shape[0], pw.shape[1]
    re, im = pw[0], pw[1]
    o = out[m, e:e + L]
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
    keep, z, level, D, Fd, gin, gout = bg.keep, bg.z, bg.level, bg.D, bg.Fd, bg.gin, bg.gout
    a0, a1j = act.a0, act.a1
    table, poles, mode_off, order, channels = view.table, view.poles, view.mode_off, view.order, view.channels
    nb, M, nmax = bg.gr.shape  # (the records' arrays taken once: each taking adds to and drops from a count)
    M = min(M, acc.shape[0])
    J, L = F.shape
    first = rec[0].start
    I = np.zeros(3 * K + 3 + 3 * nb + 1 + 2 * M, np.int64)
    idx, body, row = I[:K], I[K:2 * K], I[2 * K:3 * K + 3]  # (row: the forced modes' and their group's fillers')
    forced, heard = I[3 * K + 3:3 * K + 3 + nb], I[3 * K + 3 + nb:3 * K + 3 + 2 * nb]
    kb = I[3 * K + 3 + 2 * nb:3 * K + 3 + 3 * nb + 1]  # (body b's forced modes: kb[b]:kb[b + 1])
    lo_d, hi_d = I[3 * K + 3 + 3 * nb + 1:3 * K + 3 + 3 * nb + 1 + M], I[3 * K + 3 + 3 * nb + 1 + M:]
    Ks = 0  # (the forced modes, every body's in one run)
    nf = 0  # (the bodies with forced modes: their forces, rows of f)
    for b in range(nb):
        if sidx[b] < 0:
            continue
        if sign[b] != 0.0:
            for i in range(ptr[b], ptr[b + 1]):
                j = rows[i] // 2
                if exact[j] and not (a0[j] == 0.0 and a1j[j] == 0.0):
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
    P = np.zeros((7 + 2 * M, Kp))  # (rows: pole re, im, the recursion's a1, a2, its unit c, state u, v; per microphone A, B)
    pr, pi, a1, a2, ein, u, v, h = P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7:]
    nf_all = nf
    f = np.zeros((nf + 1, L))  # (the last row: zeros, the input of a mode with no input gain)
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
            if not exact[j] or (a0[j] == 0.0 and a1j[j] == 0.0):
                continue
            coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)
            Fj = F[j]
            for q in range(L):
                fb[q] += coef * Fj[q]
        o = table[s].obj
        m0 = mode_off[o]
        directional = order[o] >= 0
        for k in range(nmax):
            if not keep[b, k]:
                continue
            p = poles[m0 + k]
            idx[Ks] = k
            body[Ks] = b
            row[Ks] = nf
            pr[Ks] = p.real
            pi[Ks] = p.imag
            a1[Ks], a2[Ks] = real_coefficients(p)
            unit = p.imag * gin[b, k]  # (modes_run's c: x = sigma / c, the input's gain 1)
            if unit == 0.0:
                unit = 1.0
                row[Ks] = nf_all  # (no input: the row of zeros)
            ein[Ks] = unit
            u[Ks], v[Ks] = real_state(p, unit, z[b, k])
            for m in range(M):
                hm = gout[b, m, k]
                if directional and channels[m].owner == AIR:
                    hm *= Fd[b, m, k]
                h[2 * m, Ks], h[2 * m + 1, Ks] = heard_factors(p, unit, hm)
            Ks += 1
        nf += 1
    kb[nb] = Ks
    for r in range(Ks, Kp):
        row[r] = nf_all  # (the fillers: no input)
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
        S = np.empty((Kp, CH + 1))  # (x_{s+t}, 0 <= t <= n: modes_run)
        for s in range(0, L, CHUNK):  # (a chunk's states stay in the first-level cache)
            n = min(CHUNK, L - s)
            modes_run(S, f, s, n, row, a1, a2, u, v)
            for b in range(nb):
                if kb[b + 1] > kb[b]:
                    for m in range(0, M - 1, 2):
                        e0 = D[b, m] - lo_d[m] + s
                        e1 = D[b, m + 1] - lo_d[m + 1] + s
                        modes_heard_pair(out, m, e0, e1, S, n, kb[b], kb[b + 1], h)
                    if M % 2 == 1:
                        m = M - 1
                        e = D[b, m] - lo_d[m] + s
                        modes_heard(out, m, e, S, n, kb[b], kb[b + 1], h)
    if Ks < K:  # (the free modes: ringing out, faded linearly over the block)
        pw = np.empty((2, CHUNK))
        fade = np.empty(L)
        inv = 1.0 / L
        for q in range(L):
            fade[q] = (L - q) * inv
        for b in range(nb):
            if heard[b] == 0:
                continue
            o = table[sidx[b]].obj
            m0 = mode_off[o]
            directional = order[o] >= 0
            for k in range(nmax):
                if not (keep[b, k] or level[b, k] > 0.0) or (forced[b] == 1 and keep[b, k]):
                    continue
                pc = pole_powers(pw, poles[m0 + k])
                for m in range(M):
                    hm = gout[b, m, k]
                    if directional and channels[m].owner == AIR:
                        hm *= Fd[b, m, k]
                    free_heard(out, m, D[b, m] - lo_d[m], pw, pc, hm * z[b, k], fade)
                level[b, k] = 0.0  # (faded out: it stops)
                z[b, k] = 0.0
    for r in range(Ks):
        b, k = body[r], idx[r]
        level[b, k] = 1.0
        z[b, k] = complex_state(complex(pr[r], pi[r]), ein[r], u[r], v[r])
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
