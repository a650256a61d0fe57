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
lines leave out, is in :mod:`.drive_lines`.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .directivity import _factor, real_sh
from .drive_broadband import RESONANT_OFF, RESONANT_ON
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
    whether each actuator's broadband part goes through the modes (``lw.exact``, ``lw.power``:
    :mod:`.drive_broadband`) and, per driven body, its modes' static response and resonant
    broadband power (``bg.static``, ``bg.resonant``). The bodies' gains and delays are
    ``bg.gr, gi, D`` (:func:`.drive_gains.bodies_gains`); an air microphone hears a
    directional object's modes times their direction factor towards it now (as the exact
    rendering's forcing rows; ``bg.U, Fd`` the factors' cache).

    Parameters
    ----------
    view : :class:`SceneView` (the streams' records, poles, poses, microphones, channels,
        direction fits)
    act : :class:`Actuators`; lw : :class:`LineWeights`; bg : :class:`BodyGains`
    fs : float [Hz]

    Returns the largest of ``lw.Dm``.
    """
    gr, gi, D, static, resonant, U, Fd = bg.gr, bg.gi, bg.D, bg.static, bg.resonant, bg.U, bg.Fd
    W, B, Dm, exact, power = lw.W1, lw.B1, lw.Dm, lw.exact, lw.power
    sidx, sign, ptr, rows, comp_off, tones, noise, w, a = (act.sidx, act.sign, act.ptr, act.rows, act.comp_off,
                                                           act.tones, act.noise, act.w1, act.a1)
    table, poles, mode_off = view.table, view.poles, view.mode_off
    C, M = W.shape
    J = B.shape[0]
    for c in range(C):
        for m in range(M):
            W[c, m] = 0.0
    for j in range(J):
        for m in range(M):
            B[j, m] = 0.0
    for m in range(M):
        Dm[m] = -1
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
    # each component's phase step per sample and its cosine and sine, once (0 above the cut-off)
    th = np.empty(C)
    cth = np.empty(C)
    sth = np.empty(C)
    for j in range(J):
        for c in range(comp_off[j], comp_off[j + 1]):
            t = tones[c].order * w[j] / fs
            th[c] = t if abs(t) < limit else 0.0
            cth[c] = math.cos(t)
            sth[c] = math.sin(t)
    pr = np.empty(nmax)
    pi = np.empty(nmax)
    q0 = np.empty(nmax)
    g = np.empty((M, nmax), np.complex128)
    h0 = np.empty(M)
    Hp = np.empty(M, np.complex128)
    Hn = np.empty(M, np.complex128)
    sh = np.empty(M, np.complex128)
    two_pi = 2.0 * math.pi
    res = np.zeros(J)  # the resonant broadband power per unit force scale
    alpha = np.empty(J)
    for j in range(J):
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
            resonant[b, k] = 0.0
            for m in range(M):
                g[m, k] = complex(gr[b, m, k], gi[b, m, k])
        if view.order[o] >= 0:
            _direction_factors(g, n, o, m0, view, U[b], Fd[b])
        for k in range(n):
            qr = 1.0 - pr[k]
            q0[k] = 1.0 / (qr * qr + pi[k] * pi[k])
        for m in range(M):  # the static response Im H(0) = Im sum g / (1 - p)
            h = 0.0
            for k in range(n):
                x = g[m, k]
                static[b, m, k] = (x.imag * (1.0 - pr[k]) + x.real * pi[k]) * q0[k]
                h += static[b, m, k]
            h0[m] = h
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            coef = sign[b] * (1.0 if rows[i] % 2 == 0 else -1.0)  # (this side's force along the body's direction)
            for m in range(M):
                B[j, m] += coef * h0[m]
            bb = noise[j].broadband
            if bb > 0.0:
                al = alpha[j]
                q = 1.0 - al
                for k in range(n):
                    # the one-pole's power spectrum at the mode, alpha^2 / |1 - (1 - alpha) e^{-j w}|^2
                    p2 = pr[k] * pr[k] + pi[k] * pi[k]
                    S = al * al / (1.0 - 2.0 * q * pr[k] / math.sqrt(p2) + q * q)
                    den = 2.0 * (1.0 - p2)
                    for m in range(M):
                        x = g[m, k]
                        e = bb * bb * (x.real * x.real + x.imag * x.imag) * S / den
                        res[j] += e
                        resonant[b, k] += e * a[j] * a[j]
            for c in range(comp_off[j], comp_off[j + 1]):
                t = th[c]
                if t == 0.0:
                    continue
                cr = cth[c]
                ci = sth[c]
                for m in range(M):
                    Hp[m] = 0.0
                    Hn[m] = 0.0
                    # (this body's delay beyond the microphone's, dd >= 0 samples: the phase e^{-j th dd})
                    sh[m] = _cpow(complex(cr, -ci), D[b, m] - Dm[m])
                for k in range(n):
                    # 1 / (1 - p e^{-j th}) and 1 / (1 - p e^{+j th}), once for every microphone
                    xr = 1.0 - (pr[k] * cr + pi[k] * ci)
                    xi = pr[k] * ci - pi[k] * cr
                    yr = 1.0 - (pr[k] * cr - pi[k] * ci)
                    yi = -(pi[k] * cr + pr[k] * ci)
                    x2 = xr * xr + xi * xi
                    y2 = yr * yr + yi * yi
                    inv = 1.0 / (x2 * y2)  # (one division for both)
                    u = y2 * inv
                    v = x2 * inv
                    ip = complex(xr * u, -xi * u)
                    iq = complex(yr * v, -yi * v)
                    for m in range(M):
                        Hp[m] += g[m, k] * ip
                        Hn[m] += g[m, k] * iq
                for m in range(M):
                    W[c, m] += coef * tones[c].amp * sh[m] * (Hp[m] - Hn[m].conjugate()) * -0.5j
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
        exact[j] = res[j] > (RESONANT_OFF if exact[j] else RESONANT_ON) * total
    dmax = 0
    for m in range(M):
        dmax = max(dmax, Dm[m])
    return dmax


@njit(cache=True)
def _direction_factors(g, n, o, m0, dr, U, Fd):
    """``g[m, :n]`` (object ``o``'s modes, the first at ``m0`` of the flat order) times each
    mode's direction factor towards air microphone ``m`` now (:func:`.directivity.hear_directions`'
    target: the fit at ``u = R^T (mic - pos) / r``, its magnitude floored), made again only
    when ``u`` turned by more than the synthesizer's step since the factors ``Fd[m]`` were
    made for ``U[m]`` (a body's own cache; NaN: never made); ``dr``: a :class:`SceneView`."""
    mics, pos, R, channels = dr.mics, dr.pos, dr.R, dr.channels
    prm = dr.params[0]
    floor = prm.floor
    floor2 = floor * floor
    L = dr.order[o]
    for m in range(min(g.shape[0], mics.shape[0])):
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
        if not ux * U[m, 0] + uy * U[m, 1] + uz * U[m, 2] >= prm.cos_step:  # (NaN: never made)
            U[m, 0] = ux
            U[m, 1] = uy
            U[m, 2] = uz
            Y = dr.sh[0]  # (the synthesizer's scratch: one row of harmonics)
            real_sh(L, ux, uy, uz, Y, dr.sh_tab)
            for k in range(n):
                k0 = dr.msh_off[m0 + k]
                nsh = dr.msh_off[m0 + k + 1] - k0
                t = complex(1.0, 0.0)
                if nsh > 0:
                    fr, fi = _factor(Y[:nsh], dr.coef_r[k0:k0 + nsh], dr.coef_i[k0:k0 + nsh])
                    t = complex(fr, fi)
                    a2 = t.real * t.real + t.imag * t.imag
                    if not a2 >= floor2:
                        t = t * (floor / np.sqrt(a2)) if a2 > 0.0 else complex(floor, 0.0)
                Fd[m, k] = t
        for k in range(n):
            g[m, k] *= Fd[m, k]
