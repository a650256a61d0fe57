"""The motor housing's direct airborne part of a drive's lines (:mod:`.drive_lines`).

A drive's motor and gearbox radiate from their housing as well as through the links they
shake. The housing is a compact source at the joint's anchor ``x_a`` (MuJoCo's
``data.xanchor``), a monopole whose pressure follows the drive's own force: per actuator
``j`` with housing coefficient ``K_j`` [Pa m / N] (:attr:`mjsound.sim.actuators.
ActuatorPreset.housing`), at an air microphone ``m`` at distance ``r = max(|x_m - x_a|, rmin)``,

    p_m(t) = K_j f_j(t - r / c) / r        [Pa],

``f_j = a (sum_c A_c sin(phi_c) + b y)`` the drive's force [N] (:mod:`.drive_tones`). In the
lines' terms (a line at microphone ``m`` is ``Im(a W_cm e^{j phi_c})`` written ``D_m``
samples after its source sample, :func:`.drive_weights.line_weights`) each tonal component's
weight gains

    W_cm += K_j A_c e^{-j theta_c (r fs / c - D_m)} / r,

``theta_c`` its phase step per sample at the block's end (the housing's delay beyond the
microphone's, possibly negative: exact for a steady speed, like the bodies' delays), and
each actuator's static broadband gain ``B_jm += K_j / r`` (the noise heard at the
microphone's delay ``D_m``, not its own: the low-passed noise is shifted by the difference,
under a millisecond where the housing is within 30 cm of the nearest driven body's centre).

Air microphones hear it, and image microphones too (the floor's and a room's reflections,
:mod:`mjsound.sim.images`: the image's position in ``r``, its surfaces' reflection factor
``R(f)`` (its channel response, log-linear between the bands, ``lw.response``) on each tone
at the tone's frequency and on the broadband gain at ``f_n / sqrt(2)``, ``f_n`` the noise's
corner, the top octave below which its power lies); not contact microphones (their
channels are bit for bit those without it).
The weights are added after :func:`.drive_weights.line_weights` has decided which broadband
parts ring the modes, so that decision, too, is the one without the housing. The modal
rendering (``ActuatorSound.rendering == "modal"``) has no housing part.
"""

from __future__ import annotations

import math

from ..jit import njit
from .drive_tones import noise_cutoff_hz
from .records import AIR

__all__ = ["housing_weights", "reflection_at"]


@njit(cache=True, _nrt=False)
def reflection_at(resp, f):
    """An image microphone's reflection factor at ``f`` [Hz] from its response ``resp`` (2, k):
    the natural logarithms of its frequencies [Hz] (increasing; padded with ``inf``) and its
    gains, linear in log frequency between them and constant outside, as the synthesizer's
    channel response (:meth:`mjsound.synth.synthesizer.Synthesizer.response_at`); 1 without
    points. (The table in logarithms: one logarithm a call.)"""
    k = resp.shape[1]
    n = 0
    while n < k and resp[0, n] < math.inf:
        n += 1
    if n == 0:
        return 1.0
    lf = math.log(f) if f > 0.0 else -math.inf
    if not lf > resp[0, 0]:
        return resp[1, 0]
    i = 1
    while i < n and resp[0, i] < lf:
        i += 1
    if i >= n:
        return resp[1, n - 1]
    a = (lf - resp[0, i - 1]) / (resp[0, i] - resp[0, i - 1])
    return resp[1, i - 1] + a * (resp[1, i] - resp[1, i - 1])


@njit(cache=True, _nrt=False)  # (no reference counts: .drive_gains' docstring)
def housing_weights(ks, act, lw, anchor, fs):
    """Add each actuator's housing part (module docstring) to the lines' weights ``lw.W1``
    (C, M) and static broadband gains ``lw.B1`` (J, M) at the air and image microphones (an
    image's reflection from ``lw.response``, :func:`reflection_at`), at the rotor
    speeds ``act.w1`` and with the microphones' delays ``lw.Dm`` (both as
    :func:`.drive_weights.line_weights` left them). An actuator with ``act.housing[j] == 0``
    changes nothing.

    Parameters
    ----------
    ks : :class:`.records.SynthState` (microphones, channels, constants: ``c`` [m/s], ``rmin`` [m])
    act : :class:`.drive_lines.Actuators`; lw : :class:`.drive_lines.LineWeights`
    anchor : (n_joints, 3) float64, MuJoCo's ``data.xanchor`` [m]
    fs : float [Hz]

    Example
    -------
    One tone (order 10, ``A = 0.05``) of a drive with ``K = 0.01`` Pa m/N at a microphone
    1 m from the anchor whose delay is the housing's: ``W += 0.01 * 0.05 / 1``, real.
    """
    housing, comp_off, tones, w, drives = act.housing, act.comp_off, act.tones, act.w1, act.drives
    W, B, Dm, resp = lw.W1, lw.B1, lw.Dm, lw.response
    cst = ks.consts[0]
    c, rmin = cst.c, cst.rmin
    mics, channels = ks.mics, ks.channels
    M = min(W.shape[1], mics.shape[0])
    limit = 2.0 * math.pi * 0.45
    for j in range(housing.shape[0]):
        K = housing[j]
        if K == 0.0:
            continue
        jt = drives[j].joint
        fb = noise_cutoff_hz(tones, comp_off, j, w[j], fs) / math.sqrt(2.0)  # (where an image reads the broadband's reflection)
        for m in range(M):
            if channels[m].owner != AIR:  # (contact microphones)
                continue
            image = channels[m].w_off >= 0 and m < resp.shape[0]  # (an image microphone: its reflection)
            dx = mics[m, 0] - anchor[jt, 0]
            dy = mics[m, 1] - anchor[jt, 1]
            dz = mics[m, 2] - anchor[jt, 2]
            r = math.sqrt(dx * dx + dy * dy + dz * dz)
            if not r >= rmin:  # (closer than the synthesizer's least distance, or NaN)
                r = rmin if math.isfinite(r) else math.inf
            if not math.isfinite(r):
                continue
            g = K / r
            dd = r * fs / c - Dm[m]  # (samples of delay beyond the microphone's)
            B[j, m] += g * reflection_at(resp[m], fb) if image else g
            o1 = o2 = math.nan  # (the last two components' orders and phasors: a harmonic's base; NaN: none)
            c1 = s1 = c2 = s2 = 0.0
            for q in range(comp_off[j], comp_off[j + 1]):
                order = tones[q].order
                t = order * w[j] / fs
                if not abs(t) < limit:
                    continue
                # e^{-j t dd}; for a harmonic (order h o_b, h 2 or 3) of one of the last two, the
                # base's phasor to the power h (its phase h times the base's but for rounding:
                # one cosine and sine fewer)
                if order == 2.0 * o1 or order == 2.0 * o2:
                    br, bi = (c1, s1) if order == 2.0 * o1 else (c2, s2)
                    cr, ci = br * br - bi * bi, 2.0 * br * bi
                elif order == 3.0 * o1 or order == 3.0 * o2:
                    br, bi = (c1, s1) if order == 3.0 * o1 else (c2, s2)
                    sr, si = br * br - bi * bi, 2.0 * br * bi
                    cr, ci = sr * br - si * bi, sr * bi + si * br
                else:
                    x = -t * dd
                    cr, ci = math.cos(x), math.sin(x)
                o2, c2, s2 = o1, c1, s1
                o1, c1, s1 = order, cr, ci
                gq = g * reflection_at(resp[m], abs(t) * fs / (2.0 * math.pi)) if image else g
                W[q, m] += gq * tones[q].amp * complex(cr, ci)
