"""Drive-train force signals (motors and gears) and their persistent streams (numba).

A driven joint's vibration force at sample ``k`` of a block is

    f[k] = a[k] ( sum_c A_c sin(phi_c[k]) + b y[k] )

with ``a[k]`` the force scale [N] (transmitted torque over the drive's radius, times the
speed gate; :mod:`mjsound.sim.actuators`), interpolated linearly from ``a0`` to ``a1`` over
the block; ``phi_c`` the phase of tonal component ``c`` at ``order_c`` times the rotor's
angle: ``phi_c[k+1] = phi_c[k] + d_c[k]``, ``d_c[k] = order_c w[k] / fs`` with the signed
rotor speed ``w[k] = w0 + (w1 - w0) k / L`` [rad/s] (phases carry over blocks: the tones
are continuous while the speed changes, and through a reversal); a component's samples
whose frequency ``|d_c| fs / 2 pi`` is above ``0.45 fs`` are left out (no aliasing); ``y``
unit-variance noise low-passed at the first tonal component's frequency (the broadband
part, relative level ``b``).

No sine per sample: each component is a recursive oscillator, the phasor
``z[k+1] = z[k] r[k]`` turned by ``r[k] = e^{j d_c[k]}``, itself turned by the constant
``e^{j (d_c[k+1] - d_c[k])}`` (a linear chirp), run as four interleaved recursions
(:func:`tone_add`); the phase is set exactly from
``phi_c[0]`` at each block's start and stored exactly at its end (``phi_c[L] = phi_c[0] +
L d_c[0] + (L (L - 1) / 2) (d_c[1] - d_c[0])``), so rounding never accumulates over blocks.

Streams: one persistent stream per driven body (:mod:`.stream_table`, the sliding contacts'
machinery) carries the sum of the drive forces on that body (an actuator pushes its joint's
body and, equal and opposite, the parent; a link between two joints gets both): its ring
holds the force samples, its world point and direction (the strongest drive's) set the
gains (refreshed every ``regain`` samples, :func:`.streams.stream_gains`). One stream per
body instead of one per (actuator, side) renders fewer forcing rows.
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .bank_loops import fma
from .streams import SQRT3, noise_draw, ring_need, stream_aim, stream_written

__all__ = ["audible_span", "tone_add", "drive_tones", "drive_direction", "aim_at_drive", "advance_phase", "wrap_phase",
           "noise_cutoff_hz", "streams_write", "DRIVE", "TONE", "NOISE"]

#: A tonal component of an actuator's force: its multiple of the rotor's rate, its amplitude
#: relative to the force scale and its phase [rad] (carried from block to block).
TONE = np.dtype([("order", np.float64), ("amp", np.float64), ("phase", np.float64)])
#: An actuator's broadband noise: its level relative to the force scale, the generator's
#: splitmix64 state and the low-pass's last output (both carried from block to block).
NOISE = np.dtype([("broadband", np.float64), ("rng", np.int64), ("lp", np.float64)])
#: An actuator's transmission as the stream writer reads it: its joint's id and whether
#: that joint slides (else it is a hinge).
DRIVE = np.dtype([("joint", np.int64), ("slide", np.bool_)])


@njit(cache=True)
def audible_span(s0, ds, limit, L):
    """Samples ``[lo, hi)`` of ``0 <= k < L`` whose phase increment ``|s0 + ds k|`` [rad] is
    below ``limit`` (a linear frequency sweep stays under the cut-off on one interval)."""
    if ds == 0.0:
        return (0, L) if abs(s0) < limit else (0, 0)
    ka = (-limit - s0) / ds
    kb = (limit - s0) / ds
    if ka > kb:
        ka, kb = kb, ka
    lo = 0 if ka < 0.0 else (L if ka >= L else np.int64(math.floor(ka)) + 1)  # (no overflow for a tiny ds)
    hi = L if kb > L else (0 if kb <= 0.0 else np.int64(math.ceil(kb)))
    return (lo, hi) if hi > lo else (0, 0)


@njit(cache=True, inline="always")
def tone_add(out, A, ph, s0, ds, lo, hi):
    """``out[k] += A sin(phi_k)`` for ``lo <= k < hi``, ``phi_k = ph + s0 k + ds k (k - 1) / 2``
    [rad] (a linear chirp), by recursion: four interleaved oscillators (samples ``4 m + i``),
    each phasor ``z_i`` turned per step by ``q_i = e^{j (phi_{k+4} - phi_k)}``, itself turned
    by ``e^{j 16 ds}``: independent recursions, so they overlap in the processor."""
    e1 = complex(math.cos(ds), math.sin(ds))
    r = complex(math.cos(s0), math.sin(s0))  # e^{j d_0}, d_k = s0 + ds k
    z0 = complex(math.cos(ph), math.sin(ph))
    q0 = r  # (becomes R_0 = e^{j (d_0 + d_1 + d_2 + d_3)})
    z1 = z0 * r
    r *= e1
    q0 *= r
    z2 = z1 * r
    r *= e1
    q0 *= r
    z3 = z2 * r
    r *= e1
    q0 *= r
    # q_i = e^{j (4 s0 + ds (4 i + 6))}: q_{i+1} = q_i e^{j 4 ds}
    e4 = e1 * e1
    e4 = e4 * e4
    q1 = q0 * e4
    q2 = q1 * e4
    q3 = q2 * e4
    e16 = e4 * e4
    e16 = e16 * e16
    L = out.shape[0]
    if hi < L:  # (nothing to add past the cut-off: stop there)
        L = hi
    k = 0
    while k + 4 <= L:
        if lo <= k and k + 4 <= hi:
            out[k] += A * z0.imag
            out[k + 1] += A * z1.imag
            out[k + 2] += A * z2.imag
            out[k + 3] += A * z3.imag
        else:
            for i in range(4):
                if lo <= k + i and k + i < hi:
                    out[k + i] += A * (z0.imag if i == 0 else z1.imag if i == 1 else z2.imag if i == 2 else z3.imag)
        z0 *= q0
        z1 *= q1
        z2 *= q2
        z3 *= q3
        q0 *= e16
        q1 *= e16
        q2 *= e16
        q3 *= e16
        k += 4
    for i in range(L - k):
        if lo <= k + i and k + i < hi:
            out[k + i] += A * (z0.imag if i == 0 else z1.imag if i == 1 else z2.imag)


@njit(cache=True)
def drive_tones(w0, w1, a0, a1, comp_off, tones, noise, fs, out):
    """Fill ``out[j, :]`` with actuator ``j``'s force signal (see the module's formula).

    Parameters
    ----------
    w0, w1 : (J,) float64, rotor speed at the block's start and end [rad/s] (signed)
    a0, a1 : (J,) float64, force scale at the block's start and end [N]
    comp_off : (J + 1,) int64, actuator ``j``'s components ``comp_off[j]:comp_off[j+1]``
    tones : (C,) :data:`TONE` records, per component: ``order`` (multiple of the rotor's
        rate), ``amp`` (amplitude relative to the force scale), ``phase`` [rad] at the block's
        start (updated: its end)
    noise : (J,) :data:`NOISE` records, per actuator: ``broadband`` (relative level ``b`` of
        the broadband noise), ``rng`` (the generator's splitmix64 state) and ``lp`` (the
        low-pass's output), the last two updated
    fs : float, sample rate [Hz]
    out : (J, L) float64, the force [N] (written)

    Example
    -------
    >>> out = np.empty((1, 480))
    >>> tones = np.array([(10.0, 0.05, 0.0)], TONE)
    >>> drive_tones(np.array([100.0]), np.array([100.0]), np.ones(1), np.ones(1), np.array([0, 1]),
    ...             tones, np.zeros(1, NOISE), 48000.0, out)  # 0.05 sin(2 pi 159.2 Hz t)
    """
    J, L = out.shape
    limit = 2.0 * math.pi * 0.45  # [rad / sample]: 0.45 fs
    two_pi = 2.0 * math.pi
    for j in range(J):
        for k in range(L):
            out[j, k] = 0.0
        silent = a0[j] == 0.0 and a1[j] == 0.0
        dw = (w1[j] - w0[j]) / L
        for c in range(comp_off[j], comp_off[j + 1]):
            s0 = tones[c].order * w0[j] / fs
            ds = tones[c].order * dw / fs
            ph = tones[c].phase
            tones[c].phase = advance_phase(ph, s0, ds, L)  # (the rotor turns when silent too)
            if silent:
                continue
            lo, hi = audible_span(s0, ds, limit, L)
            if hi > lo:
                tone_add(out[j], tones[c].amp, ph, s0, ds, lo, hi)
    for j in range(J):
        if a0[j] == 0.0 and a1[j] == 0.0:
            continue
        da = (a1[j] - a0[j]) / L
        b = noise[j].broadband
        if b > 0.0:
            fc = noise_cutoff_hz(tones, comp_off, j, 0.5 * (w0[j] + w1[j]), fs)
            alpha = 1.0 - math.exp(-two_pi * fc / fs)
            state = np.uint64(noise[j].rng)
            y = noise[j].lp
            for q in range(L):
                state, x = noise_draw(state)
                y = alpha * (x * SQRT3) + (1.0 - alpha) * y
                out[j, q] = (a0[j] + da * q) * (out[j, q] + b * y)
            noise[j].rng = np.int64(state)
            noise[j].lp = y
        else:
            for q in range(L):
                out[j, q] *= a0[j] + da * q


@njit(cache=True, inline="always")
def drive_direction(axis, slide, out):
    """The direction [unit] a joint's drive force acts along: a slide's ``axis``; a hinge's
    ``axis x e`` normalised, ``e`` the world axis least aligned with ``axis`` (the first of
    equals)."""
    if slide:
        for c in range(3):
            out[c] = axis[c]
        return
    e = 0
    for c in range(1, 3):
        if abs(axis[c]) < abs(axis[e]):
            e = c
    # axis x unit(e): (axis[e+1], axis[e+2]) -> components e+1 = axis[e+2], e+2 = -axis[e+1]
    x = axis[(e + 1) % 3]
    y = axis[(e + 2) % 3]
    nrm = math.sqrt(x * x + y * y)
    if nrm < 1e-12:
        nrm = 1e-12
    out[e] = 0.0
    out[(e + 1) % 3] = y / nrm
    out[(e + 2) % 3] = -x / nrm


@njit(cache=True, inline="always")
def aim_at_drive(rec, row, drives, axis, anchor, k0, regain, nrm):
    """Aim a driven body's stream ``rec`` at one of its drives, ``row`` of the bodies' drive
    rows (actuator ``row // 2``; an even row is the side its force pushes along ``+nrm``):
    the force's direction into ``nrm`` (:func:`drive_direction`) and
    :func:`.streams.stream_aim` at the joint's anchor. Returns ``(sign, joint, due)``, ``due``
    whether the stream's gains are to be made now (``stream_aim``'s)."""
    jb = row // 2
    sg = 1.0 if row % 2 == 0 else -1.0
    jt = drives[jb].joint
    drive_direction(axis[jt], drives[jb].slide, nrm)
    return sg, jt, stream_aim(rec, anchor[jt], nrm, sg, k0, regain)


@njit(cache=True, inline="always")
def wrap_phase(x):
    """``x % (2 pi)`` (in ``[0, 2 pi)``) without libm's ``fmod``: ``x - k 2 pi``, ``k =
    floor(x / 2 pi)`` (one up or down where the division rounded across an integer), in one
    rounding (:func:`.bank_loops.fma`): exact where the remainder is (as ``fmod``'s), so
    the same as ``%`` for ``x >= 0``; for ``x < 0`` ``%`` rounds ``fmod(x, 2 pi) + 2 pi``,
    this the exact ``x - k 2 pi`` (a last bit apart at most)."""
    two_pi = 2.0 * math.pi
    k = float(math.floor(x / two_pi))
    r = fma(-k, two_pi, x)
    if r < 0.0:
        r = fma(-(k - 1.0), two_pi, x)
    elif r >= two_pi:
        r = fma(-(k + 1.0), two_pi, x)
    return r if r < two_pi else 0.0


@njit(cache=True, inline="always")
def advance_phase(phase, s0, ds, L):
    """A component's phase [rad] after ``L`` samples of its chirp (``s0`` [rad / sample] at
    the first, growing by ``ds`` a sample): ``phase + sum_{k < L} (s0 + k ds)``, exact, wrapped
    to [0, 2 pi) (:func:`wrap_phase`)."""
    return wrap_phase(phase + s0 * L + ds * (0.5 * L * (L - 1)))


@njit(cache=True, inline="always")
def noise_cutoff_hz(tones, comp_off, j, w, fs):
    """The low-pass corner of actuator ``j``'s broadband noise [Hz]: its first component's
    order (1 without components; ``tones``, ``comp_off`` as :func:`drive_tones`) times the
    rotor rate ``w`` [rad/s], at most ``0.45 fs``."""
    c0 = comp_off[j]
    return min(abs(w) * (tones[c0].order if comp_off[j + 1] > c0 else 1.0) / (2.0 * math.pi), 0.45 * fs)


@njit(cache=True)
def streams_write(streams, consts, sidx, ptr, rows, k0, F, a, anchor, axis, drives, regain):
    """Drive body stream ``sidx[b]`` (-1: none) on synth samples ``[k0, k0 + L)`` with the sum
    of the drive forces on body ``b``: rows ``r = rows[ptr[b]:ptr[b + 1]]``, actuator
    ``j = r // 2`` on its side ``r % 2`` (0: the joint's body, force ``+F[j]``; 1: its parent,
    ``-F[j]``, equal and opposite). The sum acts at the anchor ``anchor[joint[j*]]`` of the
    strongest acting actuator ``j*`` (largest force scale ``a``) along its direction
    (:func:`drive_direction` of ``axis[joint[j*]]``, ``drives[j*].slide``) times its side's sign.
    A body whose forces are all zero is not written (the stream falls silent after its last
    samples). Returns 0, or the ring length needed first (nothing written then).

    Parameters
    ----------
    streams, consts : the synthesizer's stream table state and constants
    sidx : (B,) int64, each body's stream
    ptr : (B + 1,) int64, rows : (R,) int64, the actuator sides on each body
    k0 : int, first synth sample
    F : (J, L) float64, the actuators' force signals [N] (:func:`drive_tones`)
    a : (J,) float64, their force scales now [N] (picks the strongest)
    anchor, axis : (n_joints, 3) float64, MuJoCo's ``data.xanchor``, ``data.xaxis``
    drives : (J,) :data:`DRIVE` records, each actuator's ``joint`` and ``slide`` (whether it slides)
    regain : int, samples between the gains' refreshes
    """
    L = F.shape[1]
    k1 = k0 + L
    cap = streams.ring.shape[1]
    for b in range(sidx.shape[0]):
        s = sidx[b]
        if s >= 0:
            need = ring_need(streams, consts, s, k1)
            if need > cap:
                return need
    ring = streams.ring
    mask = cap - 1
    nrm = np.empty(3)
    v = np.empty(L)
    for b in range(sidx.shape[0]):
        s = sidx[b]
        if s < 0:
            continue
        best = -1
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            live = False
            for q in range(L):
                if F[j, q] != 0.0:
                    live = True
                    break
            if live and (best < 0 or a[j] > a[rows[best] // 2]):
                best = i
        if best < 0:
            continue
        st = streams.table[s]
        sg, _, _ = aim_at_drive(st, rows[best], drives, axis, anchor, k0, regain, nrm)
        k = st.gen
        if k < k1 - cap:
            k = k1 - cap
        while k < k0:
            ring[s, k & mask] = 0.0
            k += 1
        # the sum, signed so that the strongest drive pushes along +nrm, then into the ring
        # (two contiguous runs, around its wrap)
        for i in range(ptr[b], ptr[b + 1]):
            j = rows[i] // 2
            f = sg if rows[i] % 2 == 0 else -sg
            if i == ptr[b]:
                for q in range(L):
                    v[q] = f * F[j, q]
            else:
                for q in range(L):
                    v[q] += f * F[j, q]
        r0 = k0 & mask
        n0 = min(L, cap - r0)
        for q in range(n0):
            ring[s, r0 + q] = v[q]
        for q in range(n0, L):
            ring[s, q - n0] = v[q]
        stream_written(st, k0, k1)
    return 0
