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

import numpy as np
from numba import njit

from .pulse import half_sine

__all__ = ["bank_free", "bank_forced", "render_voice"]


@njit(cache=True, fastmath=True)
def bank_free(wr, wi, pr, pi, na, out, o0, n, zero):
    """Advance ``na`` oscillators ``n`` samples, adding ``sum Im z`` to ``out[o0:o0+n]``.

    wr, wi : (>=na,) dtype   real / imaginary state (updated in place)
    pr, pi : (>=na,) dtype   real / imaginary pole
    out    : (N,) dtype      output (pressure, Pa)
    zero   : dtype scalar    0 of the bank's dtype (fixes the accumulator type)
    """
    for s in range(o0, o0 + n):
        acc = zero
        for k in range(na):
            a = wr[k]
            b = wi[k]
            acc += b
            wr[k] = a * pr[k] - b * pi[k]
            wi[k] = a * pi[k] + b * pr[k]
        out[s] += acc


@njit(cache=True, fastmath=True)
def bank_forced(wr, wi, pr, pi, na, out, o0, n, zero, gwr, gwi, F, act, nact):
    """Like :func:`bank_free` with forcing: ``z_i += sum_q g_{q,i} F[q, s]`` before output.

    gwr, gwi : (n_src, >=na) dtype  complex per-mode gain of each source (gathered)
    F        : (n_src, N) dtype     per-sample force values [N] of each source on this block
    act      : (nact,) int64        indices of the sources active on this segment
    """
    for s in range(o0, o0 + n):
        acc = zero
        for q in range(nact):
            j = act[q]
            fv = F[j, s]
            for k in range(na):
                wr[k] += gwr[j, k] * fv
                wi[k] += gwi[j, k] * fv
        for k in range(na):
            a = wr[k]
            b = wi[k]
            acc += b
            wr[k] = a * pr[k] - b * pi[k]
            wi[k] = a * pi[k] + b * pr[k]
        out[s] += acc


@njit(cache=True)
def _gather(zr, zi, active, pr, pi, gr, gi, wr, wi, wpr, wpi, gwr, gwi, idx):
    k = 0
    nsrc = gr.shape[0]
    for i in range(zr.shape[0]):
        if active[i]:
            idx[k] = i
            wr[k] = zr[i]
            wi[k] = zi[i]
            wpr[k] = pr[i]
            wpi[k] = pi[i]
            for q in range(nsrc):
                gwr[q, k] = gr[q, i]
                gwi[q, k] = gi[q, i]
            k += 1
    return k


@njit(cache=True)
def _scatter(zr, zi, wr, wi, idx, na):
    for k in range(na):
        zr[idx[k]] = wr[k]
        zi[idx[k]] = wi[k]


@njit(cache=True)
def render_voice(zr, zi, peak2, active, pr, pi, corr_r, corr_i,
                 ev_n, ev_kind, ev_re, ev_im,
                 src_a, src_b, gr, gi, F,
                 start, n, grid, cull2, floor2, out, zero):
    """Render samples ``[start, start + n)`` of one voice into ``out[:n]`` (added).

    Parameters
    ----------
    zr, zi : (m,) float64
        Full state at sample ``start`` (updated to the state at ``start + n``).
    peak2 : (m,) float64
        Largest ``|z|^2`` since the mode was last (re)started (updated).
    active : (m,) bool
        Which modes run (updated: events activate, culling deactivates).
    pr, pi : (m,) dtype
        Rounded poles of the bank.
    corr_r, corr_i : (m,) float64
        Grid correction ``(p_exact / p_dtype)^grid``.
    ev_n : (e,) int64
        Absolute sample index of each event, sorted, all in ``[start, start + n)``.
    ev_kind : (e,) int8
        0: add ``ev_re + j ev_im`` to the state; 1: only activate the modes where the row is
        non-zero (start of a forcing source).
    ev_re, ev_im : (e, m) float64
        Event amplitudes, already carrying the exact sub-sample phase.
    src_a, src_b : (q,) int64
        Absolute sample range ``[a, b)`` over which each forcing source acts.
    gr, gi : (q, m) dtype
        Complex per-mode gain of each source.
    F : (q, n) dtype
        Force samples of each source on this block (block-relative index).
    start, n, grid : int
        First absolute sample, number of samples, correction/culling grid (samples).
    cull2, floor2 : float
        Relative (to peak) and absolute squared-amplitude culling thresholds.
    out : (n,) dtype
        Output, added to.
    zero : dtype scalar
    """
    m = zr.shape[0]
    nsrc = gr.shape[0]
    wr = np.empty(m, pr.dtype)
    wi = np.empty(m, pr.dtype)
    wpr = np.empty(m, pr.dtype)
    wpi = np.empty(m, pr.dtype)
    gwr = np.empty((nsrc, m), pr.dtype)
    gwi = np.empty((nsrc, m), pr.dtype)
    idx = np.empty(m, np.int64)
    act = np.empty(max(nsrc, 1), np.int64)
    # a source already acting at the block start drives its modes from here on (a no-op for
    # sources whose start event activated them earlier: they cannot be culled while acting)
    for q in range(nsrc):
        if src_a[q] <= start and start < src_b[q]:
            for i in range(m):
                if (gr[q, i] != 0.0 or gi[q, i] != 0.0) and not active[i]:
                    active[i] = True
                    zr[i] = 0.0
                    zi[i] = 0.0
                    peak2[i] = 0.0
    na = _gather(zr, zi, active, pr, pi, gr, gi, wr, wi, wpr, wpi, gwr, gwi, idx)
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
            w = 0
            for k in range(na):
                i = idx[k]
                a = np.float64(wr[k])
                b = np.float64(wi[k])
                nr = a * corr_r[i] - b * corr_i[i]
                ni = a * corr_i[i] + b * corr_r[i]
                m2 = nr * nr + ni * ni
                if m2 > peak2[i]:
                    peak2[i] = m2
                driven = False
                for qq in range(nact):
                    if gwr[act[qq], k] != 0.0 or gwi[act[qq], k] != 0.0:
                        driven = True
                        break
                if (not driven) and (m2 < peak2[i] * cull2 or m2 < floor2):
                    active[i] = False
                    zr[i] = 0.0
                    zi[i] = 0.0
                    continue
                wr[w] = nr
                wi[w] = ni
                wpr[w] = wpr[k]
                wpi[w] = wpi[k]
                idx[w] = i
                for q in range(nsrc):
                    gwr[q, w] = gwr[q, k]
                    gwi[q, w] = gwi[q, k]
                w += 1
            na = w
        # ---- events at this sample
        if e < ne and ev_n[e] <= pos:
            _scatter(zr, zi, wr, wi, idx, na)
            while e < ne and ev_n[e] <= pos:
                if ev_kind[e] == 0:
                    for i in range(m):
                        a = ev_re[e, i]
                        b = ev_im[e, i]
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
            na = _gather(zr, zi, active, pr, pi, gr, gi, wr, wi, wpr, wpi, gwr, gwi, idx)
        # ---- run to the next grid point / event / source boundary / block end
        stop = end
        g = (pos // grid + 1) * grid
        if g < stop:
            stop = g
        if e < ne and ev_n[e] < stop:
            stop = ev_n[e]
        nact = 0
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
            bank_free(wr, wi, wpr, wpi, na, out, o0, stop - pos, zero)
        else:
            bank_forced(wr, wi, wpr, wpi, na, out, o0, stop - pos, zero, gwr, gwi, F, act, nact)
        pos = stop
    _scatter(zr, zi, wr, wi, idx, na)


@njit(cache=True)
def render_all(Zr, Zi, P2, ACT, PR, PI, CR, CI, v_off, v_len, v_mic, v_live,
               ev_ptr, ev_n, ev_kind, ev_re, ev_im,
               src_ptr, src_a, src_b, gr, gi, F,
               start, n, grid, cull2, floor2, out, zero):
    """Render samples ``[start, start + n)`` of every voice (one call for the whole scene).

    Voice ``v`` owns ``[v_off[v], v_off[v] + v_len[v])`` of the flat state / pole arrays and
    adds into ``out[v_mic[v]]``. Its events are rows ``ev_ptr[v] .. ev_ptr[v + 1]`` (sorted by
    sample), its sources rows ``src_ptr[v] .. src_ptr[v + 1]``; amplitudes and gains are
    padded to the widest voice (only the first ``v_len[v]`` columns are read). ``v_live[v]``
    is kept equal to "has running modes" so silent voices cost one branch. The per-voice
    work is exactly :func:`render_voice`, so block splits stay bit-identical.
    """
    nv = v_off.shape[0]
    for v in range(nv):
        e0 = ev_ptr[v]
        e1 = ev_ptr[v + 1]
        s0 = src_ptr[v]
        s1 = src_ptr[v + 1]
        if not v_live[v] and e0 == e1 and s0 == s1:
            continue
        o = v_off[v]
        m = v_len[v]
        if m == 0:
            continue
        render_voice(Zr[o:o + m], Zi[o:o + m], P2[o:o + m], ACT[o:o + m], PR[o:o + m], PI[o:o + m],
                     CR[o:o + m], CI[o:o + m],
                     ev_n[e0:e1], ev_kind[e0:e1], ev_re[e0:e1, :m], ev_im[e0:e1, :m],
                     src_a[s0:s1], src_b[s0:s1], gr[s0:s1, :m], gi[s0:s1, :m], F[s0:s1],
                     start, n, grid, cull2, floor2, out[v_mic[v]], zero)
        live = False
        for i in range(o, o + m):
            if ACT[i]:
                live = True
                break
        v_live[v] = live


@njit(cache=True, inline="always")
def _mic_distance(mics, m, pos, rmin):
    """Distance [m] from ``pos`` to microphone ``m``, at least ``rmin``."""
    dx = mics[m, 0] - pos[0]
    dy = mics[m, 1] - pos[1]
    dz = mics[m, 2] - pos[2]
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    return r if r >= rmin else rmin


@njit(cache=True, inline="always")
def _nearest_one(points, x, y, z):
    """Index of the row of ``points`` (p, 3) nearest to ``(x, y, z)`` (brute force; models
    carry ~1000 surface samples, so this is a few microseconds and needs no tree)."""
    best = np.inf
    bi = 0
    for i in range(points.shape[0]):
        dx = points[i, 0] - x
        dy = points[i, 1] - y
        dz = points[i, 2] - z
        d = dx * dx + dy * dy + dz * dz
        if d < best:
            best = d
            bi = i
    return bi


@njit(cache=True)
def nearest(points, q):
    """Index of the nearest row of ``points`` (p, 3) for each row of ``q`` (k, 3)."""
    k = q.shape[0]
    out = np.empty(k, np.int64)
    for j in range(k):
        out[j] = _nearest_one(points, q[j, 0], q[j, 1], q[j, 2])
    return out


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


# ---------------------------------------------------------------------------------------------
# Persistent sustained-contact streams (sliding / rolling noise of the per-step driver)
#
# A *stream* is one sustained contact source (one side of one contact pair and kind). Its
# noise is generated inside numba, sample by sample in source time, into a per-stream ring
# buffer ``ring[s, k & mask]`` (force [N] of source sample k); microphone m hears source sample
# k at voice sample ``k + D[s, m]`` (integer propagation delay; the sub-sample part is in the
# complex gain). Nothing is allocated per step beyond the block's source rows.

_U1 = np.uint64(0x9E3779B97F4A7C15)
_U2 = np.uint64(0xBF58476D1CE4E5B9)
_U3 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_M16 = np.uint64(0xFFFF)
_S16 = np.uint64(16)
_S32 = np.uint64(32)
_S48 = np.uint64(48)
_INV16 = 1.0 / 65536.0
_SQRT3 = float(np.sqrt(3.0))


@njit(cache=True, inline="always")
def _splitmix(state):
    state = state + _U1
    z = state
    z = (z ^ (z >> _S30)) * _U2
    z = (z ^ (z >> _S27)) * _U3
    z = z ^ (z >> _S31)
    return state, z


@njit(cache=True)
def stream_seed(seed, obj, key):
    """Initial generator state of a stream from (synthesizer seed, object index, stream key)."""
    s = np.uint64(seed & 0x7FFFFFFFFFFFFFFF)
    s, a = _splitmix(s ^ np.uint64(obj & 0x7FFFFFFFFFFFFFFF))
    s, b = _splitmix(a ^ np.uint64(key & 0x7FFFFFFFFFFFFFFF))
    return b


@njit(cache=True)
def stream_gains(pts, shk, pos, R, p, nrm, wd, weights, lam, mics, c, fs, rmin, tol,
                 gr, gi, D):
    """Per-microphone complex gain ``gr + j gi`` (n,) and integer delay ``D`` of a force along
    world ``nrm`` at world point ``p`` on an object at (pos, R) (see ``Synthesizer._add_source``)."""
    pl0 = 0.0
    pl1 = 0.0
    pl2 = 0.0
    d0 = 0.0
    d1 = 0.0
    d2 = 0.0
    for i in range(3):
        q = p[i] - pos[i]
        pl0 += q * R[i, 0]
        pl1 += q * R[i, 1]
        pl2 += q * R[i, 2]
        d0 += nrm[i] * R[i, 0]
        d1 += nrm[i] * R[i, 1]
        d2 += nrm[i] * R[i, 2]
    bi = _nearest_one(pts, pl0, pl1, pl2)
    n = wd.shape[0]
    M = mics.shape[0]
    for m in range(M):
        r = _mic_distance(mics, m, pos, rmin)
        ta = r / c
        Dm = np.int64(np.ceil(ta * fs - tol))
        if Dm < 0:
            Dm = 0
        D[m] = Dm
        dts = Dm / fs - ta
        for k in range(n):
            G = d0 * shk[bi, 0, k] + d1 * shk[bi, 1, k] + d2 * shk[bi, 2, k]
            a = G / (fs * wd[k]) * weights[k] / r
            e = np.exp(lam[k].real * dts)
            ph = lam[k].imag * dts
            gr[m, k] = a * e * np.cos(ph)
            gi[m, k] = a * e * np.sin(ph)
            if not (np.isfinite(gr[m, k]) and np.isfinite(gi[m, k])):
                gr[m, k] = 0.0  # a bad pose or point: silence, never NaN audio
                gi[m, k] = 0.0
        for k in range(n, gr.shape[1]):
            gr[m, k] = 0.0
            gi[m, k] = 0.0


#: Columns of the per-stream state: floats ``SF`` (streams, 9) and integers ``SI`` (streams, 9).
SF_AMP, SF_ALPHA, SF_Y, SF_P, SF_N = 0, 1, 2, 3, 6
SI_LIVE, SI_OBJ, SI_K0, SI_K1, SI_GEN, SI_LAST, SI_GUPD, SI_DUE, SI_RNG = range(9)


@njit(cache=True)
def stream_generate(s, k0, k1, amp, alpha, SF, SI, ring):
    """Drive stream ``s`` on source samples ``[k0, k1)``: its noise (force [N]) is generated now
    into the ring, so several drives may precede one render. Samples between the last drive
    and ``k0`` are silent; the low-pass restarts when the drive does not continue the last
    one (as :meth:`Synthesizer.slide`)."""
    cap = ring.shape[1]
    mask = cap - 1
    if k0 != SI[s, SI_K1]:
        SF[s, SF_Y] = 0.0
    SI[s, SI_K0] = k0
    SI[s, SI_K1] = k1
    SF[s, SF_AMP] = amp
    SF[s, SF_ALPHA] = alpha
    k = SI[s, SI_GEN]
    if k < k1 - cap:
        k = k1 - cap
    b = 1.0 - alpha
    y = SF[s, SF_Y]
    state = np.uint64(SI[s, SI_RNG])
    while k < k1:
        if k >= k0:
            # unit-variance noise: Irwin-Hall sum of four 16-bit uniforms from one splitmix64
            # draw (no log / cos per sample; the low-pass makes it Gaussian-like anyway)
            state, z = _splitmix(state)
            x = (np.float64(z & _M16) + np.float64((z >> _S16) & _M16) + np.float64((z >> _S32) & _M16)
                 + np.float64(z >> _S48) + 2.0) * _INV16 - 2.0
            x *= _SQRT3
            y = alpha * x + b * y
            ring[s, k & mask] = y * amp
        else:
            ring[s, k & mask] = 0.0
        k += 1
    SF[s, SF_Y] = y
    SI[s, SI_RNG] = np.int64(state)
    if k1 > SI[s, SI_GEN]:
        SI[s, SI_GEN] = k1
    if amp != 0.0 and k1 > SI[s, SI_LAST]:
        SI[s, SI_LAST] = k1


@njit(cache=True)
def stream_drive(s, k0, k1, amp, alpha, p, nrm, regain, rendered, slack, SF, SI, D, ring):
    """Drive stream ``s`` (see :func:`stream_generate`) at world point ``p`` along unit ``nrm``;
    marks its gains due every ``regain`` samples. Returns 0, or the ring length needed first
    (nothing changed then)."""
    if k1 <= k0 or amp == 0.0:
        return 0
    dmax = 0
    for m in range(D.shape[1]):
        if D[s, m] > dmax:
            dmax = D[s, m]
    need = dmax + (k1 - rendered) + slack
    if need > ring.shape[1]:
        return need
    for c in range(3):
        SF[s, SF_P + c] = p[c]
        SF[s, SF_N + c] = nrm[c]
    g = SI[s, SI_GUPD]
    if k0 >= g + regain or k0 < g:
        SI[s, SI_GUPD] = k0
        SI[s, SI_DUE] = 1
    stream_generate(s, k0, k1, amp, alpha, SF, SI, ring)
    return 0


@njit(cache=True)
def streams_bank_rows(SF, SI, D, st_gr, st_gi, ring, vbase, v_rel, v_len, n_mics, width, start, end, zero):
    """The block's rows of every stream for :func:`render_all`, active on ``[start,
    min(end, last + D))`` and read from the ring (the noise was generated when the stream was
    driven), placed in the microphone banks (voice ``v``'s gains at columns ``v_rel[v] ...``
    of a row ``width`` wide) and grouped by microphone (stream order within one):
    ``(ptr (n_mics + 1,), sa, sb, gr, gi, F)``, microphone ``m``'s rows ``ptr[m] : ptr[m + 1]``."""
    S = SF.shape[0]
    mask = ring.shape[1] - 1
    cap = ring.shape[1]
    ptr = np.zeros(n_mics + 1, np.int64)
    for m in range(n_mics):
        for s in range(S):
            if SI[s, SI_LIVE] and SI[s, SI_LAST] + D[s, m] > start:
                ptr[m + 1] += 1
    for m in range(n_mics):
        ptr[m + 1] += ptr[m]
    q = ptr[n_mics]
    n = end - start
    sa = np.empty(q, np.int64)
    sb = np.empty(q, np.int64)
    gr = np.zeros((q, width), st_gr.dtype)
    gi = np.zeros((q, width), st_gr.dtype)
    F = np.zeros((q, n), st_gr.dtype)
    j = 0
    for m in range(n_mics):
        for s in range(S):
            if not SI[s, SI_LIVE]:
                continue
            Dm = D[s, m]
            hi = SI[s, SI_LAST] + Dm
            if hi <= start:
                continue
            v = vbase[SI[s, SI_OBJ]] + m
            c0 = v_rel[v]
            w = min(v_len[v], st_gr.shape[2])
            for k in range(w):
                gr[j, c0 + k] = st_gr[s, m, k]
                gi[j, c0 + k] = st_gi[s, m, k]
            sa[j] = start
            sb[j] = hi if hi < end else end
            lo_src = SI[s, SI_GEN] - cap  # oldest sample still in the ring
            gen = SI[s, SI_GEN]
            for t in range(start, sb[j]):
                ks = t - Dm
                if ks >= lo_src and ks < gen:
                    F[j, t - start] = ring[s, ks & mask]
            j += 1
    return ptr, sa, sb, gr, gi, F


@njit(cache=True)
def impacts_to_queue(obj, P, J, t, tau, pts_all, pts_off, shk_all, shk_off, mode_off, wd_all, w_all, lam_all,
                     leps_all, pos_all, R_all, mics, c, fs, rmin, tol, rendered, grid,
                     QI, qkind, qre, qim, count, used):
    """Modal amplitudes of ``k`` impacts at every microphone, appended to an
    :class:`~mjsound.synth.queue.EventQueue`'s arrays (``QI``, ``qkind``, ``qre``, ``qim``
    from row ``count`` and pool offset ``used``; the caller reserved room).

    Impact ``i`` strikes object ``obj[i]`` (flat per-object data as in :func:`streams_gains`;
    complex poles ``lam_all`` and pole-rounding logs ``leps_all``) at world point ``P[i]``
    with impulse ``J[i]`` [N s] at synth time ``t[i]`` [s], Hertz pulse length ``tau[i]`` [s].
    For each microphone at distance ``r`` it queues, at the arrival sample
    ``na = ceil((t + r / c) fs)``, the amplitudes
    ``a = phi(x).J / w_d * S(w_d tau) * w / r * e^{lam dt} * eps^{-(na % grid)}``
    (``phi(x)``: the shapes at the surface point nearest ``x``; ``dt = na / fs - t - r / c``).
    Rows are microphone-major per impact. Impacts on objects without modes or points, or
    with non-finite input, are skipped. Returns ``(count, used, next sample, max |a|)``.
    """
    k = P.shape[0]
    M = mics.shape[0]
    amax = 0.0
    nxt = np.int64(2**62)
    pl = np.zeros(3)
    jl = np.zeros(3)
    for i in range(k):
        o = obj[i]
        p0, p1 = pts_off[o], pts_off[o + 1]
        m0, m1 = mode_off[o], mode_off[o + 1]
        n = m1 - m0
        if n <= 0 or p1 <= p0:
            continue
        if not (np.isfinite(P[i, 0] + P[i, 1] + P[i, 2] + J[i, 0] + J[i, 1] + J[i, 2]) and np.isfinite(tau[i])):
            continue
        shk = shk_all[shk_off[o]:shk_off[o + 1]].reshape((p1 - p0, 3, n))
        pos = pos_all[o]
        R = R_all[o]
        for b in range(3):
            pl[b] = 0.0
            jl[b] = 0.0
        for a in range(3):
            for b in range(3):
                pl[b] += (P[i, a] - pos[a]) * R[a, b]
                jl[b] += J[i, a] * R[a, b]
        bi = _nearest_one(pts_all[p0:p1], pl[0], pl[1], pl[2])
        cm = np.empty(n, np.complex128)
        for m in range(n):
            G = shk[bi, 0, m] * jl[0] + shk[bi, 1, m] * jl[1] + shk[bi, 2, m] * jl[2]
            cm[m] = G / wd_all[m0 + m] * half_sine(wd_all[m0 + m] * tau[i])
        for mi in range(M):
            r = _mic_distance(mics, mi, pos, rmin)
            ta = t[i] + r / c
            nn = np.int64(np.ceil(ta * fs - tol))
            if nn < rendered:
                nn = rendered
            dts = nn / fs - ta
            g = nn % grid
            QI[0, count] = o
            QI[1, count] = mi
            QI[2, count] = nn
            QI[3, count] = used
            QI[4, count] = n
            qkind[count] = 0
            for m in range(n):
                v = cm[m] * (w_all[m0 + m] / r) * np.exp(lam_all[m0 + m] * dts - g * leps_all[m0 + m])
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


@njit(cache=True)
def any_due(SI, n):
    """Whether any of the first ``n`` streams is marked for new gains (``SI_DUE``)."""
    for j in range(n):
        if SI[j, SI_DUE]:
            return True
    return False


@njit(cache=True)
def streams_gains(n, SI, SF, D, st_gr, st_gi, pts_all, pts_off, shk_all, shk_off, mode_off, wd_all, w_all,
                  lam_all, pos_all, R_all, mics, c, fs, rmin, tol):
    """:func:`stream_gains` of every stream ``j < n`` marked due (``SI_DUE``, cleared here) in
    one call. Object ``o``'s surface points are
    rows ``pts_off[o]:pts_off[o+1]`` of ``pts_all``, its shapes the flat slice
    ``shk_off[o]:shk_off[o+1]`` of ``shk_all`` (points, 3, modes), its per-mode values the
    slice ``mode_off[o]:mode_off[o+1]`` of ``wd_all`` ...; its pose ``pos_all[o]``, ``R_all[o]``.
    Streams of removed objects (not live, or no points) are skipped. Returns the largest
    delay ``D`` computed [samples]."""
    dmax = 0
    for j in range(n):
        if not SI[j, SI_DUE]:
            continue
        SI[j, SI_DUE] = 0
        o = SI[j, SI_OBJ]
        if not SI[j, SI_LIVE] or o + 1 >= pts_off.shape[0]:
            continue
        p0, p1 = pts_off[o], pts_off[o + 1]
        m0, m1 = mode_off[o], mode_off[o + 1]
        if p1 <= p0 or m1 <= m0:
            continue
        shk = shk_all[shk_off[o]:shk_off[o + 1]].reshape((p1 - p0, 3, m1 - m0))
        stream_gains(pts_all[p0:p1], shk, pos_all[o], R_all[o], SF[j, SF_P:SF_P + 3], SF[j, SF_N:SF_N + 3],
                     wd_all[m0:m1], w_all[m0:m1], lam_all[m0:m1], mics, c, fs, rmin, tol,
                     st_gr[j], st_gi[j], D[j])
        for m in range(D.shape[1]):
            if D[j, m] > dmax:
                dmax = D[j, m]
    return dmax


#: :func:`render_streams` results: rendered; gains are due and ``on_regain`` must run first;
#: rendered, but some sample is NaN or infinite (an exploding simulation)
RENDERED, REGAIN_FIRST, RENDERED_NONFINITE = 0, -1, -2


@njit(cache=True)
def render_streams(n_st, SI, SF, D, st_gr, st_gi, ring, dmax, may_regain,
                   pts_all, pts_off, shk_all, shk_off, mode_off, wd_all, w_all, lam_all, pos_all, R_all, mics, c,
                   fs, rmin, tol,
                   vbase, v_rel, v_len_bank, n_mics, width,
                   Zr, Zi, P2, ACT, PR, PI, CR, CI, v_off, v_len, v_mic, v_live,
                   ev_ptr, ev_n, ev_kind, ev_re, ev_im,
                   start, n, grid, cull2, floor2, out, zero):
    """One block with persistent streams and no forcing sources, in one call: the due
    streams' gains (:func:`streams_gains`), their rows (:func:`streams_bank_rows`) and
    :func:`render_all`, as ``Synthesizer.render`` does them one call each.

    ``dmax`` is the largest stream delay so far [samples]; ``may_regain``: the poses and
    microphones are current (else, when gains are due, nothing is done and
    :data:`REGAIN_FIRST` is returned: call ``on_regain`` and again). Returns ``(code, dmax)``:
    :data:`RENDERED`, :data:`RENDERED_NONFINITE` (``out`` holds a NaN or infinity),
    :data:`REGAIN_FIRST`, or the ring length needed (> 0; the gains are computed, nothing
    rendered: grow the ring and call again)."""
    if any_due(SI, n_st):
        if not may_regain:
            return REGAIN_FIRST, dmax
        dmax = max(dmax, streams_gains(n_st, SI, SF, D, st_gr, st_gi, pts_all, pts_off, shk_all, shk_off, mode_off,
                                       wd_all, w_all, lam_all, pos_all, R_all, mics, c, fs, rmin, tol))
        need = dmax + n + 1
        if need > ring.shape[1]:
            return need, dmax
    ptr, sa, sb, gr, gi, F = streams_bank_rows(SF[:n_st], SI[:n_st], D[:n_st], st_gr[:n_st], st_gi[:n_st],
                                               ring[:n_st], vbase, v_rel, v_len_bank, n_mics, width, start,
                                               start + n, zero)
    render_all(Zr, Zi, P2, ACT, PR, PI, CR, CI, v_off, v_len, v_mic, v_live, ev_ptr, ev_n, ev_kind, ev_re, ev_im,
               ptr, sa, sb, gr, gi, F, start, n, grid, cull2, floor2, out, zero)
    for c in range(out.shape[0]):
        for k in range(out.shape[1]):
            if not np.isfinite(out[c, k]):
                return RENDERED_NONFINITE, dmax
    return RENDERED, dmax
