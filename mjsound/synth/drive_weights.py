"""The drive lines' weights: each tonal component's complex weight per microphone, from the
driven links' transfer functions, once per block (:func:`line_weights`; the rendering that
uses them: :mod:`.drive_lines`).

A mode of pole ``p_i`` driven with gain ``g_i`` (a microphone's stream gain, times the
direction factor of a turning, directional link) answers a tonal force ``sin(phi_k)``,
``phi_{k+1} - phi_k = theta``, in the steady state with ``Im(W e^{j phi})``,

    W = (H(theta) - conj(H(-theta))) / 2j,    H(theta) = sum_i g_i / (1 - p_i e^{-j theta}),

summed over the modes of the (up to two) bodies an actuator pushes, each with its sign and a
delay beyond the microphone's own as the phase ``e^{-j theta dD}``; the broadband part is
heard through the static response ``Im H(0)``, and where its resonant part matters the modes
that hold it are kept to run (:mod:`.drive_broadband`). The full derivation, and what the
lines leave out, is in :mod:`.drive_lines`. The per-body helpers (:func:`_transfer_sums`,
:func:`_phase_steps`, the direction factors) allocate nothing and are compiled without
reference counting (``_nrt=False``, :mod:`.drive_gains`' docstring); :func:`line_weights`
allocates one scratch array a block.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from .bank_loops import FAST
from .drive_directions import direction_factors
from .drive_lanes import cpow
from .drive_tones import noise_cutoff_hz
from .records import AIR

__all__ = ["line_weights"]


@njit(cache=True, inline="always")
def _cpow(z, n):
    """``z^n`` for an integer ``n >= 0`` (by squaring: a delay's phase without a sine)."""
    out = complex(1.0, 0.0)
    while n > 0:
        if n & 1:
            out *= z
        z *= z
        n >>= 1
    return out


@njit(cache=True)
def line_weights(view, act, lw, bg, fs):
    """Each component's complex weight ``lw.W1[c, m]`` (without the force scale; see the
    module) at the rotor speeds ``act.w1`` [rad/s], each actuator's broadband gain
    ``lw.B1[j, m]`` (the static ``Im H(0)``), each microphone's delay ``lw.Dm[m]`` [samples],
    each actuator's resonant broadband power and everything it makes heard (``lw.power``:
    what :func:`.drive_broadband.broadband_route` chooses the broadband's route by) and, per driven body, its modes' static response and resonant
    broadband power (``bg.static``, ``bg.resonant``). The bodies' gains and delays are
    ``bg.gr, gi, D`` (:func:`.drive_gains.bodies_gains`); an air microphone hears a
    directional object's modes times their direction factor towards it now (as the exact
    rendering's forcing rows, from the fits' float32 copy ``view.dd``:
    :func:`.drive_directions.direction_factors`; ``bg.U, Fd`` the factors' cache).

    A body's weight for a component of step ``theta`` sums, per microphone, the real and
    imaginary parts of its modes' gains ``g = g_r + j g_i`` against two complex numbers per
    mode that depend on ``theta`` and the pole alone, made once for every microphone
    (:func:`_transfer_sums`: all of an actuator's components in one call).

    Parameters
    ----------
    view : :class:`SceneView` (the streams' records, poles, poses, microphones, channels,
        direction fits)
    act : :class:`Actuators`; lw : :class:`LineWeights`; bg : :class:`BodyGains`
    fs : float [Hz]

    Returns the largest of ``lw.Dm``.
    """
    gr, gi, D, static, resonant, U, Fd = bg.gr, bg.gi, bg.D, bg.static, bg.resonant, bg.U, bg.Fd
    W, B, Dm, power = lw.W1, lw.B1, lw.Dm, lw.power
    sidx, sign, ptr, rows, comp_off, tones, noise, w, a = (act.sidx, act.sign, act.ptr, act.rows, act.comp_off,
                                                           act.tones, act.noise, act.w1, act.a1)
    table, poles, mode_off, order = view.table, view.poles, view.mode_off, view.order
    C, M = W.shape
    J = B.shape[0]
    W[:, :] = 0.0
    B[:, :] = 0.0
    Dm[:] = -1
    for b in range(sidx.shape[0]):
        if sidx[b] < 0 or sign[b] == 0.0:
            continue
        for m in range(M):
            if Dm[m] < 0 or D[b, m] < Dm[m]:
                Dm[m] = D[b, m]
    for m in range(M):
        if Dm[m] < 0:
            Dm[m] = 0
    limit = 2.0 * math.pi * 0.45
    nmax = gr.shape[2]
    for b in range(sidx.shape[0]):
        for k in range(nmax):
            resonant[b, k] = 0.0
    # (the scratch in one allocation: per component its phase step and its cosine and sine;
    # per actuator its noise's one-pole and resonant power; per mode the pole, 1 / |1 - p|^2,
    # the terms alpha, beta; per microphone and mode the gain with its direction factor; per
    # component of an actuator and microphone the sums; per microphone whether it hears a direction)
    cmax = 0
    for j in range(J):
        cmax = max(cmax, comp_off[j + 1] - comp_off[j])
    buf = np.empty(3 * C + 2 * J + (7 + 2 * M) * nmax + 2 * cmax * M + M)
    th, cth, sth = buf[:C], buf[C:2 * C], buf[2 * C:3 * C]
    alpha, res = buf[3 * C:3 * C + J], buf[3 * C + J:3 * C + 2 * J]
    o1 = 3 * C + 2 * J
    pr, pi, q0 = buf[o1:o1 + nmax], buf[o1 + nmax:o1 + 2 * nmax], buf[o1 + 2 * nmax:o1 + 3 * nmax]
    ab = buf[o1 + 3 * nmax:o1 + 7 * nmax].reshape((4, nmax))
    o2 = o1 + 7 * nmax
    xr = buf[o2:o2 + M * nmax].reshape((M, nmax))
    xi = buf[o2 + M * nmax:o2 + 2 * M * nmax].reshape((M, nmax))
    o3 = o2 + 2 * M * nmax
    hs = buf[o3:o3 + 2 * cmax * M].reshape((2, cmax, M))
    heard = buf[o3 + 2 * cmax * M:o3 + 2 * cmax * M + M]
    # each component's phase step per sample and its cosine and sine, once (0 above the cut-off)
    _phase_steps(tones, comp_off, w, fs, limit, th, cth, sth)
    two_pi = 2.0 * math.pi
    for j in range(J):  # (res: the resonant broadband power per unit force scale)
        res[j] = 0.0
        fc = noise_cutoff_hz(tones, comp_off, j, w[j], fs)
        alpha[j] = 1.0 - math.exp(-two_pi * fc / fs)
    for b in range(sidx.shape[0]):
        s = sidx[b]
        if s < 0 or sign[b] == 0.0:
            continue
        o = table[s].obj
        m0 = mode_off[o]
        n = mode_off[o + 1] - m0
        for k in range(n):
            p = poles[m0 + k]
            pr[k] = p.real
            pi[k] = p.imag
            qr = 1.0 - p.real
            q0[k] = 1.0 / (qr * qr + p.imag * p.imag)
        for m in range(M):
            for k in range(n):
                xr[m, k] = gr[b, m, k]
                xi[m, k] = gi[b, m, k]
        if order[o] >= 0:
            direction_factors(xr, xi, n, o, view, U[b], Fd[b], heard)
        for m in range(M):  # the static response Im H(0) = Im sum g / (1 - p)
            for k in range(n):
                static[b, m, k] = (xi[m, k] * (1.0 - pr[k]) + xr[m, k] * pi[k]) * q0[k]
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)  # (this side's force along the body's direction)
            for m in range(M):
                h = 0.0
                for k in range(n):
                    h += static[b, m, k]
                B[j, m] += coef * h
            bb = noise[j].broadband
            if bb > 0.0:
                al = alpha[j]
                q = 1.0 - al
                for k in range(n):
                    # the one-pole's power spectrum at the mode, alpha^2 / |1 - (1 - alpha) e^{-j w}|^2,
                    # times the mode's power gain 1 / (2 (1 - |p|^2)) and |g|^2 summed over the microphones
                    p2 = pr[k] * pr[k] + pi[k] * pi[k]
                    g2 = 0.0
                    for m in range(M):
                        g2 += xr[m, k] * xr[m, k] + xi[m, k] * xi[m, k]
                    e = bb * bb * al * al * g2 / ((1.0 - 2.0 * q * pr[k] / math.sqrt(p2) + q * q) * 2.0 * (1.0 - p2))
                    res[j] += e
                    resonant[b, k] += e * a[j] * a[j]
            c0, c1 = comp_off[j], comp_off[j + 1]
            _transfer_sums(pr, pi, n, cth, sth, th, c0, c1, xr, xi, ab, hs)
            for c in range(c0, c1):
                if th[c] == 0.0:
                    continue
                amp = 0.5 * coef * tones[c].amp
                z = complex(cth[c], -sth[c])
                for m in range(M):
                    # (this body's delay beyond the microphone's, dd >= 0 samples: the phase e^{-j th dd})
                    W[c, m] += amp * _cpow(z, D[b, m] - Dm[m]) * complex(hs[0, c - c0, m], hs[1, c - c0, m])
    for j in range(J):
        bb = noise[j].broadband
        b2 = 0.0
        for m in range(M):
            b2 += B[j, m] * B[j, m]
        total = res[j] + bb * bb * alpha[j] / (2.0 - alpha[j]) * b2
        for c in range(comp_off[j], comp_off[j + 1]):
            for m in range(M):
                total += 0.5 * (W[c, m].real ** 2 + W[c, m].imag ** 2)
        power[j, 0] = res[j]
        power[j, 1] = total
    dmax = 0
    for m in range(M):
        dmax = max(dmax, Dm[m])
    return dmax


@njit_inner(cache=True, _nrt=False)
def _phase_steps(tones, comp_off, w, fs, limit, th, cth, sth):
    """Each component's phase step per sample ``t = order w / fs`` into ``th`` (0 where
    ``|t| >= limit``: above the cut-off) and ``cos t``, ``sin t`` into ``cth, sth``; a
    component at twice or three times the order of one before it of the same actuator (the
    presets' harmonics) from that one's by the double- and triple-angle products (a sine and
    cosine fewer; within a few ulp of ``math.cos``, ``math.sin``)."""
    for j in range(w.shape[0]):
        c0 = comp_off[j]
        for c in range(c0, comp_off[j + 1]):
            t = tones[c].order * w[j] / fs
            th[c] = t if abs(t) < limit else 0.0
            h = 0
            cb = c0
            while cb < c and h == 0:
                ob = tones[cb].order
                h = 2 if ob * 2.0 == tones[c].order else (3 if ob * 3.0 == tones[c].order else 0)
                cb += 1
            if h:
                cr, ci = cpow(cth[cb - 1], sth[cb - 1], h)
                cth[c] = cr
                sth[c] = ci
            else:
                cth[c] = math.cos(t)
                sth[c] = math.sin(t)


@njit_inner(cache=True, fastmath=FAST, error_model="numpy", _nrt=False)
def _transfer_sums(pr, pi, n, cth, sth, th, c0, c1, xr, xi, ab, hs):
    """One body's ``2 W`` at each microphone for components ``c0 .. c1`` (phase steps ``th``,
    their cosines and sines ``cth, sth``; 0: none) into ``hs[0] + j hs[1]`` (c - c0, m), from
    its ``n`` modes' poles ``pr + j pi`` and gains ``xr + j xi`` (m, :n). With
    ``A = 1 / (1 - p e^{-j theta})`` and ``Bc = 1 / (1 - conj(p) e^{-j theta})``,

        g A - conj(g) Bc = g_r (A - Bc) + j g_i (A + Bc),   so   2 W = 2 (H(theta) - conj(H(-theta))) / 2j
        = sum g_r alpha + g_i beta,   alpha = -j (A - Bc),   beta = A + Bc,

    ``A = (x_r - j x_i) / |x|^2``, ``x = 1 - p e^{-j theta}``; ``Bc = (y_r + j y_i) / |y|^2``,
    ``y = 1 - p e^{+j theta}`` (one division for both): the terms ``alpha, beta`` once per
    mode for every microphone (``ab`` (4, >= n) scratch), then one sum over the modes per
    microphone (``fastmath``: both loops vectorised; ``error_model="numpy"``: the division
    without Python's zero test, which kept the first loop scalar; ``|x|, |y| > 0`` as ``|p| < 1``)."""
    ar, ai, br, bi = ab[0], ab[1], ab[2], ab[3]
    for c in range(c0, c1):
        if th[c] == 0.0:
            continue
        cr = cth[c]
        ci = sth[c]
        for k in range(n):
            p = pr[k]
            q = pi[k]
            xr_ = 1.0 - (p * cr + q * ci)
            xi_ = p * ci - q * cr
            yr_ = 1.0 - (p * cr - q * ci)
            yi_ = -(q * cr + p * ci)
            x2 = xr_ * xr_ + xi_ * xi_
            y2 = yr_ * yr_ + yi_ * yi_
            inv = 1.0 / (x2 * y2)
            u = y2 * inv
            v = x2 * inv
            ar[k] = -(xi_ * u + yi_ * v)
            ai[k] = yr_ * v - xr_ * u
            br[k] = xr_ * u + yr_ * v
            bi[k] = yi_ * v - xi_ * u
        for m in range(xr.shape[0]):
            re = 0.0
            im = 0.0
            for k in range(n):
                re += xr[m, k] * ar[k] + xi[m, k] * br[k]
                im += xr[m, k] * ai[k] + xi[m, k] * bi[k]
            hs[0, c - c0, m] = re
            hs[1, c - c0, m] = im
