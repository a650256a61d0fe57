"""Drive-train force signals (motors and gears) and their persistent streams (numba).

A driven joint's vibration force at sample ``k`` of a block is

    f[k] = a[k] ( sum_c A_c sin(phi_c[k]) + b y[k] )

with ``a[k]`` the force scale [N] (transmitted torque over the drive's radius, times the
speed gate; :mod:`mjsound.sim.actuators`), interpolated linearly from ``a0`` to ``a1`` over
the block; ``phi_c`` the phase of tonal component ``c`` at ``order_c`` times the rotor's
rate: ``phi_c[k+1] = phi_c[k] + order_c w[k] / fs`` with the rotor speed ``w[k]`` [rad/s]
linear from ``w0`` to ``w1`` (phases carry over blocks: the tones are continuous while the
speed changes); a component above ``0.45 fs`` is left out (no aliasing); ``y`` unit-variance
noise low-passed at the first tonal component's frequency (the broadband part, relative
level ``b``). The phasor of each component turns by a rotation recomputed every
:data:`HOLD` samples (the frequency is held that long, 1/3 ms at 48 kHz) and renormalised
there.

Streams: each signal enters the synthesizer as a persistent stream (:mod:`.stream_table`,
the sliding contacts' machinery): its ring holds the force samples, its world point and
direction set the gains (refreshed every ``regain`` samples, :func:`.streams.stream_gains`).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .streams import _INV16, _M16, _S16, _S32, _S48, _SQRT3, _splitmix, ring_need

__all__ = ["HOLD", "drive_tones", "streams_write"]

#: Samples a tonal component's frequency is held before its rotation is recomputed.
HOLD = 16


@njit(cache=True)
def drive_tones(w, a, comp_off, order, amp, phase, broadband, rng, lp, fs, out):
    """Fill ``out[j, :]`` with actuator ``j``'s force signal (see the module's formula).

    Parameters
    ----------
    w : (J, 2) float64, rotor speed at the block's start and end [rad/s]
    a : (J, 2) float64, force scale at the block's start and end [N]
    comp_off : (J + 1,) int64, actuator ``j``'s components ``comp_off[j]:comp_off[j+1]``
    order, amp : (C,) float64, multiple of the rotor's rate and relative amplitude per component
    phase : (C,) float64, each component's phase [rad] (updated: the block's end)
    broadband : (J,) float64, relative level ``b`` of the broadband noise
    rng : (J,) int64, per actuator the noise generator's splitmix64 state (updated)
    lp : (J,) float64, per actuator the noise low-pass's output (updated)
    fs : float, sample rate [Hz]
    out : (J, L) float64, the force [N] (written)
    """
    J, L = out.shape
    w0, w1, a0, a1 = w[:, 0], w[:, 1], a[:, 0], a[:, 1]
    nyq = 0.45 * fs
    two_pi = 2.0 * math.pi
    for j in range(J):
        for k in range(L):
            out[j, k] = 0.0
        if a0[j] == 0.0 and a1[j] == 0.0:
            continue
        da = (a1[j] - a0[j]) / L
        dw = (w1[j] - w0[j]) / L
        for c in range(comp_off[j], comp_off[j + 1]):
            ph = phase[c]
            cr = math.cos(ph)
            ci = math.sin(ph)
            A = amp[c]
            k = 0
            while k < L:
                w = abs(w0[j] + dw * (k + 0.5 * HOLD)) * order[c]  # [rad/s], held for HOLD samples
                n = min(HOLD, L - k)
                step = w / fs
                if w / two_pi < nyq:
                    rr = math.cos(step)
                    ri = math.sin(step)
                    for q in range(k, k + n):
                        out[j, q] += A * (a0[j] + da * q) * ci
                        t = cr * rr - ci * ri
                        ci = cr * ri + ci * rr
                        cr = t
                ph = (ph + n * step) % two_pi
                cr = math.cos(ph)  # (renormalised: no drift of the phasor's length)
                ci = math.sin(ph)
                k += n
            phase[c] = ph
        b = broadband[j]
        if b > 0.0:
            c0 = comp_off[j]
            fc = min(abs(0.5 * (w0[j] + w1[j])) * (order[c0] if comp_off[j + 1] > c0 else 1.0) / two_pi, nyq)
            alpha = 1.0 - math.exp(-two_pi * fc / fs)
            state = np.uint64(rng[j])
            y = lp[j]
            for q in range(L):
                state, z = _splitmix(state)
                x = (np.float64(z & _M16) + np.float64((z >> _S16) & _M16) + np.float64((z >> _S32) & _M16)
                     + np.float64(z >> _S48) + 2.0) * _INV16 - 2.0
                y = alpha * (x * _SQRT3) + (1.0 - alpha) * y
                out[j, q] += b * (a0[j] + da * q) * y
            rng[j] = np.int64(state)
            lp[j] = y


@njit(cache=True)
def streams_write(streams, consts, sidx, sign, k0, F, P, D, regain):
    """Drive stream ``sidx[r]`` (-1: none) on synth samples ``[k0, k0 + L)`` with the force
    ``sign[r] * F[j(r)]`` [N] at world point ``P[j(r)]`` along unit ``D[j(r)]``, ``j(r) = r // 2``
    (two sides per actuator: its body and its parent, equal and opposite). An all-zero signal
    is not written (the stream falls silent after its last samples). Returns 0, or the ring
    length needed first (nothing written then)."""
    L = F.shape[1]
    k1 = k0 + L
    cap = streams.ring.shape[1]
    for r in range(sidx.shape[0]):
        s = sidx[r]
        if s >= 0:
            need = ring_need(streams, consts, s, k1)
            if need > cap:
                return need
    ring = streams.ring
    mask = cap - 1
    for r in range(sidx.shape[0]):
        s = sidx[r]
        if s < 0:
            continue
        j = r // 2
        live = False
        for q in range(L):
            if F[j, q] != 0.0:
                live = True
                break
        if not live:
            continue
        st = streams.table[s]
        for c in range(3):
            st.p[c] = P[j, c]
            st.n[c] = sign[r] * D[j, c]
        g = st.gupd
        if k0 >= g + regain or k0 < g:
            st.gupd = k0
            st.due = 1
        k = st.gen
        if k < k1 - cap:
            k = k1 - cap
        sg = sign[r]
        while k < k1:
            ring[s, k & mask] = sg * F[j, k - k0] if k >= k0 else 0.0
            k += 1
        st.k0 = k0
        st.k1 = k1
        st.amp = 1.0
        if k1 > st.gen:
            st.gen = k1
        if k1 > st.last:
            st.last = k1
    return 0
