"""Persistent sustained-contact streams: sliding / rolling noise generated in numba.

A *stream* is one sustained contact source (one side of one contact pair). Its noise is
generated sample by sample in source time into a per-stream ring buffer
``ring[s, k & (L - 1)]`` (force [N] of source sample k); microphone m hears source sample k
at voice sample ``k + D[s, m]`` (integer propagation delay; the sub-sample part is in the
complex gain). The state is a :data:`.records.STREAM` table (:class:`.records.StreamState`);
nothing is allocated per step beyond the block's source rows.

Noise: unit-variance Irwin-Hall sums of four 16-bit uniforms from one splitmix64 draw,
low-passed by a one-pole filter ``y += alpha (x - y)`` with ``alpha = 1 - e^{-2 pi f_c / fs}``,
``f_c = speed / length`` (van den Doel et al. 2001), scaled by ``amp = roughness |F_n| |v|``.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit, njit_inner
from .records import AIR

__all__ = ["noise_draw", "stream_aim", "stream_written", "stream_seed", "nearest_sorted", "stream_gains", "stream_generate", "stream_drive", "streams_gains", "streams_bank_rows",
           "any_due"]

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
SQRT3 = float(np.sqrt(3.0))  # a noise_draw times this: unit variance


@njit(cache=True, inline="always")
def _splitmix(state):
    state = state + _U1
    z = state
    z = (z ^ (z >> _S30)) * _U2
    z = (z ^ (z >> _S27)) * _U3
    z = z ^ (z >> _S31)
    return state, z


@njit(cache=True, inline="always")
def noise_draw(state):
    """The next sample of a stream's noise generator: ``(state, x)``, ``state`` the generator's
    uint64 state, ``x`` the centred sum of the four 16-bit lanes of one splitmix64 draw: in
    [-2, 2), mean 0, variance 1/3, near Gaussian (times :data:`SQRT3`: unit variance)."""
    state, z = _splitmix(state)
    x = (np.float64(z & _M16) + np.float64((z >> _S16) & _M16) + np.float64((z >> _S32) & _M16)
         + np.float64(z >> _S48) + 2.0) * _INV16 - 2.0
    return state, x


_MASK64 = (1 << 64) - 1


def _splitmix_int(state: int) -> tuple[int, int]:
    """:func:`_splitmix` on Python integers (modulo 2^64)."""
    state = (state + 0x9E3779B97F4A7C15) & _MASK64
    z = ((state ^ (state >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return state, z ^ (z >> 31)


def stream_seed(seed: int, obj: int, key: int) -> int:
    """Initial generator state of a stream from (synthesizer seed, object index, stream key):
    the uint64 ``splitmix(splitmix(seed ^ obj) ^ key)`` (each input's low 63 bits), as the
    int64 of the same bits that the stream record's ``rng`` field holds. Plain Python: it
    runs once per new stream, in Python, where a numba call would cost more than the mix."""
    s = seed & 0x7FFFFFFFFFFFFFFF
    _, a = _splitmix_int(s ^ (obj & 0x7FFFFFFFFFFFFFFF))
    _, b = _splitmix_int(a ^ (key & 0x7FFFFFFFFFFFFFFF))
    return b - (1 << 64) if b >> 63 else b


@njit(cache=True, inline="always")
def mic_distance(mics, m, pos, rmin):
    """Distance [m] from ``pos`` to microphone ``m``, at least ``rmin``."""
    dx = mics[m, 0] - pos[0]
    dy = mics[m, 1] - pos[1]
    dz = mics[m, 2] - pos[2]
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    return r if r >= rmin else rmin


@njit_inner(cache=True)
def nearest_sorted(pts, index, axis, x, y, z):
    """The nearest surface sample for rows ``pts`` (p, 3) sorted ascending along column
    ``axis``: the sample index (``index`` of the row) of the row nearest to ``(x, y, z)``, the
    lowest sample index among equally near rows, 0 for a non-finite point or no rows: exactly
    what a brute-force scan of the samples in their own order gives (``tests/test_nearest.py``).

    From the row where the axis coordinate reaches the query's, rows are visited outwards,
    always on the side with the smaller axis gap ``a``; a side stops once ``a^2`` exceeds the
    best squared distance (every farther row there is at least that far), so a surface of
    ~1000 samples costs tens of rows, not all of them. Distances are summed as
    ``dx*dx + dy*dy + dz*dz`` in that order, as the scan does, so ties and rounding are the same."""
    n = pts.shape[0]
    if n == 0 or not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
        return 0
    q = x if axis == 0 else (y if axis == 1 else z)
    lo = 0
    hi = n
    while lo < hi:  # first row whose axis coordinate is >= q
        mid = (lo + hi) >> 1
        if pts[mid, axis] < q:
            lo = mid + 1
        else:
            hi = mid
    up = lo
    dn = lo - 1
    best = np.inf
    bi = -1
    while up < n or dn >= 0:
        if up < n and (dn < 0 or pts[up, axis] - q <= q - pts[dn, axis]):
            i = up
        else:
            i = dn
        a = pts[i, axis] - q
        if a * a > best:  # this side is done: its next rows are farther along the axis
            if i == up:
                up = n
            else:
                dn = -1
            continue
        if i == up:
            up += 1
        else:
            dn -= 1
        dx = pts[i, 0] - x
        dy = pts[i, 1] - y
        dz = pts[i, 2] - z
        d = dx * dx + dy * dy + dz * dz
        j = index[i]
        if d < best or (d == best and j < bi):
            best = d
            bi = j
    return bi if bi >= 0 else 0


@njit_inner(cache=True)
def stream_gains(synth, j, o):
    """Per-microphone complex gain ``gr + j gi`` and integer delay ``D`` of stream ``j`` on
    object ``o``: a force along the stream's world direction ``n`` at its world point ``p``,
    ``G = phi(x) . n_local`` at the nearest surface point, ``a = G / (fs w_d) w / r`` with
    the sub-sample delay's phase ``e^{lam (D / fs - r / c)}`` (see ``Synthesizer._add_source``);
    at a contact microphone (``synth.channels``) ``a = G / (fs w_d)`` times its complex weight
    on its own object, no delay, and 0 on any other."""
    ob, cst, st = synth.objects, synth.consts[0], synth.streams
    p0, p1 = ob.pts_off[o], ob.pts_off[o + 1]
    m0, m1 = ob.mode_off[o], ob.mode_off[o + 1]
    n = m1 - m0
    pos = synth.pos[o]
    R = synth.R[o]
    p = st.table[j].p
    nrm = st.table[j].n
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
    bi = nearest_sorted(ob.pts[p0:p1], ob.pts_index[p0:p1], ob.pts_axis[o], pl0, pl1, pl2)
    sb = ob.shk_off[o] + 3 * bi * n  # shapes of o: flat (points, 3, modes)
    shk = ob.shk
    mics = synth.mics
    fs = cst.fs
    gr = st.gr[j]
    gi = st.gi[j]
    D = st.D[j]
    chans = synth.channels
    # per mode, the same at every microphone: G / (fs w_d) and G / (fs w_d) w
    gq = np.empty(n)
    gw = np.empty(n)
    for k in range(n):
        G = d0 * shk[sb + k] + d1 * shk[sb + n + k] + d2 * shk[sb + 2 * n + k]
        gq[k] = G / (fs * ob.wd[m0 + k])
        gw[k] = gq[k] * ob.w[m0 + k]
    for m in range(mics.shape[0]):
        owner = chans[m].owner
        if owner != AIR:  # a contact microphone: its own object only, its weights, no delay
            D[m] = 0
            for k in range(n):
                if owner == o:
                    a = gq[k] * synth.chan_w[chans[m].w_off + k]
                    gr[m, k] = a.real
                    gi[m, k] = a.imag
                    if not (np.isfinite(gr[m, k]) and np.isfinite(gi[m, k])):
                        gr[m, k] = 0.0
                        gi[m, k] = 0.0
                else:
                    gr[m, k] = 0.0
                    gi[m, k] = 0.0
            for k in range(n, gr.shape[1]):
                gr[m, k] = 0.0
                gi[m, k] = 0.0
            continue
        r = mic_distance(mics, m, pos, cst.rmin)
        ta = r / cst.c
        Dm = np.int64(np.ceil(ta * fs - cst.tol))
        if Dm < 0:
            Dm = 0
        D[m] = Dm
        dts = Dm / fs - ta
        # (the delay factors depend on dts alone: an object at rest keeps them)
        fresh = not (st.dts[j, m] == dts)
        st.dts[j, m] = dts
        fac = st.dfac[j, m]
        refl = chans[m].w_off  # (>= 0: an image microphone, its reflection per mode at chan_w[refl + m0 + k])
        for k in range(n):
            a = gw[k] / r
            if refl >= 0:
                a *= synth.chan_w[refl + m0 + k].real
            if fresh:
                lam = ob.lam[m0 + k]
                ph = lam.imag * dts
                fac[0, k] = np.exp(lam.real * dts)
                fac[1, k] = np.cos(ph)
                fac[2, k] = np.sin(ph)
            e = fac[0, k]
            gr[m, k] = a * e * fac[1, k]
            gi[m, k] = a * e * fac[2, k]
            if not (np.isfinite(gr[m, k]) and np.isfinite(gi[m, k])):
                gr[m, k] = 0.0  # a bad pose or point: silence, never NaN audio
                gi[m, k] = 0.0
        for k in range(n, gr.shape[1]):
            gr[m, k] = 0.0
            gi[m, k] = 0.0


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts every stream array)
def stream_generate(streams, s, k0, k1, amp, alpha):
    """Drive stream ``s`` on source samples ``[k0, k1)``: its noise (force [N]) is generated now
    into the ring, so several drives may precede one render. Samples between the last drive
    and ``k0`` are silent; the low-pass restarts when the drive does not continue the last
    one (as :meth:`Synthesizer.slide`)."""
    ring = streams.ring
    st = streams.table[s]
    cap = ring.shape[1]
    mask = cap - 1
    if k0 != st.k1:
        st.y = 0.0
    st.k0 = k0
    st.k1 = k1
    st.amp = amp
    st.alpha = alpha
    k = st.gen
    if k < k1 - cap:
        k = k1 - cap
    b = 1.0 - alpha
    y = st.y
    state = np.uint64(st.rng)
    while k < k1:
        if k >= k0:
            state, x = noise_draw(state)
            x *= SQRT3
            y = alpha * x + b * y
            ring[s, k & mask] = y * amp
        else:
            ring[s, k & mask] = 0.0
        k += 1
    st.y = y
    st.rng = np.int64(state)
    if k1 > st.gen:
        st.gen = k1
    if amp != 0.0 and k1 > st.last:
        st.last = k1


@njit_inner(cache=True, inline="always")  # (numba IR: no call that reference-counts every stream array)
def ring_need(streams, consts, s, k1):
    """Ring length stream ``s`` needs to be driven up to sample ``k1``: its largest delay plus
    the samples not rendered yet plus the slack."""
    dmax = 0
    D = streams.D
    for m in range(D.shape[1]):
        if D[s, m] > dmax:
            dmax = D[s, m]
    return dmax + (k1 - consts[0].rendered) + consts[0].slack


@njit_inner(cache=True)
def stream_drive(streams, consts, s, k0, k1, amp, alpha, p, nrm, regain):
    """Drive stream ``s`` (see :func:`stream_generate`) at world point ``p`` along unit ``nrm``;
    marks its gains due every ``regain`` samples. Returns 0, or the ring length needed first
    (nothing changed then)."""
    if k1 <= k0 or amp == 0.0:
        return 0
    need = ring_need(streams, consts, s, k1)
    if need > streams.ring.shape[1]:
        return need
    stream_aim(streams.table[s], p, nrm, 1.0, k0, regain)
    stream_generate(streams, s, k0, k1, amp, alpha)
    return 0


@njit_inner(cache=True, inline="always")  # (as stream_generate: no call per record member)
def stream_aim(st, p, nrm, sign, k0, regain):
    """Point stream record ``st`` at world point ``p`` [m] along ``sign * nrm`` (``nrm`` a unit
    vector), its gains marked due when ``regain`` samples have passed since they were made at
    sample ``st.gupd`` (or the clock went back before it) at sample ``k0``. Returns whether
    they were marked due."""
    for c in range(3):
        st.p[c] = p[c]
        st.n[c] = sign * nrm[c]
    g = st.gupd
    if k0 >= g + regain or k0 < g:
        st.gupd = k0
        st.due = 1
        return True
    return False


@njit_inner(cache=True, inline="always")
def stream_written(st, k0, k1):
    """Stream record ``st`` now holds force samples ``[k0, k1)`` at unit amplitude, written into
    its ring by the caller (the drives: :mod:`.drive_tones`, :mod:`.drive_broadband`)."""
    st.k0 = k0
    st.k1 = k1
    st.amp = 1.0
    if k1 > st.gen:
        st.gen = k1
    if k1 > st.last:
        st.last = k1


@njit(cache=True)
def any_due(streams):
    """Whether any stream in use is marked for new gains."""
    t = streams.table
    for j in range(streams.counts[0].n):
        if t[j].due:
            return True
    return False


@njit(cache=True)
def streams_gains(synth):
    """:func:`stream_gains` of every stream marked due (cleared here) in one call; streams of
    removed objects (not live, or no points or modes) are skipped. Updates and returns the
    largest delay ``dmax`` [samples]."""
    st = synth.streams
    ob = synth.objects
    t = st.table
    dmax = st.counts[0].dmax
    for j in range(st.counts[0].n):
        if not t[j].due:
            continue
        t[j].due = 0
        o = t[j].obj
        if not t[j].live or o + 1 >= ob.pts_off.shape[0]:
            continue
        if ob.pts_off[o + 1] <= ob.pts_off[o] or ob.mode_off[o + 1] <= ob.mode_off[o]:
            continue
        stream_gains(synth, j, o)
        for m in range(st.D.shape[1]):
            if st.D[j, m] > dmax:
                dmax = st.D[j, m]
    st.counts[0].dmax = dmax
    return dmax


@njit(cache=True)
def streams_bank_rows(streams, layout, start, end, zero):
    """The block's rows of every stream for :func:`.kernels.render_all`, active on
    ``[start, min(end, last + D))`` and read from the ring, placed in the microphone banks
    (voice ``v``'s gains at columns ``v_rel[v] ...`` of a row ``width`` wide) and grouped by
    microphone (stream order within one). ``layout``: :class:`.kernels.BankLayout`.
    Returns the fields of :class:`.records.SourceRows` as a plain tuple (microphone ``m``'s rows
    ``ptr[m] : ptr[m + 1]``)."""
    S = streams.counts[0].n
    t = streams.table
    D = streams.D
    ring = streams.ring
    st_gr = streams.gr
    st_gi = streams.gi
    n_mics = D.shape[1]
    width = layout.width
    mask = ring.shape[1] - 1
    cap = ring.shape[1]
    ptr = np.zeros(n_mics + 1, np.int64)
    for m in range(n_mics):
        for s in range(S):
            if t[s].live and t[s].last + D[s, m] > start:
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
            if not t[s].live:
                continue
            Dm = D[s, m]
            hi = t[s].last + Dm
            if hi <= start:
                continue
            v = layout.vbase[t[s].obj] + m
            c0 = layout.v_rel[v]
            w = min(layout.v_len[v], st_gr.shape[2])
            for k in range(w):
                gr[j, c0 + k] = st_gr[s, m, k]
                gi[j, c0 + k] = st_gi[s, m, k]
            sa[j] = start
            sb[j] = hi if hi < end else end
            gen = t[s].gen
            # source samples ks = u - Dm still in the ring (gen - cap <= ks < gen); the rest stay 0
            u0 = max(start, gen - cap + Dm)
            u1 = min(sb[j], gen + Dm)
            if u1 > u0:  # (at most cap samples: two contiguous runs of the ring, around its wrap)
                r0 = (u0 - Dm) & mask
                n0 = min(u1 - u0, cap - r0)
                o = u0 - start
                for x in range(n0):
                    F[j, o + x] = ring[s, r0 + x]
                for x in range(n0, u1 - u0):
                    F[j, o + x] = ring[s, x - n0]
            j += 1
    return ptr, sa, sb, gr, gi, F  # (the fields of SourceRows: a NamedTuple is not boxed safely on Ctrl-C)
