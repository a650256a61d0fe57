"""The drive lines' samples (:mod:`.drive_lines`): each line ``Im(V_k z_k)``, its phasor ``z``
turned by its rate ``r`` a sample and the rate by its turn ``e^{j ds}`` (a linear chirp), its
weight ``V`` linear over the block, summed per channel into the pulse track's ring.

The samples run in float32 lanes, one line a lane, restarted every :data:`SUB` samples from
a float64 recursion over the restarts (:func:`lines_pass`); a line crossing the cut-off runs
in float64, one sample at a time, in the restarts it covers in part (:func:`_span_part`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from .bank_loops import FAST, fma, fmuladd

__all__ = ["SUB", "LANES_MIN", "LaneScratch", "lane_scratch", "lanes_for", "lines_pass", "turn", "cpow"]


#: Samples between the lines' exact restarts (a power of two: :func:`lines_pass`).
SUB = 64
#: Fewest lanes :func:`_sub_pass` runs (a multiple of 8, the lines padded with silent ones:
#: LLVM's vector loop there starts at 24 lanes (below, its scalar loop runs, ~3x slower per
#: lane; the lines of one or two actuators: Fetch's gripper). Measured again with the weights
#: ramped on the adders: 8 lanes were slower on Fetch's blocks than 24.
LANES_MIN = 24


class LaneScratch(NamedTuple):
    """:func:`lines_pass`'s working arrays for up to ``n`` lines (:func:`lane_scratch`; kept by
    their owner between blocks: a block allocates none where they are large enough)."""

    T: np.ndarray  # (6, n) float64: each line's phasor, rate and the rates' product over SUB samples at a restart
    G: np.ndarray  # (4, n) float64: their turns per restart
    S32: np.ndarray  # (6, nv) float32: the lanes' phasor, rate, turn
    V32: np.ndarray  # (8, nv) float32: the lanes' weights and steps
    lane: np.ndarray  # (n,) int64: each line's lane in the last restart (-1: none)


@njit(cache=True, inline="always")
def lanes_for(n):
    """The lanes ``nv`` of ``n`` lines: ``n`` rounded up to a multiple of 8, at least :data:`LANES_MIN`."""
    return max(LANES_MIN, (n + 7) // 8 * 8)


def lane_scratch(n: int) -> LaneScratch:
    """:class:`LaneScratch` for ``n`` lines (``nv``: :func:`lanes_for`)."""
    nv = max(LANES_MIN, (n + 7) // 8 * 8)
    return LaneScratch(np.zeros((6, n)), np.zeros((4, n)), np.zeros((6, nv), np.float32),
                       np.zeros((8, nv), np.float32), np.full(n, -1, np.int64))


@njit(cache=True, fastmath=FAST, _nrt=False)
def _sub_pass(acc, first, c0, c1, k0, n_k, n, S, V):
    """``n_k`` samples of the gathered lines in float32 lanes (the first ``n`` columns, a
    multiple of 8: lanes past the lines are zero), two samples per pass over them, into
    channels ``c0`` (absolute sample ``k0 + k``) and ``c1`` (``k0 + k + (the second
    channel's offset)``, passed as ``c1 = (channel, offset)``; one channel:
    :func:`_sub_pass1`): rows of ``S`` (6, >= n) float32 phasor, rate, the rate's turn (re,
    im; updated); ``V`` (8, >= n) float32 each channel's weight at the first sample and its
    step per sample (re, im; the weights updated: the weight ramps by adding its step a
    sample, on the adders, so that the multipliers do the phasors' and the outputs' work
    alone). A product and a sum fuse where the code says so, the same in every process
    (:func:`.bank_loops.fma`: the phasor's ``Re = fma(a, c, -b d)``, ``Im = fma(a, d, b c)``;
    :func:`.bank_loops.fmuladd`, which LLVM vectorises as a sum over the lanes: each
    output's ``fmuladd(wr, zi, fmuladd(wi, zr, sum))``)."""
    mask = acc.shape[1] - 1
    ur, ui, rr, ri, er, ei = S[0], S[1], S[2], S[3], S[4], S[5]
    v0r, v0i, d0r, d0i, v1r, v1i, d1r, d1i = V[0], V[1], V[2], V[3], V[4], V[5], V[6], V[7]
    ch1, off1 = c1
    zero = np.float32(0.0)
    k = 0
    while k < n_k:
        s0 = zero
        s1 = zero
        t0 = zero
        t1 = zero
        for q in range(n):
            a = ur[q]
            b = ui[q]
            c = rr[q]
            d = ri[q]
            e = er[q]
            f = ei[q]
            xr = v0r[q]
            xi = v0i[q]
            yr = v1r[q]
            yi = v1i[q]
            s0 = fmuladd(xr, b, fmuladd(xi, a, s0))
            s1 = fmuladd(yr, b, fmuladd(yi, a, s1))
            xr += d0r[q]
            xi += d0i[q]
            yr += d1r[q]
            yi += d1i[q]
            a2 = fma(a, c, -(b * d))
            b2 = fma(a, d, b * c)
            c2 = fma(c, e, -(d * f))
            d2 = fma(c, f, d * e)
            t0 = fmuladd(xr, b2, fmuladd(xi, a2, t0))
            t1 = fmuladd(yr, b2, fmuladd(yi, a2, t1))
            v0r[q] = xr + d0r[q]
            v0i[q] = xi + d0i[q]
            v1r[q] = yr + d1r[q]
            v1i[q] = yi + d1i[q]
            ur[q] = fma(a2, c2, -(b2 * d2))
            ui[q] = fma(a2, d2, b2 * c2)
            rr[q] = fma(c2, e, -(d2 * f))
            ri[q] = fma(c2, f, d2 * e)
        for i in range(2):
            if k + i < n_k:
                u = k0 + k + i
                if u >= first:
                    acc[c0, u & mask] += s0 if i == 0 else t0
                if u + off1 >= first:
                    acc[ch1, (u + off1) & mask] += s1 if i == 0 else t1
        k += 2


@njit(cache=True, fastmath=FAST, _nrt=False)
def _sub_pass1(acc, first, c0, k0, n_k, n, S, V):
    """:func:`_sub_pass` into one channel ``c0`` (``V``'s first 4 rows)."""
    mask = acc.shape[1] - 1
    ur, ui, rr, ri, er, ei = S[0], S[1], S[2], S[3], S[4], S[5]
    v0r, v0i, d0r, d0i = V[0], V[1], V[2], V[3]
    zero = np.float32(0.0)
    k = 0
    while k < n_k:
        s0 = zero
        t0 = zero
        for q in range(n):
            a = ur[q]
            b = ui[q]
            c = rr[q]
            d = ri[q]
            e = er[q]
            f = ei[q]
            xr = v0r[q]
            xi = v0i[q]
            s0 = fmuladd(xr, b, fmuladd(xi, a, s0))
            xr += d0r[q]
            xi += d0i[q]
            a2 = fma(a, c, -(b * d))
            b2 = fma(a, d, b * c)
            c2 = fma(c, e, -(d * f))
            d2 = fma(c, f, d * e)
            t0 = fmuladd(xr, b2, fmuladd(xi, a2, t0))
            v0r[q] = xr + d0r[q]
            v0i[q] = xi + d0i[q]
            ur[q] = fma(a2, c2, -(b2 * d2))
            ui[q] = fma(a2, d2, b2 * c2)
            rr[q] = fma(c2, e, -(d2 * f))
            ri[q] = fma(c2, f, d2 * e)
        for i in range(2):
            if k + i < n_k:
                u = k0 + k + i
                if u >= first:
                    acc[c0, u & mask] += s0 if i == 0 else t0
        k += 2


@njit(cache=True, inline="always")
def turn(x):
    """``(cos x, sin x)``; for ``|x| < 0.01`` (a chirp's turn per sample, harmonics' phase
    differences) by their series to ``x^6`` and ``x^7`` (the next terms below 3e-21: within
    float64's rounding of libm's)."""
    if abs(x) >= 0.01:
        return math.cos(x), math.sin(x)
    x2 = x * x
    return (1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0))),
            x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 * (1.0 / 5040.0)))))


@njit(cache=True, inline="always")
def cpow(r, i, k):
    """``(r + j i)^k`` for ``k`` 2 or 3."""
    r2, i2 = r * r - i * i, 2.0 * r * i
    return (r2, i2) if k == 2 else (r2 * r - i2 * i, r2 * i + i2 * r)


@njit(cache=True, inline="always")
def _csq(r, i, times):
    """``(r + j i)^(2^times)`` by squaring."""
    for _ in range(times):
        r, i = r * r - i * i, 2.0 * r * i
    return r, i


@njit(cache=True, _nrt=False)
def lines_pass(acc, first, off0, off1, two, L, S, V, span, n, work):
    """The first ``n`` gathered lines over ``L`` samples into channels ``off0`` (and ``off1``
    when ``two``), each ``(channel, absolute sample of the block's first)``: rows of ``S``
    (6, >= n) float64 phasor, rate (at the block's first sample), the rate's turn per sample
    (re, im each; left as they are); of ``V`` (8, >= n) channel 0's and 1's weight and its
    step per sample (re, im each; channel 1's only read when ``two``); line ``q`` sounds on
    samples ``span[0, q] <= k < span[1, q]`` only (a line crossing the cut-off: in the
    restarts it covers partly, its samples there run one at a time, :func:`_span_part`; in
    those it does not cover, it is left out). ``work``: :class:`LaneScratch` for at least ``n``
    lines (nothing is allocated here: no reference counts, :mod:`.drive_gains`' docstring).

    The samples run in float32 lanes (:func:`_sub_pass`: the lines sounding through the
    restart, packed and padded to a multiple of 8 lanes, at least :data:`LANES_MIN`),
    restarted every :data:`SUB` samples from a float64 recursion over the restarts (phasor
    ``z`` times the product of the rates over ``SUB`` samples ``P``; ``P`` turned by
    ``e^{j ds SUB^2}``, the rate by ``e^{j ds SUB}``; the powers by squaring), so float32's
    rounding does not accumulate past ``SUB`` samples (relative error ~1e-5)."""
    c0, k0 = off0
    c1, k1 = off1
    nv = lanes_for(n)
    T, G, S32, V32, lane = work.T, work.G, work.S32, work.V32, work.lane
    lg = 0
    while (1 << lg) < SUB:
        lg += 1
    for q in range(n):
        e1r, e1i = S[4, q], S[5, q]
        hr, hi = _csq(e1r, e1i, lg - 1)  # e^{j ds SUB / 2}
        eSr, eSi = _csq(hr, hi, 1)  # e^{j ds SUB}
        br, bi = _csq(eSr, eSi, lg - 1)  # e^{j ds SUB^2 / 2}
        Qr, Qi = _csq(br, bi, 1)  # e^{j ds SUB^2}
        rr, ri = _csq(S[2, q], S[3, q], lg)  # e^{j SUB s0}
        # P_0 = e^{j (SUB s0 + ds SUB (SUB - 1) / 2)}, SUB (SUB - 1) / 2 = SUB^2 / 2 - SUB / 2
        pr, pi = rr * br - ri * bi, rr * bi + ri * br
        pr, pi = pr * hr + pi * hi, pi * hr - pr * hi
        T[0, q], T[1, q], T[2, q], T[3, q], T[4, q], T[5, q] = S[0, q], S[1, q], S[2, q], S[3, q], pr, pi
        G[0, q], G[1, q], G[2, q], G[3, q] = eSr, eSi, Qr, Qi
    whole = True  # (every line sounds through the block: the lanes are set once)
    for q in range(n):
        lane[q] = -1  # (each line's lane in the last restart; -1: none)
        whole = whole and span[0, q] <= 0 and span[1, q] >= L
    na = 0  # (lanes in use: the lines sounding through the restart)
    for s in range(0, L, SUB):
        nk = min(SUB, L - s)
        same = s > 0 or not whole  # (the same lines in the same lanes as the last restart)
        i = 0
        for q in range(n):
            if whole:
                break
            lo, hi = span[0, q], span[1, q]
            if lo <= s and s + nk <= hi:
                same = same and lane[q] == i
                i += 1
            else:
                same = same and lane[q] < 0
        if not same:
            na = 0
            for q in range(n):
                lo, hi = span[0, q], span[1, q]
                lane[q] = -1
                if lo <= s and s + nk <= hi:
                    lane[q] = na
                    S32[4, na] = S[4, q]
                    S32[5, na] = S[5, q]
                    for r in range(2, 8, 4):  # (the weights' steps)
                        V32[r, na] = V[r, q]
                        V32[r + 1, na] = V[r + 1, q]
                    na += 1
            for q in range(na, nv):  # (silent lanes)
                for r in range(8):
                    V32[r, q] = 0.0
                for r in range(6):
                    S32[r, q] = 0.0
        if na == n:  # (every line in its own lane, in order)
            _lanes_load(T, V, S32, V32, n, s)
        for q in range(n):
            i = lane[q]
            if na == n:
                break
            if i >= 0:
                for r in range(4):
                    S32[r, i] = T[r, q]
                for r in range(0, 8, 4):  # (the weights at the restart, from float64)
                    V32[r, i] = V[r, q] + V[r + 2, q] * s
                    V32[r + 1, i] = V[r + 1, q] + V[r + 3, q] * s
            else:  # (a partial line: its part one sample at a time)
                lo, hi = span[0, q], span[1, q]
                a = max(lo, s)
                b = min(hi, s + nk)
                if b > a:
                    _span_part(acc, first, (c0, k0, c1, k1), two, s, a, b,
                               (T[0, q], T[1, q], T[2, q], T[3, q], S[4, q], S[5, q]), V[:, q])
        if na:
            nl = max(LANES_MIN, (na + 7) // 8 * 8)
            if two:
                _sub_pass(acc, first, c0, (c1, k1 - k0), k0 + s, nk, nl, S32, V32)
            else:
                _sub_pass1(acc, first, c0, k0 + s, nk, nl, S32, V32)
        _advance(T, G, n)


@njit(cache=True, _nrt=False)
def _lanes_load(T, V, S32, V32, n, s):
    """Lanes ``0 .. n-1`` at the restart at sample ``s`` (line ``q`` in lane ``q``): the
    phasors and rates ``T`` (float64, rows 0-3) rounded to float32, the weights ``V[r] + s
    V[r + 2]`` (float64, then rounded; rows 0, 1, 4, 5). Straight copies: vectorised."""
    for r in range(4):
        src = T[r]
        dst = S32[r]
        for q in range(n):
            dst[q] = src[q]
    for r in (0, 1, 4, 5):
        v = V[r]
        d = V[r + 2]
        dst = V32[r]
        for q in range(n):
            dst[q] = v[q] + d[q] * s


@njit(cache=True, _nrt=False)
def _advance(T, G, n):
    """The float64 recursion from one restart to the next (:func:`lines_pass`): the phasor
    ``z`` times ``P``, the rate times its turn ``G[0:2]``, ``P`` times its turn ``G[2:4]``
    (elementwise over the lines: vectorised)."""
    zr, zi, rr, ri, pr, pi = T[0], T[1], T[2], T[3], T[4], T[5]
    gr, gi, hr, hi = G[0], G[1], G[2], G[3]
    for q in range(n):
        a, b, c, d, e, f = zr[q], zi[q], rr[q], ri[q], pr[q], pi[q]
        zr[q], zi[q] = a * e - b * f, a * f + b * e
        rr[q], ri[q] = c * gr[q] - d * gi[q], c * gi[q] + d * gr[q]
        pr[q], pi[q] = e * hr[q] - f * hi[q], e * hi[q] + f * hr[q]


@njit(cache=True, fastmath=FAST, _nrt=False)
def _span_part(acc, first, offs, two, s, a, b, ph, v):
    """One line's samples ``a <= k < b`` (of the block) one at a time, into channel ``c0`` at
    ``k0 + k`` and (``two``) ``c1`` at ``k1 + k`` (``offs = (c0, k0, c1, k1)``): ``ph = (zr,
    zi, xr, xi, fr, fi)`` its phasor ``zr + j zi`` and rate ``xr + j xi`` at sample
    ``s <= a`` and the rate's turn ``fr + j fi``; ``v`` (8,) each channel's weight and step
    per sample from sample 0 (re, im)."""
    c0, k0, c1, k1 = offs
    zr, zi, xr, xi, fr, fi = ph
    mask = acc.shape[1] - 1
    for k in range(s, b):
        if k >= a:
            u = k0 + k
            if u >= first:
                acc[c0, u & mask] += (v[0] + v[2] * k) * zi + (v[1] + v[3] * k) * zr
            u = k1 + k
            if two and u >= first:
                acc[c1, u & mask] += (v[4] + v[6] * k) * zi + (v[5] + v[7] * k) * zr
        zr, zi = zr * xr - zi * xi, zr * xi + zi * xr
        xr, xi = xr * fr - xi * fi, xr * fi + xi * fr
