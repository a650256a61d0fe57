"""Drive-train lines rendered from the links' transfer functions, without running their modes.

The exact rendering (:mod:`.drive_tones`) feeds each driven body's force through the body's
modes sample by sample: a mode of pole ``p`` driven by a force ``F`` with gain ``g`` (one
microphone's :func:`.streams.stream_gains`) is heard as ``y[s] = Im sum_{k <= s} g F[k]
p^(s - k)`` (:func:`.bank_loops.bank_forced`). A tonal component ``F[k] = sin(phi_k)``,
``phi_{k+1} - phi_k = theta``, has the steady-state response

    y[s] = Im(W e^{j phi_s}),   W = (H(theta) - conj(H(-theta))) / 2j,
    H(theta) = sum_i g_i / (1 - p_i e^{-j theta})

(the response to ``e^{j phi}`` is ``H(theta) e^{j phi}``; that to ``e^{-j phi}``,
``H(-theta) e^{-j phi}``). So a line costs one complex weight per microphone, summed over the
modes of the bodies it acts on once per block, and then per sample one phasor step and two
multiply-adds per microphone: the cost is the number of lines, not lines times modes.

Per actuator ``j``, block ``[n0, n0 + L)``, component ``c`` (order ``o_c``, amplitude
``A_c``), microphone ``m``:

- ``theta`` follows the rotor speed, linear over the block (a chirp, as :mod:`.drive_tones`),
  and the phase is set exactly at the block's start and stored exactly at its end;
- ``W_{c,m}`` is summed over the (up to two) driven bodies the actuator pushes, each with
  its stream's gains and sign (the body's force is the sum of its drives along the strongest
  one's direction: :func:`.drive_tones.streams_write`), at ``theta`` of the block's end; over
  the block the line is ``Im(V_k e^{j phi_k})`` with ``V`` linear from the last block's
  ``a A W`` to this one's (``a``: the force scale);
- the broadband part ``a b y`` (``y`` the unit noise low-passed at the first component's
  frequency ``f_c``) is heard through the bodies' static response ``Im H(0)``, the part of
  the modes' response below their resonances (the noise's power at a mode ``f_i`` is
  ``(f_c / f_i)^2`` of its power below ``f_c``); it is generated every ``R = fs / (16 f_c)``
  samples and interpolated linearly;
- a microphone hears every body of the scene with one delay ``D_m`` (the least of the
  driven bodies' delays); a body's delay beyond it, ``dD``, is the phase
  ``e^{-j theta dD}`` of its lines (exact for a steady speed);
- the motor housing's direct airborne part (:mod:`.drive_housing`: a monopole at the
  joint's anchor) is one more term in ``W`` and the broadband gain at the air microphones;
- the output (pressure at an air or image microphone, acceleration at a contact one) is
  added into the pulse track's ring (:class:`.bandlimited.PulseTrack`), which every rendered
  block takes in.

**What it leaves out** (the exact rendering has them): a mode's transient when a component's
frequency or level changes faster than the mode settles (``d_i`` [1/s]; a line sweeping
through a resonance of bandwidth ``d_i`` within ``1 / d_i``), the ring-out after a drive
stops, the broadband noise's resonant part, a delay spread over the driven bodies beyond a
phase, and the radiation pattern (each mode is heard with its RMS over directions).
``tests/test_drive_lines.py`` bounds the difference against the exact rendering.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit
from .bandlimited import ring_add
from .bank_loops import FAST
from .drive_lanes import LaneScratch, cpow, lane_scratch, lanes_for, lines_pass, turn
from .drive_broadband import broadband_force, broadband_modes, broadband_resonant, broadband_route
from .drive_directions import DriveDirections, drive_directions
from .drive_gains import bodies_gains
from .drive_housing import housing_weights
from .drive_tones import advance_phase, audible_span, noise_cutoff_hz, wrap_phase
from .drive_weights import line_weights
from .packing import unpack
from .streams import SQRT3, noise_draw

__all__ = ["Actuators", "LinesScratch", "lines_scratch", "LineWeights", "BodyGains", "SceneView", "scene_view", "DriveRead", "drive_read",
           "line_weights", "lines_render", "lines_render_in", "scratch_fits", "lines_drive", "lines_drive_packed", "DONE",
           "GROW_TRACK", "GROW_LINES"]


class Actuators(NamedTuple):
    """The sounding actuators as the kernels read them (owner: :class:`mjsound.sim.actuators.
    ActuatorSound`, made once; its arrays are updated in place)."""

    comp_off: np.ndarray  # (J + 1,) int64: actuator j's components comp_off[j]:comp_off[j + 1]
    tones: np.ndarray  # (C,) drive_tones.TONE
    noise: np.ndarray  # (J,) drive_tones.NOISE
    drives: np.ndarray  # (J,) drive_tones.DRIVE
    ptr: np.ndarray  # (B + 1,) int64: the actuator sides on driven body b, rows[ptr[b]:ptr[b + 1]]
    rows: np.ndarray  # (R,) int64: 2 j + side (0: the joint's body, 1: its parent)
    sidx: np.ndarray  # (B,) int64: each driven body's stream (-1: none)
    sign: np.ndarray  # (B,) float64: the strongest drive's side sign on the body (0: none acts)
    acting: np.ndarray  # (J,) bool: the actuator drives in this block
    w0: np.ndarray  # (J,) rotor speed [rad/s] at the block's start
    w1: np.ndarray  # (J,) ... at its end (now)
    a0: np.ndarray  # (J,) force scale [N] at the block's start
    a1: np.ndarray  # (J,) ... at its end
    housing: np.ndarray  # (J,) float64: the housing's airborne coefficient [Pa m / N] (.drive_housing; 0: none)


class LinesScratch(NamedTuple):
    """:func:`lines_render`'s working arrays for ``C`` lines, ``M`` microphones and blocks of
    up to ``L`` samples (:func:`lines_scratch`; owner: ``ActuatorSound``, in its
    :class:`LineWeights`): a block allocates none where they are large enough, else makes
    what it needs for itself."""

    S: np.ndarray  # (6, C) float64: each gathered line's phasor, rate, the rate's turn
    V: np.ndarray  # (4 M + 4, C) float64: its weight and step per sample at each microphone
    span: np.ndarray  # (2, C) int64: its audible samples
    line_of: np.ndarray  # (C,) int64: its component
    ph_of: np.ndarray  # (C,) float64: its phase at the block's start
    y: np.ndarray  # (M, L + 1) float64: the decimated broadband
    buf: np.ndarray  # (L,) float64: one channel's broadband samples
    kj: np.ndarray  # (J,) int64: the actuators whose broadband is generated here
    ky: np.ndarray  # (J, L) float64: ... their low-passed noises at the decimated points
    tq: np.ndarray  # (L,) float64: the decimated points' times (fractions of the block)
    lanes: LaneScratch  # (.drive_lanes.lines_pass's)


def lines_scratch(C: int, M: int, L: int, J: int = 0) -> LinesScratch:
    """:class:`LinesScratch` for ``C`` lines, ``M`` microphones, blocks of up to ``L`` samples,
    ``J`` actuators."""
    z = np.zeros
    return LinesScratch(z((6, C)), z((4 * M + 4, C)), z((2, C), np.int64), z(C, np.int64), z(C), z((M, L + 1)),
                        z(L), z(J, np.int64), z((J, L)), z(L), lane_scratch(C))


#: No scratch: :func:`lines_render` makes its working arrays each block.
NO_SCRATCH = lines_scratch(0, 0, 0)


@njit(cache=True, inline="always")
def scratch_fits(sc, C, M, L, J):
    """Whether the working arrays ``sc`` (:class:`LinesScratch`) hold a block of ``L`` samples
    of ``C`` lines, ``M`` microphones and ``J`` actuators (those :func:`lines_scratch` makes)."""
    nv = lanes_for(C)
    lanes = sc.lanes
    return (sc.S.shape[1] >= C and sc.V.shape[0] >= 4 * M + 4 and sc.V.shape[1] >= C and sc.span.shape[1] >= C
            and sc.line_of.shape[0] >= C and sc.ph_of.shape[0] >= C and sc.y.shape[0] >= M
            and sc.y.shape[1] >= L + 1 and sc.buf.shape[0] >= L and sc.kj.shape[0] >= J and sc.ky.shape[0] >= J
            and sc.ky.shape[1] >= L and sc.tq.shape[0] >= L and lanes.T.shape[1] >= C and lanes.G.shape[1] >= C
            and lanes.S32.shape[1] >= nv and lanes.V32.shape[1] >= nv and lanes.lane.shape[0] >= C)


@njit(cache=True)
def _scratch_made(C, M, L, J):
    """:func:`lines_scratch` in a kernel."""
    nv = lanes_for(C)
    lanes = LaneScratch(np.zeros((6, C)), np.zeros((4, C)), np.zeros((6, nv), np.float32),
                        np.zeros((8, nv), np.float32), np.full(C, -1, np.int64))
    return LinesScratch(np.zeros((6, C)), np.zeros((4 * M + 4, C)), np.zeros((2, C), np.int64), np.zeros(C, np.int64),
                        np.zeros(C), np.zeros((M, L + 1)), np.zeros(L), np.zeros(J, np.int64), np.zeros((J, L)),
                        np.zeros(L), lanes)
#: ``LineWeights.held`` of no hold (the route follows each block's share alone).
NO_HOLD = np.zeros(0, np.int64)
#: ``LineWeights.response`` of no image microphone (:mod:`.drive_housing`).
NO_RESPONSE = np.zeros((0, 2, 0))


class LineWeights(NamedTuple):
    """Each block's weights (owner: ``ActuatorSound``; :func:`.drive_weights.line_weights` writes the ends,
    :func:`lines_render` moves them to the starts)."""

    W0: np.ndarray  # (C, M) complex128: each component's weight at each microphone, block start
    W1: np.ndarray  # (C, M) ... block end
    B0: np.ndarray  # (J, M) float64: each actuator's static broadband gain, block start
    B1: np.ndarray  # (J, M) ... block end
    Dm: np.ndarray  # (M,) int64: each microphone's delay [samples]
    exact: np.ndarray  # (J,) bool: the broadband part goes through the modes (.drive_broadband)
    power: np.ndarray  # (J, 2) float64: its resonant power and everything heard, per unit force scale
    scratch: LinesScratch = NO_SCRATCH  # (lines_render's working arrays: lines_scratch)
    held: np.ndarray = NO_HOLD  # (J,) int64: samples the resonant share has been low while on (.drive_broadband.broadband_route; length 0: no hold)
    response: np.ndarray = NO_RESPONSE  # (M, 2, k) float64: each image microphone's reflection, log frequencies [ln Hz] and gains (.drive_housing)


class BodyGains(NamedTuple):
    """The driven bodies' gains (:func:`.drive_gains.bodies_gains`) and what is made of them
    (owner: ``ActuatorSound``, shaped as the stream table's gains)."""

    gr: np.ndarray  # (B, M, nmax) float64: per-mode gains, real part (.drive_gains)
    gi: np.ndarray  # (B, M, nmax) ..., imaginary part
    gin: np.ndarray  # (B, nmax) float64: ... as an input gain per mode (phi . n / (fs wd))
    gout: np.ndarray  # (B, M, nmax) complex128: ... times an output factor per microphone
    D: np.ndarray  # (B, M) int64: delay to each microphone [samples] (0: a contact microphone)
    dts: np.ndarray  # (B, M) float64: the sub-sample delay [s] of the last gains made (NaN: none yet)
    dfac: np.ndarray  # (B, M, nmax) complex128: their delay factors e^{lam dts}, each body's row packed (mic m's modes at m n)
    loc: np.ndarray  # (R, 3) float64: each drive side's anchor in its body's frame at the last search [m] (NaN: none)
    near: np.ndarray  # (R,) int64: ... and its nearest surface sample
    static: np.ndarray  # (B, M, nmax) float64: each mode's static response Im g / (1 - p)
    resonant: np.ndarray  # (B, nmax) float64: each mode's resonant broadband power
    keep: np.ndarray  # (B, nmax) bool: the modes carrying a broadband part
    z: np.ndarray  # (B, nmax) complex128: their states (.drive_broadband.broadband_resonant)
    level: np.ndarray  # (B, nmax) float64: 1 where a mode was forced in the last block (it fades out next), else 0
    U: np.ndarray  # (B, M, 3) float64: the direction the factors Fd were made for (NaN: none)
    Fd: np.ndarray  # (B, M, nmax) complex128: the direction factors


class SceneView(NamedTuple):
    """What :func:`.drive_weights.line_weights` reads of the synthesizer (owner: ``ActuatorSound``, made
    again when one of the synthesizer's arrays is replaced): the streams' records, the
    objects' poles, poses, the microphones, the channels and the direction fits (the
    fields of :class:`.records.DirectionState` of those names)."""

    table: np.ndarray  # (S,) STREAM
    poles: np.ndarray  # (modes,) complex128: each mode's pole per sample e^{lam / fs}
    mode_off: np.ndarray  # (objects + 1,) int64
    mics: np.ndarray  # (M, 3) [m]
    pos: np.ndarray  # (objects, 3) [m]
    R: np.ndarray  # (objects, 3, 3)
    channels: np.ndarray  # (M,) CHANNEL
    order: np.ndarray  # (objects,) int64
    msh_off: np.ndarray  # (modes + 1,) int64
    coef_r: np.ndarray  # (k,) float64
    coef_i: np.ndarray  # (k,) float64
    sh: np.ndarray  # (rows, harmonics) scratch (its first row is used)
    sh_tab: np.ndarray
    params: np.ndarray  # (1,) DIRECTIONS
    dd: DriveDirections = None  # the fits' float32 copy for the weights (.drive_directions)


def scene_view(synth, dr) -> SceneView:
    """:class:`SceneView` of a :class:`.records.SynthState` and :class:`.records.DirectionState`
    (the poles and the fits' float32 copy made here, once)."""
    st, ob = synth.streams, synth.objects
    poles = np.exp(ob.lam / float(synth.consts[0]["fs"]))
    return SceneView(st.table, poles, ob.mode_off, synth.mics, synth.pos, synth.R, synth.channels, dr.order,
                     dr.msh_off, dr.coef_r, dr.coef_i, dr.sh, dr.sh_tab, dr.params, drive_directions(dr, ob.mode_off))


class DriveRead(NamedTuple):
    """What :func:`drive_read` reads of the model (owner: ``ActuatorSound``, made once)."""

    dof: np.ndarray  # (J,) int64: each actuator's joint's dof
    ids: np.ndarray  # (J,) int64: the actuators
    ratio: np.ndarray  # (J,) float64: rotor radians per joint unit
    gear: np.ndarray  # (J,) float64: MJCF gear
    inv_radius: np.ndarray  # (J,) float64: 1 / the preset's radius (1: a slide)
    gate: np.ndarray  # (1,) float64: joint speed at full level



@njit(cache=True, _nrt=False)  # (no reference counts: drive_gains' docstring)
def drive_read(rd, act, qvel, force, fresh):
    """A new block's ends: the last end becomes the start (``act.w0, a0``; ``fresh``: the
    start is now too) and ``act.w1, a1`` each actuator's rotor speed ``w = ratio qdot``
    [rad/s] and force scale ``a = |gear force| inv_radius min(1, |qdot| / gate)`` [N] now (a
    non-finite value reads 0). Returns whether some force scale is not 0."""
    live = False
    w, a = act.w1, act.a1
    for j in range(w.shape[0]):
        act.w0[j] = w[j]
        act.a0[j] = a[j]
        qd = qvel[rd.dof[j]]
        w[j] = qd * rd.ratio[j]
        a[j] = abs(force[rd.ids[j]] * rd.gear[j]) * rd.inv_radius[j] * min(1.0, abs(qd) / rd.gate[0])
        if not (math.isfinite(w[j]) and math.isfinite(a[j])):
            w[j] = 0.0 if not math.isfinite(w[j]) else w[j]
            a[j] = 0.0
        if fresh:
            act.w0[j] = w[j]
            act.a0[j] = a[j]
        live = live or a[j] != 0.0 or act.a0[j] != 0.0
    return live


@njit(cache=True, fastmath=FAST, _nrt=False)
def _ramp_fill(out, y0, dy):
    """``out[q] = y0 + dy q`` (by adding ``dy`` a sample, as :func:`_ramp_add`)."""
    y = y0
    for q in range(out.shape[0]):
        out[q] = y
        y += dy


@njit(cache=True, fastmath=FAST, _nrt=False)
def _ramp_add(out, x, g0, dg):
    """``out[q] += (g0 + dg q) x[q]``, the gain ramped by adding ``dg`` a sample (vectorised:
    no integer-to-float conversion a sample)."""
    g = g0
    for q in range(out.shape[0]):
        out[q] += g * x[q]
        g += dg


@njit(cache=True)
def lines_render(track, act, lw, n0, L, fs, F):
    """:func:`lines_render_in` with ``lw.scratch`` where it holds the block
    (:func:`scratch_fits`), else with working arrays made for the call. Returns the number of
    lines rendered."""
    C, M = lw.W1.shape
    M = min(M, track.acc.shape[0])
    J = act.a0.shape[0]
    if scratch_fits(lw.scratch, C, M, L, J):
        return lines_render_in(track, act, lw, lw.scratch, n0, L, fs, F)
    return lines_render_in(track, act, lw, _scratch_made(C, M, L, J), n0, L, fs, F)


@njit(cache=True, _nrt=False)  # (no reference counts: .drive_gains' docstring; it allocates nothing)
def lines_render_in(track, act, lw, sc, n0, L, fs, F):
    """Add the block's lines and broadband part (module docstring) into the pulse track
    (:class:`.records.TrackState`: its ring ``acc``, channels x capacity a power of two,
    absolute sample ``k`` at ``k & (capacity - 1)``; its ``rec``'s pending span grows),
    microphone ``m``'s source sample ``n0 + q`` at ``n0 + q + Dm[m]`` (ring samples before
    ``rec.start``, handed out already, are not written), for ``0 <= q < L``; the components'
    phases and the noise's state advance over the block (as :func:`.drive_tones.drive_tones`),
    and the block's end weights become the next one's start. The lines' samples:
    :func:`.drive_lanes.lines_pass`, two channels a pass. The working arrays: ``sc``
    (:class:`LinesScratch`, large enough for the block: :func:`scratch_fits`).

    Parameters
    ----------
    track : :class:`.records.TrackState`
    act : :class:`Actuators` (speeds and force scales at the block's start and end)
    lw : :class:`LineWeights` (the actuators ``exact``: their broadband force is ``F[j]`` (J,
        L), :func:`.drive_broadband.broadband_force`, heard here through their bodies' modes
        left out of the resonant route, ``lw.B``; the rest goes through the modes,
        :func:`.drive_broadband.broadband_resonant`)
    Returns the number of lines rendered.
    """
    acc, rec = track.acc, track.rec
    comp_off, tones, noise, w0, w1, a0, a1 = act.comp_off, act.tones, act.noise, act.w0, act.w1, act.a0, act.a1
    W0, W1, B0, B1, Dm, exact = lw.W0, lw.W1, lw.B0, lw.B1, lw.Dm, lw.exact
    C, M = W1.shape
    M = min(M, acc.shape[0])  # (the track's channels: the same as the weights' where they are current)
    J = a0.shape[0]
    limit = 2.0 * math.pi * 0.45
    two_pi = 2.0 * math.pi
    first = rec[0].start
    lo = n0 + L
    hi = n0
    for m in range(M):
        lo = min(lo, n0 + Dm[m])
        hi = max(hi, n0 + L + Dm[m])
    lo = max(lo, first)
    if hi > lo:
        r = rec[0]
        r.pending_from = lo if r.pending_until <= first else min(r.pending_from, lo)
        r.pending_until = max(r.pending_until, hi)
    # the lines gathered, each over its audible samples
    S, V, span, line_of, ph_of = sc.S, sc.V, sc.span, sc.line_of, sc.ph_of  # (line_of: each line's component; ph_of: its phase at the block's start)
    nl = 0
    for j in range(J):
        silent = a0[j] == 0.0 and a1[j] == 0.0
        dw = (w1[j] - w0[j]) / L
        for c in range(comp_off[j], comp_off[j + 1]):
            s0 = tones[c].order * w0[j] / fs
            ds = tones[c].order * dw / fs
            ph = tones[c].phase
            tones[c].phase = advance_phase(ph, s0, ds, L)
            if silent:
                continue
            lo, hi = audible_span(s0, ds, limit, L)
            if hi <= lo:
                continue
            heard = False
            for m in range(M):
                v0 = a0[j] * W0[c, m]
                d = (a1[j] * W1[c, m] - v0) / L
                V[4 * m, nl] = v0.real
                V[4 * m + 1, nl] = v0.imag
                V[4 * m + 2, nl] = d.real
                V[4 * m + 3, nl] = d.imag
                heard = heard or v0 != 0.0 or d != 0.0
            if not heard:  # (its weights are 0 at every microphone)
                continue
            # phasor, rate and the rate's turn at the block's first sample; for a harmonic
            # (order h o_b, h 2 or 3) of a line b of the actuator before it, b's to the power
            # h (s0 = h s0_b, ds = h ds_b), the phasor turned by e^{j (ph - h ph_b)} (the
            # phases grow as h: 0 but for their rounding): one sine and cosine fewer than three
            ib = nl - 1
            h = 0
            while ib >= 0 and line_of[ib] >= comp_off[j] and h == 0:
                ob = tones[line_of[ib]].order
                h = 2 if ob * 2.0 == tones[c].order else (3 if ob * 3.0 == tones[c].order else 0)
                ib -= 1
            if h:
                ib += 1
                cr, ci = cpow(S[0, ib], S[1, ib], h)
                tr, ti = cpow(S[2, ib], S[3, ib], h)
                fr, fi = cpow(S[4, ib], S[5, ib], h)
                er, ei = turn(wrap_phase(ph - h * ph_of[ib] + math.pi) - math.pi)
                cr, ci = cr * er - ci * ei, cr * ei + ci * er
            else:
                cr, ci = math.cos(ph), math.sin(ph)
                tr, ti = math.cos(s0), math.sin(s0)
                fr, fi = turn(ds)
            S[0, nl], S[1, nl], S[2, nl], S[3, nl], S[4, nl], S[5, nl] = cr, ci, tr, ti, fr, fi
            line_of[nl] = c
            ph_of[nl] = ph
            span[0, nl] = lo  # (a line crossing the cut-off sounds on its audible samples alone)
            span[1, nl] = hi
            nl += 1
    if nl:
        for m in range(0, M, 2):  # (two channels per pass over the phasors)
            two = m + 1 < M
            lines_pass(acc, first, (m, n0 + Dm[m]), (m + 1 if two else m, n0 + Dm[m + 1 if two else m]), two, L,
                       S, V[4 * m:4 * m + 8], span, nl, sc.lanes)
    # broadband: the static response of the low-passed noises, generated every R samples,
    # summed per channel there and interpolated linearly in between
    R = 64
    for j in range(J):
        if noise[j].broadband > 0.0 and (a0[j] != 0.0 or a1[j] != 0.0) and not exact[j]:
            c0 = comp_off[j]
            fc = abs(0.5 * (w0[j] + w1[j])) * (tones[c0].order if comp_off[j + 1] > c0 else 1.0) / two_pi
            R = min(R, max(1, int(fs / (16.0 * fc)) if fc > 0.0 else 64))
    nb = (L + R - 1) // R  # decimated points at samples R - 1, 2R - 1, ... (the last at L - 1)
    y = sc.y
    for m in range(M):  # (column 0: the last block's end, from the noise state)
        for i in range(nb + 1):
            y[m, i] = 0.0
    # (each actuator's noise at the decimated points first, then summed per channel along a
    # row of y with the gains' ends held in registers: the sum's order over the actuators kept)
    kj, ky, tq = sc.kj, sc.ky, sc.tq
    for i in range(nb):
        tq[i] = (min(L - 1, (i + 1) * R - 1) + 1) / L
    nk = 0
    for j in range(J):
        b = noise[j].broadband
        if b <= 0.0 or (a0[j] == 0.0 and a1[j] == 0.0) or exact[j]:
            continue
        fc = noise_cutoff_hz(tones, comp_off, j, 0.5 * (w0[j] + w1[j]), fs)
        alpha = 1.0 - math.exp(-two_pi * fc * R / fs)
        scale = SQRT3 / math.sqrt(R)  # (white noise at fs / R: the same density below f_c)
        state = np.uint64(noise[j].rng)
        yl = noise[j].lp
        for m in range(M):
            y[m, 0] += a0[j] * b * B0[j, m] * yl
        row = ky[nk]
        for i in range(nb):
            state, x = noise_draw(state)
            yl = alpha * (x * scale) + (1.0 - alpha) * yl
            row[i] = yl
        noise[j].rng = np.int64(state)
        noise[j].lp = yl
        kj[nk] = j
        nk += 1
    any_bb = nk > 0
    for k in range(nk):
        j = kj[k]
        b = noise[j].broadband
        ga, gd = a0[j], a1[j] - a0[j]
        row = ky[k]
        for m in range(M):
            g0, g1 = B0[j, m], B1[j, m] - B0[j, m]
            ym = y[m, 1:]
            for i in range(nb):
                t = tq[i]
                ym[i] += (ga + gd * t) * b * (g0 + g1 * t) * row[i]
    some_exact = False
    for j in range(J):
        some_exact = some_exact or (exact[j] and (a0[j] != 0.0 or a1[j] != 0.0))
    if any_bb or some_exact:
        buf = sc.buf[:L]
        for m in range(M):
            if any_bb:  # (the decimated broadband, interpolated linearly)
                for i in range(nb):
                    k0 = i * R
                    k1 = min(L, (i + 1) * R)
                    ya = y[m, i]
                    dy = (y[m, i + 1] - ya) / (k1 - k0)
                    _ramp_fill(buf[k0:k1], ya + dy, dy)
            else:
                buf[:] = 0.0
            for j in range(J):  # the exact actuators' static part, from their own force
                if not exact[j] or (a0[j] == 0.0 and a1[j] == 0.0):
                    continue
                _ramp_add(buf, F[j], B0[j, m], (B1[j, m] - B0[j, m]) / L)
            ring_add(acc, m, n0 + Dm[m], first, buf)
    for c in range(C):  # (this block's end starts the next)
        for m in range(M):
            W0[c, m] = W1[c, m]
    for j in range(J):
        for m in range(M):
            B0[j, m] = B1[j, m]
    return nl


#: :func:`lines_drive`'s outcome (``io[0]``): done, or the pulse track's ring must first grow
#: to hold sample ``io[1] - 1`` (then call again with ``resume``: the block's read is kept), or
#: the lines' working arrays (``LineWeights.scratch``) must first be made for blocks of
#: ``io[1]`` samples (:func:`lines_scratch`; nothing was read: call again as before).
DONE, GROW_TRACK, GROW_LINES = 0, 1, 2


@njit(cache=True)
def lines_drive(state, k0, L, fs, fresh, resume, regain, F):
    """One block of the drives in one call (``state = (rd, act, lw, bg, view, ks, track, dv,
    io)``: :class:`DriveRead`, :class:`Actuators`, :class:`LineWeights`, :class:`BodyGains`,
    :class:`SceneView`, :class:`.records.SynthState`, :class:`.records.TrackState`, and):
    :func:`drive_read` of ``dv`` (unless ``resume``:
    the block's read is kept), the driven bodies' gains (:func:`.drive_gains.bodies_gains`),
    :func:`.drive_weights.line_weights`, the broadband's route
    (:func:`.drive_broadband.broadband_route`) and the housing's airborne part
    (:func:`.drive_housing.housing_weights`), the broadband's modes where some actuator's goes through them
    (:func:`.drive_broadband.broadband_modes`, :func:`.drive_broadband.broadband_force` into
    ``F`` (J, L)), the weights' start (``fresh``: the same as the end), :func:`lines_render`
    and :func:`.drive_broadband.broadband_resonant` into ``track``.

    Parameters
    ----------
    dv : (qvel, actuator_force, xanchor, xaxis), MuJoCo's ``data`` arrays
    io : (5,) int64 (written): outcome (:data:`DONE`, :data:`GROW_TRACK`, :data:`GROW_LINES`),
        the length to grow to, lines rendered, modes kept, whether some joint moves (kept for ``resume``)
    k0 : int, the block's first synth sample; L : int, its samples; fs : float [Hz]
    regain : int, samples between the driven bodies' gains (:func:`.drive_gains.bodies_gains`)
    """
    rd, act, lw, bg, view, ks, track, dv, io = state
    qvel, force, anchor, axis = dv
    io[0] = DONE
    io[2] = 0
    io[3] = 0
    if not scratch_fits(lw.scratch, lw.W1.shape[0], min(lw.W1.shape[1], track.acc.shape[0]), L, act.a0.shape[0]):
        io[0] = GROW_LINES
        io[1] = L
        return
    if not resume:
        io[4] = 1 if drive_read(rd, act, qvel, force, fresh) else 0
        if io[4] == 1:
            for j in range(act.a1.shape[0]):
                act.acting[j] = act.a0[j] != 0.0 or act.a1[j] != 0.0
            bodies_gains(ks, act, bg, anchor, axis, k0, regain)
    if io[4] == 0:  # (every joint still: no lines, the phases wait; the resonant modes ring out)
        ringing = False
        for b in range(bg.level.shape[0]):
            for k in range(bg.level.shape[1]):
                ringing = ringing or bg.level[b, k] > 0.0
        if not ringing:
            return
        for b in range(bg.keep.shape[0]):
            act.sign[b] = 0.0
            for k in range(bg.keep.shape[1]):
                bg.keep[b, k] = False
        dmax = 0
        for b in range(bg.D.shape[0]):
            for m in range(bg.D.shape[1]):
                dmax = max(dmax, bg.D[b, m])
        if k0 + L + dmax - track.rec[0].start > track.acc.shape[1]:
            io[0] = GROW_TRACK
            io[1] = k0 + L + dmax + 1
            return
        broadband_resonant(view, act, lw, bg, track, k0, F, False)
        return
    dmax = line_weights(view, act, lw, bg, fs)
    broadband_route(lw, L, fs)
    housing_weights(ks, act, lw, anchor, fs)  # (after the broadband's route is chosen: it leaves that alone)
    for b in range(bg.D.shape[0]):  # (the resonant modes are heard at their own body's delays)
        if act.sidx[b] >= 0:
            for m in range(bg.D.shape[1]):
                dmax = max(dmax, bg.D[b, m])
    last = k0 + L + dmax
    if last - track.rec[0].start > track.acc.shape[1]:
        io[0] = GROW_TRACK
        io[1] = last + 1
        return
    some = False
    for j in range(lw.exact.shape[0]):
        some = some or lw.exact[j]
    if some:
        io[3] = broadband_modes(act, lw, bg)
        broadband_force(act, lw, fs, F)
    else:
        bg.keep[:, :] = False
    if fresh:
        lw.W0[:, :] = lw.W1
        lw.B0[:, :] = lw.B1
    io[2] = lines_render_in(track, act, lw, lw.scratch, k0, L, fs, F)
    broadband_resonant(view, act, lw, bg, track, k0, F, fresh)


@njit(cache=True)
def lines_drive_packed(table, layout, k0, L, fs, fresh, resume, regain, F):
    """:func:`lines_drive` with its state ``(rd, act, lw, bg, view, ks, track, dv, io)``
    packed (:func:`.packing.unpack`; called through :class:`.dispatch.PackedEntry`: one
    table crosses into numba instead of every array)."""
    lines_drive(unpack(table, layout), k0, L, fs, fresh, resume, regain, F)
