"""Numba kernels of the resonator bank.

One *voice* is one (object, microphone) pair: ``n`` damped complex oscillators

    z_i[s + 1] = p_i z_i[s],     p_i = e^{(-d_i + j w_i) / fs},   |p_i| < 1

whose imaginary parts summed over i are the voice's pressure at the microphone, sample s::

    out[s] += sum_i Im z_i[s]

Events (impulses) add a complex amplitude to z before sample s is output; forcing sources
(sliding, rolling, user signals) add ``g_i f[s]`` per sample. The state lives in full-size
float64 arrays between calls; inside a call the *active* modes are gathered into compact
work arrays of the bank's dtype (float32 or float64) so that decayed modes cost nothing and
the inner loop over modes vectorises (``fastmath``).

Everything that changes the set of active modes or rescales the state happens at *absolute*
sample indices (events, source boundaries, and a fixed grid of ``grid`` samples), never at
block boundaries, so any split of the same audio into blocks is bit-identical. At each grid
point the state is multiplied by ``corr_i = (p_exact / p_dtype)^grid`` (computed in float64),
which cancels the systematic error of the rounded pole (in float32 about 1e-7 per sample in
both decay and phase) so that hours of ringing keep the exact decay and pitch; then modes
whose ``|z|^2`` fell below ``peak^2 * cull2`` (or the absolute floor ``floor2``) are zeroed
and dropped from the work arrays until an event re-excites them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..jit import njit, njit_inner
from .bank_loops import bank_forced, bank_free
from .directivity import ModeGains, commit_ramp, gain_at, hear_directions, ramp_poles, scale_sources
from .contact_coupling import coupled_response
from .pulse import half_sine
from .queue import take_due
from .records import AIR, EventRows, SourceRows
from .streams import any_due, mic_distance, nearest_sorted, streams_bank_rows, streams_gains

__all__ = ["bank_free", "bank_forced", "render_voice", "render_all", "render_streams", "impacts_to_queue",
           "commit_queued", "one_pole", "place_rows", "Voice"]


class Voice(NamedTuple):
    """One bank's (or voice's) modes: views into the flat state of :class:`.records.Bank`."""

    zr: np.ndarray
    zi: np.ndarray
    peak2: np.ndarray
    active: np.ndarray
    pr: np.ndarray
    pi: np.ndarray
    corr_r: np.ndarray
    corr_i: np.ndarray


@njit_inner(cache=True)
def _gather(voice, gr, gi, cols, work, gains, idx, kof, span):
    """The active modes of ``voice`` (state, poles) and their source gains into the compact
    work arrays, and each source's span of gathered modes with a non-zero gain (as
    :func:`source_spans` finds it); returns how many modes.

    cols : (2, n_src) int64   the bank modes ``cols[0, q] <= i < cols[1, q]`` outside which
                              source q's gains ``gr, gi`` are zero (only those are visited)
    gains : (gwr, gwi)        (n_src, m) gathered gains, zero outside each source's modes
    kof : (m,) int64          work: the gathered index of each active mode
    """
    zr, zi, active, pr, pi = voice.zr, voice.zi, voice.active, voice.pr, voice.pi
    wr, wi, wpr, wpi = work
    gwr, gwi = gains
    k = np.int64(0)  # (not a literal 0: the callee it reaches would compile twice)
    for i in range(zr.shape[0]):
        if active[i]:
            idx[k] = i
            kof[i] = k
            wr[k] = zr[i]
            wi[k] = zi[i]
            wpr[k] = pr[i]
            wpi[k] = pi[i]
            k += 1
    for q in range(gwr.shape[0]):  # (an earlier gather's gains, wherever they were)
        for j in range(gwr.shape[1]):
            gwr[q, j] = 0.0
            gwi[q, j] = 0.0
    for q in range(gr.shape[0]):
        lo, hi = k, 0
        for i in range(cols[0, q], cols[1, q]):
            if active[i]:
                j = kof[i]
                a = gr[q, i]
                b = gi[q, i]
                gwr[q, j] = a
                gwi[q, j] = b
                if a != 0.0 or b != 0.0:
                    if j < lo:
                        lo = j
                    hi = j + 1
        span[0, q] = lo if lo < hi else 0
        span[1, q] = hi
    return k


@njit_inner(cache=True)
def source_spans(gwr, gwi, na, span):
    """``span[0, q] .. span[1, q]``: the first and one past the last of the ``na`` gathered
    modes where source q's gain is non-zero (an empty span when it has none)."""
    for q in range(gwr.shape[0]):
        lo, hi = na, 0
        for k in range(na):
            if gwr[q, k] != 0.0 or gwi[q, k] != 0.0:
                if k < lo:
                    lo = k
                hi = k + 1
        span[0, q] = lo if lo < hi else 0
        span[1, q] = hi


@njit_inner(cache=True)
def _scatter(zr, zi, wr, wi, idx, na):
    for k in range(na):
        zr[idx[k]] = wr[k]
        zi[idx[k]] = wi[k]


@njit_inner(cache=True)
def render_voice(voice, ev, src, start, n, consts, out, zero, gains):
    """Render samples ``[start, start + n)`` of one bank of modes into ``out[:n]`` (added).

    Parameters
    ----------
    voice : Voice
        Its modes' state ``zr, zi`` (m,) float64 at sample ``start`` (updated to ``start +
        n``), ``peak2`` (largest ``|z|^2`` since the mode was last (re)started), ``active``
        (events activate, culling deactivates), rounded poles ``pr, pi`` (dtype) and the grid
        correction ``corr_r, corr_i`` = ``(p_exact / p_dtype)^grid``.
    ev : EventRows
        Its events (``ptr`` unused): ``sample`` sorted, all in ``[start, start + n)``;
        ``kind`` 0 adds ``re + j im`` (already carrying the exact sub-sample phase) to the
        state, 1 only activates the modes where the row is non-zero (a forcing source starts).
    src : SourceRows
        Its forcing sources (``ptr`` unused): absolute ranges ``[a, b)``, complex per-mode
        gains ``gr, gi`` (q, m) dtype, force samples ``F`` (q, n) on this block.
    start, n : int
        First absolute sample, number of samples.
    consts : (1,) SYNTH_CONSTS
        ``grid`` (correction / culling grid [samples]), ``cull2`` and ``floor2`` (relative and
        absolute squared-amplitude culling thresholds).
    out : (n,) dtype
        Output, added to.
    zero : dtype scalar
    gains : :class:`.directivity.ModeGains`
        The direction factors the state carries: an event's amplitudes are added times
        ``D(s)`` at its sample, and while they ramp the gathered poles are multiplied by the
        per-sample factor (:mod:`.directivity`; the caller scaled the forcing rows). A bank
        without a directional mode (``on`` false) renders exactly as without them.
    """
    zr, zi, peak2, active, pr = voice.zr, voice.zi, voice.peak2, voice.active, voice.pr
    corr_r, corr_i = voice.corr_r, voice.corr_i
    ev_n, ev_kind, ev_re, ev_im = ev.sample, ev.kind, ev.re, ev.im
    src_a, src_b, gr, gi, F = src.a, src.b, src.gr, src.gi, src.F
    grid, cull2, floor2 = consts[0].grid, consts[0].cull2, consts[0].floor2
    m = zr.shape[0]
    nsrc = gr.shape[0]
    wr = np.empty(m, pr.dtype)
    wi = np.empty(m, pr.dtype)
    wpr = np.empty(m, pr.dtype)
    wpi = np.empty(m, pr.dtype)
    gwr = np.empty((nsrc, m), pr.dtype)
    gwi = np.empty((nsrc, m), pr.dtype)
    idx = np.empty(m, np.int64)
    kof = np.empty(m, np.int64)
    act = np.empty(max(nsrc, 1), np.int64)
    span = np.zeros((2, nsrc), np.int64)
    cols = np.zeros((2, nsrc), np.int64)
    work = (wr, wi, wpr, wpi)
    sgains = (gwr, gwi)
    for q in range(nsrc):
        # the bank modes of source q's first and last non-zero gain (a stream's row has gains
        # on its object's modes only)
        lo = 0
        while lo < m and gr[q, lo] == 0.0 and gi[q, lo] == 0.0:
            lo += 1
        hi = m
        while hi > lo and gr[q, hi - 1] == 0.0 and gi[q, hi - 1] == 0.0:
            hi -= 1
        cols[0, q] = lo
        cols[1, q] = hi
        # a source already acting at the block start drives its modes from here on (a no-op
        # for sources whose start event activated them earlier: they cannot be culled while
        # acting)
        if src_a[q] <= start and start < src_b[q]:
            for i in range(lo, hi):
                if (gr[q, i] != 0.0 or gi[q, i] != 0.0) and not active[i]:
                    active[i] = True
                    zr[i] = 0.0
                    zi[i] = 0.0
                    peak2[i] = 0.0
    na = _gather(voice, gr, gi, cols, work, sgains, idx, kof, span)
    if gains.ramp:
        ramp_poles(wpr, wpi, idx, na, gains)
    # forcing sources must not be culled while they act
    pos = start
    end = start + n
    e = 0
    ne = ev_n.shape[0]
    while pos < end:
        # ---- grid point: exact-pole correction, peak tracking, culling
        if pos % grid == 0:
            # a mode driven by a source acting now is never culled (one bank holds many
            # objects: only the driven object's modes are exempt)
            nact = 0
            for q in range(nsrc):
                if src_a[q] <= pos and pos < src_b[q]:
                    act[nact] = q
                    nact += 1
            w = np.int64(0)  # (not a literal 0: the callee it reaches would compile twice)
            for k in range(na):
                i = idx[k]
                a = np.float64(wr[k])
                b = np.float64(wi[k])
                nr = a * corr_r[i] - b * corr_i[i]
                ni = a * corr_i[i] + b * corr_r[i]
                m2 = nr * nr + ni * ni
                if m2 > peak2[i]:
                    peak2[i] = m2
                if m2 < peak2[i] * cull2 or m2 < floor2:
                    driven = False
                    for qq in range(nact):
                        if gwr[act[qq], k] != 0.0 or gwi[act[qq], k] != 0.0:
                            driven = True
                            break
                    if not driven:
                        active[i] = False
                        zr[i] = 0.0
                        zi[i] = 0.0
                        continue
                wr[w] = nr
                wi[w] = ni
                if w != k:  # (a mode before this one was culled: move it down)
                    wpr[w] = wpr[k]
                    wpi[w] = wpi[k]
                    idx[w] = i
                    for q in range(nsrc):
                        gwr[q, w] = gwr[q, k]
                        gwi[q, w] = gwi[q, k]
                w += 1
            if w != na:  # (the spans change only when a mode was culled)
                na = w
                source_spans(gwr, gwi, na, span)
        # ---- events at this sample
        if e < ne and ev_n[e] <= pos:
            _scatter(zr, zi, wr, wi, idx, na)
            while e < ne and ev_n[e] <= pos:
                if ev_kind[e] == 0:
                    for i in range(m):
                        a = ev_re[e, i]
                        b = ev_im[e, i]
                        if (a != 0.0 or b != 0.0) and gains.on and gains.dmode[i]:
                            c = complex(a, b) * gain_at(gains, i, ev_n[e] - start)
                            a = c.real
                            b = c.imag
                        if a != 0.0 or b != 0.0:
                            if not active[i]:
                                active[i] = True
                                zr[i] = 0.0
                                zi[i] = 0.0
                                peak2[i] = 0.0
                            zr[i] += a
                            zi[i] += b
                            m2 = zr[i] * zr[i] + zi[i] * zi[i]
                            if m2 > peak2[i]:
                                peak2[i] = m2
                else:
                    for i in range(m):
                        if ev_re[e, i] != 0.0 or ev_im[e, i] != 0.0:
                            if not active[i]:
                                active[i] = True
                                zr[i] = 0.0
                                zi[i] = 0.0
                                peak2[i] = 0.0
                e += 1
            na = _gather(voice, gr, gi, cols, work, sgains, idx, kof, span)
            if gains.ramp:
                ramp_poles(wpr, wpi, idx, na, gains)
        # ---- run to the next grid point / event / source boundary / block end
        stop = end
        g = (pos // grid + 1) * grid
        if g < stop:
            stop = g
        if e < ne and ev_n[e] < stop:
            stop = ev_n[e]
        nact = np.int64(0)  # (not a literal 0: the callee it reaches would compile twice)
        for q in range(nsrc):
            if src_a[q] > pos and src_a[q] < stop:
                stop = src_a[q]
            if src_b[q] > pos and src_b[q] < stop:
                stop = src_b[q]
        for q in range(nsrc):
            if src_a[q] <= pos and pos < src_b[q]:
                act[nact] = q
                nact += 1
        o0 = pos - start
        if nact == 0:
            bank_free(work, na, out, o0, stop - pos, zero)
        else:
            bank_forced(work, na, out, o0, stop - pos, zero, gwr, gwi, F, act, nact, span)
        pos = stop
    _scatter(zr, zi, wr, wi, idx, na)


@njit(cache=True)
def render_all(bank, consts, ev, src, start, n, out, zero):
    """Render samples ``[start, start + n)`` of every bank (one call for the whole scene).

    Bank ``b`` (:class:`.records.Bank`) owns modes ``[start[b], start[b] + length[b])`` of the
    flat state and adds into ``out[mic[b]]``. Its events are rows ``ev.ptr[b] .. ev.ptr[b +
    1]`` (sorted by sample), its sources rows ``src.ptr[b] .. src.ptr[b + 1]``; amplitudes and
    gains are padded to the widest bank (only the first ``length[b]`` columns are read).
    ``live[b]`` is kept equal to "has running modes" so silent banks cost one branch. The
    per-bank work is exactly :func:`render_voice`, so block splits stay bit-identical (but for
    directional objects turning: :mod:`.directivity`, whose factors for the block
    :func:`.directivity.hear_directions` made; the forcing rows of directional modes are scaled
    here by the factor at the block's middle, and each ramp is committed at its end).
    """
    nv = bank.start.shape[0]
    ACT = bank.active
    dr = bank.direction
    for v in range(nv):
        e0 = ev.ptr[v]
        e1 = ev.ptr[v + 1]
        s0 = src.ptr[v]
        s1 = src.ptr[v + 1]
        o = bank.start[v]
        m = bank.length[v]
        ramp = dr.ramp[v]
        if ramp:  # (committed now: render_voice reads the views below, not the flag)
            dr.ramp[v] = False
        if (not bank.live[v] and e0 == e1 and s0 == s1) or m == 0:
            if ramp:
                commit_ramp(dr, o, m)
            continue
        gains = ModeGains(dr.on[v], ramp, dr.dmode[o:o + m], dr.ar[o:o + m], dr.ai[o:o + m], dr.lr[o:o + m],
                          dr.li[o:o + m], dr.rho_r[o:o + m], dr.rho_i[o:o + m])
        if gains.on and s1 > s0:
            scale_sources(src.gr[s0:s1, :m], src.gi[s0:s1, :m], gains, 0.5 * n)
        voice = Voice(bank.zr[o:o + m], bank.zi[o:o + m], bank.peak2[o:o + m], ACT[o:o + m], bank.pr[o:o + m],
                      bank.pi[o:o + m], bank.corr_r[o:o + m], bank.corr_i[o:o + m])
        ev_v = EventRows(ev.ptr, ev.sample[e0:e1], ev.kind[e0:e1], ev.re[e0:e1, :m], ev.im[e0:e1, :m])
        src_v = SourceRows(src.ptr, src.a[s0:s1], src.b[s0:s1], src.gr[s0:s1, :m], src.gi[s0:s1, :m], src.F[s0:s1])
        render_voice(voice, ev_v, src_v, start, n, consts, out[bank.mic[v]], zero, gains)
        if ramp:
            commit_ramp(dr, o, m)
        live = False
        for i in range(o, o + m):
            if ACT[i]:
                live = True
                break
        bank.live[v] = live


@njit(cache=True)
def one_pole(x, a, y0):
    """``y[k] = a x[k] + (1 - a) y[k - 1]`` with ``y[-1] = y0`` (in place of scipy's lfilter)."""
    b = 1.0 - a
    y = np.empty(x.shape[0])
    prev = y0
    for k in range(x.shape[0]):
        prev = a * x[k] + b * prev
        y[k] = prev
    return y


@njit(cache=True)
def impacts_to_queue(synth, obj, P, J, t, tau, budget, mass):
    """Modal amplitudes of ``k`` impacts at every microphone, appended to the synthesizer's
    event queue (``synth.queue``, from its ``count`` and ``pool_used``; the caller reserved
    room; the counts are *not* advanced: :func:`commit_queued` does that once the amplitudes
    are known to be in range).

    Impact ``i`` strikes object ``obj[i]`` (``synth.objects``, posed by ``synth.pos`` /
    ``synth.R``) at world point ``P[i]`` with impulse ``J[i]`` [N s] at synth time ``t[i]``
    [s], Hertz pulse length ``tau[i]`` [s]. For each microphone at distance ``r`` it queues,
    at the arrival sample ``na = ceil((t + r / c) fs)``, the amplitudes
    ``a = phi(x).J / w_d * S(w_d tau) * w / r * e^{lam dt} * eps^{-(na % grid)}``
    (``phi(x)``: the shapes at the surface point nearest ``x``; ``dt = na / fs - t - r / c``).
    A contact microphone (``synth.channels``) hears only its own object, with its complex
    weights (``synth.chan_w``) in place of ``w / r`` and no delay. Rows are microphone-major
    per impact. Impacts on objects without modes or points, or with non-finite input, are
    skipped. Returns ``(count, used, next sample, max |a|)``.

    **Energy bound.** The impact leaves mode ``m`` with the velocity amplitude
    ``v_m = phi_m(x).J S(w_m tau)``, so it gives the object the vibration energy
    ``E = sum_m |v_m|^2 / 2``. A point impulse on a thin wall, an edge or a corner can make
    ``E`` far larger than the impact has (the local mobility of a point grows without bound
    as the mesh refines; a 0.3 mm can on its rim: 600 times the collision's kinetic energy,
    ``scripts/impact_energy.py``). No impact can give more than the energy the collision takes
    from the approach, ``|J| v_n (1 - e) / 2`` for an approach speed ``v_n`` and restitution
    ``e`` (:mod:`.impact_energy`), so when ``E > budget[i]`` every amplitude of the impact is
    scaled by ``sqrt(budget[i] / E)``. ``budget[i] = inf`` (an impulse given without a speed)
    leaves it unbounded.

    **Coupling.** Where ``mass[i]`` (the collision's effective mass along the impulse [kg],
    ``|J| / ((1 + e) v)``) is positive and finite and ``tau[i] > 0``, the modes push back on
    the contact that drives them (:func:`.contact_coupling.coupled_response`): the amplitudes
    are those the coupled contact leaves when it ends, ``T`` after ``t[i]``, and are queued from
    then on (``t[i] + T`` in place of ``t[i]`` above); they keep the modes' energy within the
    collision's however light the struck point is. ``mass[i] = 0`` keeps the prescribed
    half-sine force alone (the closed form above).
    """
    ob, cst, q = synth.objects, synth.consts[0], synth.queue
    mics = synth.mics
    chans = synth.channels
    c, fs, rmin, tol, rendered, grid = cst.c, cst.fs, cst.rmin, cst.tol, cst.rendered, cst.grid
    ev, qre, qim = q.events, q.re, q.im
    count = q.counts[0].count
    used = q.counts[0].pool_used
    k = P.shape[0]
    M = mics.shape[0]
    amax = 0.0
    nxt = np.int64(2**62)
    pl = np.zeros(3)
    jl = np.zeros(3)
    for i in range(k):
        o = obj[i]
        p0, p1 = ob.pts_off[o], ob.pts_off[o + 1]
        m0, m1 = ob.mode_off[o], ob.mode_off[o + 1]
        n = m1 - m0
        if n <= 0 or p1 <= p0:
            continue
        if not (np.isfinite(P[i, 0] + P[i, 1] + P[i, 2] + J[i, 0] + J[i, 1] + J[i, 2]) and np.isfinite(tau[i])):
            continue
        s0 = ob.shk_off[o]  # shapes of o: flat (points, 3, modes)
        pos = synth.pos[o]
        R = synth.R[o]
        for b in range(3):
            pl[b] = 0.0
            jl[b] = 0.0
        for a in range(3):
            for b in range(3):
                pl[b] += (P[i, a] - pos[a]) * R[a, b]
                jl[b] += J[i, a] * R[a, b]
        bi = nearest_sorted(ob.pts[p0:p1], ob.pts_index[p0:p1], ob.pts_axis[o], pl[0], pl[1], pl[2])
        sb = s0 + 3 * bi * n
        cm = np.empty(n, np.complex128)
        gn = np.empty(n)  # phi_m(x) . J
        energy = 0.0
        for m in range(n):
            G = ob.shk[sb + m] * jl[0] + ob.shk[sb + n + m] * jl[1] + ob.shk[sb + 2 * n + m] * jl[2]
            gn[m] = G
            vm = G * half_sine(ob.wd[m0 + m] * tau[i])
            cm[m] = vm / ob.wd[m0 + m]
            energy += 0.5 * (vm.real * vm.real + vm.imag * vm.imag)
        jn = np.sqrt(jl[0] * jl[0] + jl[1] * jl[1] + jl[2] * jl[2])
        t_i = t[i]
        if mass[i] > 0 and np.isfinite(mass[i]) and tau[i] > 0 and jn > 0:  # (docstring: coupling)
            for m in range(n):
                gn[m] /= jn
            ring = np.empty(n, np.complex128)
            steps, t_end = coupled_response(gn, ob.lam[m0:m1], tau[i], mass[i], ring)
            if steps > 0:
                t_i = t[i] + t_end  # (the modes ring from the contact's end)
                energy = 0.0
                for m in range(n):
                    cm[m] = jn * ring[m]
                    vm = cm[m] * ob.wd[m0 + m]
                    energy += 0.5 * (vm.real * vm.real + vm.imag * vm.imag)
        if energy > budget[i]:  # (the energy bound, docstring; NaN budgets bound nothing)
            f = np.sqrt(budget[i] / energy)
            for m in range(n):
                cm[m] *= f
        for mi in range(M):
            ch = chans[mi]
            if ch.owner == AIR:
                r = mic_distance(mics, mi, pos, rmin)
                ta = t_i + r / c
            elif ch.owner == o:  # a contact microphone on this object: no delay, its own weights
                r = 1.0
                ta = t_i
            else:  # a contact microphone on another body hears nothing of this impact
                continue
            nn = np.int64(np.ceil(ta * fs - tol))
            if nn < rendered:
                nn = rendered
            dts = nn / fs - ta
            g = nn % grid
            e = ev[count]
            e.obj = o
            e.mic = mi
            e.sample = nn
            e.offset = used
            e.width = n
            e.kind = 0
            for m in range(n):
                w = ob.w[m0 + m] / r if ch.owner == AIR else synth.chan_w[ch.w_off + m]
                if ch.owner == AIR and ch.w_off >= 0:  # an image microphone: the surface's reflection
                    w = w * synth.chan_w[ch.w_off + m0 + m].real
                v = cm[m] * w * np.exp(ob.lam[m0 + m] * dts - g * ob.leps[m0 + m])
                qre[used + m] = v.real
                qim[used + m] = v.imag
                av = abs(v)
                if not (av <= amax):  # NaN propagates into amax
                    amax = av
            if nn < nxt:
                nxt = nn
            used += n
            count += 1
    return count, used, nxt, amax


@njit(cache=True)
def commit_queued(queue, count, used, nxt):
    """Keep the rows :func:`impacts_to_queue` wrote past the queue's end."""
    qc = queue.counts[0]
    qc.count = count
    qc.pool_used = used
    if nxt < qc.next_sample:
        qc.next_sample = nxt


@njit(cache=True)
def place_rows(voice, re, im, v_rel, v_len, v_mic, width):
    """Rows of per-voice amplitudes/gains ``re``, ``im`` (k, >= v_len) moved into their
    microphone bank: row i's first ``v_len[voice[i]]`` values go to columns
    ``v_rel[voice[i]] ...`` of a (k, width) row. Returns ``(mic (k,), re, im)``."""
    k = voice.shape[0]
    out_re = np.zeros((k, width), re.dtype)
    out_im = np.zeros((k, width), im.dtype)
    mic = np.empty(k, np.int64)
    for i in range(k):
        v = voice[i]
        o = v_rel[v]
        mic[i] = v_mic[v]
        for j in range(v_len[v]):
            out_re[i, o + j] = re[i, j]
            out_im[i, o + j] = im[i, j]
    return mic, out_re, out_im


#: :func:`render_streams` results: rendered; gains are due and ``on_regain`` must run first;
#: rendered, but some sample is NaN or infinite (an exploding simulation)
RENDERED, REGAIN_FIRST, RENDERED_NONFINITE = 0, -1, -2


@njit(cache=True)
def render_streams(synth, bank, layout, start, n, may_regain, out, zero):
    """One block ``[start, start + n)`` without forcing sources, in one call: the due
    streams' gains (:func:`.streams.streams_gains`), the queue's events due in the block
    (:func:`.queue.take_due`), the streams' rows (:func:`.streams.streams_bank_rows`; none
    without streams), the direction factors (:func:`.directivity.hear_directions`) and
    :func:`render_all`, as ``Synthesizer.render`` does them one call each.

    ``may_regain``: the poses and microphones are current (else, when gains are due, nothing
    is done and :data:`REGAIN_FIRST` is returned: call ``on_regain`` and again). Returns
    :data:`RENDERED`, :data:`RENDERED_NONFINITE` (``out`` holds a NaN or infinity),
    :data:`REGAIN_FIRST`, or the ring length needed (> 0; the gains are computed, nothing
    rendered: grow the ring and call again). The events are taken only once nothing is
    handed back, so a repeated call renders the same block."""
    st = synth.streams
    if any_due(st):
        if not may_regain:
            return REGAIN_FIRST
        dmax = streams_gains(synth)
        need = dmax + n + 1
        if need > st.ring.shape[1]:
            return need
    end = start + n
    q = synth.queue
    if q.counts[0].count and q.counts[0].next_sample < end:
        ev = EventRows(*take_due(q, end, layout.vbase, layout.v_rel, layout.v_len, synth.consts[0].n_mics, layout.width))
    else:  # (nothing due: the queue stays as it is)
        ev = EventRows(np.zeros(synth.consts[0].n_mics + 1, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int8),
                       np.zeros((0, layout.width)), np.zeros((0, layout.width)))
    src = SourceRows(*streams_bank_rows(st, layout, start, end, zero))
    hear_directions(synth, bank, layout, ev, src, n)
    render_all(bank, synth.consts, ev, src, start, n, out, zero)
    for c in range(out.shape[0]):
        bad = 0
        for k in range(out.shape[1]):
            v = out[c, k]
            bad += (v - v) != 0.0  # (NaN for a NaN or an infinity: a count the loop can vectorise)
        if bad:
            return RENDERED_NONFINITE
    return RENDERED
