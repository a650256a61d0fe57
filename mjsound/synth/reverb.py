"""A late reverberant tail: a feedback delay network with a decay time per octave band.

The statistical late reverberation of a room (Polack's model: Gaussian noise whose energy
decays as ``exp(-t / tau_b)`` in each band, ``tau_b = T60_b / (6 ln 10)``) is rendered by a
feedback delay network (J.-M. Jot and A. Chaigne, "Digital delay networks for designing
artificial reverberators", 90th AES Convention, 1991, preprint 3030): ``L`` delay lines of
mutually prime lengths ``m_i`` samples, each line's output ``v_i`` passed through an
absorptive filter, mixed by an orthogonal matrix and fed back,

.. math::

    v_i[n] = h_i * \\big(s_i[n - m_i]\\big), \\qquad
    s[n] = \\mathbf{Q}\\, v[n] + \\mathbf{b}\\, x[n], \\qquad y[n] = \\mathbf{c}^T v[n],

``Q = H_L / sqrt(L)`` the normalised Hadamard matrix (lossless: it keeps the energy held in
the lines), ``b`` a column of ``Q`` (one per input: orthogonal inputs), ``c`` a row of
``Q`` with random signs per line (one per output: uncorrelated outputs). A sample that crosses line ``i``
spends ``m_i`` samples there, so Jot's absorptive filter gives it the gain that the band's
decay asks for that long,

.. math::

    20 \\log_{10} |h_i(f_b)| = -60\\, \\frac{m_i}{f_s\\, T_{60,b}} \\;\\mathrm{dB},

and every band then decays at its own ``T60_b`` whatever path its energy takes through the
lines. ``h_i`` is a broadband gain and a cascade of second-order high shelves at the
geometric midpoints between the band centres (R. Bristow-Johnson's cookbook shelves, slope
1), their gains fitted to the band centres through the shelves' interaction, as in
K. Prawda, V. Välimäki and S. J. Schlecht, "Improved reverberation time control for feedback
delay networks", DAFx 2019 (:func:`fit_graphic_eq`). The same cascade on the output sets the
tail's level per band.

Level: the lines hold the energy ``|b|^2 = 1`` a unit input impulse put there; it decays as
``exp(-t / tau_b)`` and spreads over the ``M = sum m_i`` samples the lines hold, so the
output's energy per sample is ``|c|^2 exp(-n / (f_s tau_b)) / M`` once the lines have mixed
(a few passes; :meth:`LateTail.impulse_energy`). The caller sets the level it wants per
band with ``band_gain`` (:mod:`mjsound.sim.room_tail` calibrates a room's).

Input: each tail ``a`` takes the weighted sum of some rows of the block (``send_rows``,
``send_weight``) through a short tapped delay (``tap_delay``, ``tap_gain``: where and how
fast the tail starts), and adds its output into row ``a``. The kernel runs sample by
sample with its state carried between calls, so any split of the samples into blocks
renders the same numbers.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit import njit, njit_inner
from .dispatch import compiled_entry
from .packing import state_typeof

__all__ = ["TailPlan", "TailState", "LateTail", "shelf", "cascade_db", "fit_graphic_eq", "prime_delays",
           "render_tail", "N_LINES"]

#: The largest gain of one shelf of :func:`fit_graphic_eq` [dB].
MAX_SHELF_DB = 24.0

#: Delay lines of the network (the kernel's Hadamard transform is written out for 8).
N_LINES = 8


class TailPlan(NamedTuple):
    """What the network is (made once; ``L`` lines, ``S`` shelves, ``A`` outputs, ``K`` input
    taps, ``I`` send rows)."""

    line_len: np.ndarray  # (L,) int64: delay line lengths m_i [samples]
    line_off: np.ndarray  # (L,) int64: each line's start in TailState.lines
    line_g: np.ndarray  # (L,) float64: each line's broadband gain
    line_eq: np.ndarray  # (S, 5, L) float64: each line's shelves (b0, b1, b2, a1, a2)
    out_gain: np.ndarray  # (A, L) float64: c of each output
    out_eq: np.ndarray  # (S, 5) float64: the outputs' shelves (the tail's level per band)
    out_g: np.ndarray  # (A,) float64: each output's broadband gain
    tap_delay: np.ndarray  # (K,) int64: the input's taps [samples] (< TailState.send_buf.shape[1])
    tap_gain: np.ndarray  # (K,) float64
    send_row: np.ndarray  # (I,) int64: block rows fed into the lines
    send_line: np.ndarray  # (I,) int64: the input each of them feeds (then spread over the lines by H_L)
    send_weight: np.ndarray  # (I,) float64: its weight (sign included)


class TailState(NamedTuple):
    """What the network carries from one block to the next."""

    lines: np.ndarray  # (sum of line_len,) float64: the delay lines
    line_pos: np.ndarray  # (L,) int64: each line's read/write position
    z1: np.ndarray  # (S, L) float64: the lines' shelves' state (transposed direct form II)
    z2: np.ndarray  # (S, L) float64
    out_z: np.ndarray  # (A, S, 2) float64: the outputs' shelves' state
    send_buf: np.ndarray  # (L, D) float64: each line's input, its last D samples (ring)
    send_pos: np.ndarray  # (1,) int64


def shelf(f0: float, gain_db: float, fs: float) -> np.ndarray:
    """A second-order high shelf (Bristow-Johnson's cookbook, shelf slope 1): gain 1 well
    below ``f0`` [Hz], ``gain_db`` well above, half of it (in dB) at ``f0``.

    Returns
    -------
    (5,) float64
        ``b0, b1, b2, a1, a2`` of ``H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``.
    """
    A = 10.0 ** (gain_db / 40.0)
    w0 = 2.0 * math.pi * f0 / fs
    cw, alpha = math.cos(w0), math.sin(w0) / 2.0 * math.sqrt(2.0)
    sa = 2.0 * math.sqrt(A) * alpha
    b0 = A * ((A + 1) + (A - 1) * cw + sa)
    b1 = -2 * A * ((A - 1) + (A + 1) * cw)
    b2 = A * ((A + 1) + (A - 1) * cw - sa)
    a0 = (A + 1) - (A - 1) * cw + sa
    a1 = 2 * ((A - 1) - (A + 1) * cw)
    a2 = (A + 1) - (A - 1) * cw - sa
    return np.array([b0, b1, b2, a1, a2]) / a0


def cascade_db(sos: np.ndarray, f, fs: float) -> np.ndarray:
    """Magnitude [dB] of the cascade ``sos`` (S, 5) at frequencies ``f`` [Hz]."""
    z = np.exp(-2j * np.pi * np.asarray(f, np.float64) / fs)
    h = np.ones_like(z)
    for b0, b1, b2, a1, a2 in np.asarray(sos).reshape(-1, 5):
        h = h * (b0 + b1 * z + b2 * z * z) / (1 + a1 * z + a2 * z * z)
    return 20 * np.log10(np.abs(h))


def fit_graphic_eq(bands_hz, target_db, fs: float, iterations: int = 6) -> tuple[float, np.ndarray]:
    """A broadband gain and ``len(bands_hz) - 1`` high shelves whose cascade has the gain
    ``target_db`` at each band centre.

    The shelves sit at the geometric midpoints between neighbouring centres; a shelf's dB
    response is nearly proportional to its gain (and exactly additive over the cascade), so
    Newton's iteration on the interaction matrix ``J[b, k] = d(dB at band b) / d(gain k)``
    converges in a few steps (damped, each shelf within :data:`MAX_SHELF_DB`: targets that
    alternate band by band more than shelves an octave apart can follow keep the closest
    fit found). Bands at or above ``0.45 fs`` are left out (their shelves flat): they take the
    highest band's gain below.

    Returns
    -------
    (broadband gain [linear], (S, 5) shelves)

    Examples
    --------
    >>> g, sos = fit_graphic_eq([125, 250, 500, 1000, 2000, 4000], [-1, -1.5, -2, -3, -4, -5], 48000)
    >>> np.round(20 * np.log10(g) + cascade_db(sos, [125, 250, 500, 1000, 2000, 4000], 48000), 6).tolist()
    [-1.0, -1.5, -2.0, -3.0, -4.0, -5.0]
    """
    bands = np.asarray(bands_hz, np.float64)
    target = np.asarray(target_db, np.float64)
    mids = np.sqrt(bands[:-1] * bands[1:])
    fit = int(np.sum(bands < 0.45 * fs))
    if fit < 1:
        raise ValueError(f"fit_graphic_eq: the sample rate {fs} Hz is below every band ({bands.tolist()} Hz)")
    f, t = bands[:fit], target[:fit]
    x = np.concatenate([[t[0]], np.diff(t)])  # (broadband gain, the shelves' gains)

    def response(x):
        sos = [shelf(mids[k], x[k + 1], fs) for k in range(fit - 1)]
        return x[0] + (cascade_db(np.array(sos), f, fs) if sos else 0.0)

    err = np.abs(t - response(x)).max()
    for _ in range(iterations):  # (damped: a step is halved until it lowers the largest error)
        r = response(x)
        J = np.empty((fit, fit))
        for k in range(fit):
            dx = np.zeros(fit)
            dx[k] = 1e-3
            J[:, k] = (response(x + dx) - r) / 1e-3
        step = np.linalg.lstsq(J, t - r, rcond=None)[0]
        for lam in 0.5 ** np.arange(8):
            trial = np.concatenate([[x[0] + lam * step[0]], np.clip(x[1:] + lam * step[1:], -MAX_SHELF_DB, MAX_SHELF_DB)])
            e = np.abs(t - response(trial)).max()
            if e < err:
                x, err = trial, e
                break
        else:
            break
    sos = np.tile(np.array([1.0, 0.0, 0.0, 0.0, 0.0]), (len(bands) - 1, 1))
    for k in range(fit - 1):
        sos[k] = shelf(mids[k], x[k + 1], fs)
    return 10.0 ** (x[0] / 20.0), sos


def prime_delays(mean_samples: float, n: int = N_LINES, seed: int = 0) -> np.ndarray:
    """``n`` distinct primes spread geometrically over ``[0.6, 1.6] mean_samples`` (each
    jittered by a few percent), so that no two lines' echoes keep coinciding (mutually prime
    lengths)."""
    rng = np.random.default_rng(seed)
    want = mean_samples * np.geomspace(0.6, 1.6, n) * rng.uniform(0.96, 1.04, n)
    out = []
    for w in np.maximum(want, 2.0):
        p = max(2, int(round(w)))
        while not _is_prime(p) or p in out:
            p += 1
        out.append(p)
    return np.array(sorted(out), np.int64)


def _is_prime(p: int) -> bool:
    return p >= 2 and all(p % d for d in range(2, int(p ** 0.5) + 1))


def _hadamard(n: int) -> np.ndarray:
    h = np.ones((1, 1))
    while h.shape[0] < n:
        h = np.block([[h, h], [h, -h]])
    return h


class LateTail:
    """A late reverberant tail (one network) heard at ``A`` outputs, added into the rows
    ``0 .. A-1`` of each block.

    Parameters
    ----------
    fs : float
        Sample rate [Hz].
    bands_hz : (B,) array_like
        Octave band centres [Hz].
    rt60 : (B,) array_like
        Reverberation time per band [s] (finite, > 0).
    band_gain : (B,) array_like
        The outputs' gain per band (linear, > 0; :meth:`impulse_energy` says what an impulse
        into the network gives at an output).
    out_scale : (A,) array_like
        Each output's gain (> 0, finite).
    mean_delay : float
        The mean length of the delay lines [s].
    taps : ((K,) delays [samples], (K,) gains)
        The input's taps.
    send_row, send_weight : (I,) array_like
        Block rows fed into the network and their weights (each block's send rows are read
        whole before the outputs are added: an output's own row may be one). Row ``j`` enters the
        lines through column ``j mod L`` of ``H_L / sqrt(L)`` (with a random sign): orthogonal
        input vectors, so copies of one sound in several rows (a source's images) ring through
        different paths of the network and their tails add as incoherent sums do, not as the
        comb filter their delays would make of one input.

    Raises
    ------
    ValueError
        For a reverberation time that is not a positive finite number, a gain that is not
        positive and finite, or a delay out of range; the message names the input.

    Examples
    --------
    >>> tail = LateTail(48000, [125, 250, 500, 1000, 2000, 4000], [0.8] * 6, [1.0] * 6, [1.0], 0.006,
    ...                 ([0], [1.0]), [1], [1.0])
    >>> block = np.zeros((2, 4800)); block[1, 0] = 1.0
    >>> bool(np.abs(tail.apply(block)[0]).max() > 0)
    True
    """

    def __init__(self, fs, bands_hz, rt60, band_gain, out_scale, mean_delay, taps, send_row, send_weight):
        fs = float(fs)
        if not (math.isfinite(fs) and fs > 0):
            raise ValueError(f"LateTail: sample rate fs={fs!r} must be a positive number of Hz")
        bands = np.asarray(bands_hz, np.float64).reshape(-1)
        rt60 = np.asarray(rt60, np.float64).reshape(-1)
        if rt60.shape != bands.shape or not np.all(np.isfinite(rt60)) or not np.all(rt60 > 0):
            raise ValueError(f"LateTail: rt60={rt60.tolist()} s must be {bands.size} finite times > 0 (one per "
                             "octave band; a room that absorbs everything has no tail: turn it off)")
        band_gain = np.asarray(band_gain, np.float64).reshape(-1)
        out_scale = np.asarray(out_scale, np.float64).reshape(-1)
        for name, g in (("band_gain", band_gain), ("out_scale", out_scale)):
            if not g.size or not np.all(np.isfinite(g)) or not np.all(g > 0):
                raise ValueError(f"LateTail: {name}={g.tolist()} must be finite gains > 0")
        if band_gain.shape != bands.shape:
            raise ValueError(f"LateTail: band_gain must have {bands.size} gains (one per band)")
        mean_delay = float(mean_delay)
        if not (math.isfinite(mean_delay) and mean_delay * fs >= 2):
            raise ValueError(f"LateTail: mean_delay={mean_delay!r} s must be finite and at least 2 samples")
        self.fs, self.bands_hz, self.rt60 = fs, bands, rt60
        L, A, S = N_LINES, out_scale.size, bands.size - 1
        line_len = prime_delays(mean_delay * fs, L)
        line_off = np.cumsum(line_len) - line_len
        rng = np.random.default_rng(12345)
        # outputs: rows of a Hadamard matrix (mutually orthogonal: the outputs are uncorrelated)
        # with random line signs; beyond L - 1 outputs, random signs
        signs = rng.choice([-1.0, 1.0], L)
        rows = _hadamard(L)[1:]
        out_gain = np.array([rows[a] * signs if a < L - 1 else rng.choice([-1.0, 1.0], L)
                             for a in range(A)]).reshape(A, L) / math.sqrt(L)
        # Jot's absorption: a band loses -60 m_i / (fs T60) dB over line i's m_i samples
        line_eq = np.zeros((S, 5, L))
        line_g = np.zeros(L)
        grid = np.concatenate([[0.0], np.geomspace(10.0, fs / 2, 400)])
        for i in range(L):
            line_g[i], line_eq[:, :, i] = fit_graphic_eq(bands, -60.0 * line_len[i] / (fs * rt60), fs)
            # (stable: the loop's gain below 1 at every frequency, not only at the band centres; a
            # fit that rises to 0 dB between them, for decays of minutes, is lowered to -1e-4 dB)
            top = 20 * math.log10(line_g[i]) + float(cascade_db(line_eq[:, :, i], grid, fs).max())
            if top > -1e-4:
                line_g[i] *= 10.0 ** (-(top + 1e-4) / 20.0)
        g, out_eq = fit_graphic_eq(bands, 20 * np.log10(band_gain), fs)
        tap_delay = np.asarray(taps[0], np.int64).reshape(-1)
        tap_gain = np.asarray(taps[1], np.float64).reshape(-1)
        if tap_delay.shape != tap_gain.shape or not tap_delay.size or np.any(tap_delay < 0) \
                or not np.all(np.isfinite(tap_gain)):
            raise ValueError("LateTail: taps must be (delays >= 0 [samples], finite gains) of equal length, at "
                             "least one")
        tap_delay, where = np.unique(tap_delay, return_inverse=True)  # (taps of one delay summed)
        tap_gain = np.bincount(where.reshape(-1), tap_gain, tap_delay.size)
        send_row = np.asarray(send_row, np.int64).reshape(-1)
        send_weight = np.asarray(send_weight, np.float64).reshape(-1)
        if send_row.shape != send_weight.shape or np.any(send_row < 0) or not np.all(np.isfinite(send_weight)):
            raise ValueError("LateTail: send_row and send_weight must be equally long, the rows >= 0, the weights "
                             "finite")
        send_line = np.arange(send_row.size, dtype=np.int64) % L
        send_weight = send_weight * rng.choice([-1.0, 1.0], send_row.size)
        self.plan = TailPlan(line_len, line_off, line_g, line_eq, out_gain, out_eq, g * out_scale, tap_delay,
                             tap_gain, send_row, send_line, send_weight)
        self._depth = int(tap_delay.max(initial=0)) + 1
        self._max_row = max(A - 1, int(send_row.max(initial=0)))
        self._entries = {}  # (the kernel's compiled entry point per block type: no typing per call)
        self.state = None
        self.reset()

    @property
    def n_outputs(self) -> int:
        return self.plan.out_gain.shape[0]

    def reset(self) -> None:
        """Silence the tail (the lines, filters and input history emptied)."""
        p = self.plan
        S, A = p.line_eq.shape[0], p.out_gain.shape[0]
        self.state = TailState(np.zeros(int(p.line_len.sum())), np.zeros(N_LINES, np.int64), np.zeros((S, N_LINES)),
                               np.zeros((S, N_LINES)), np.zeros((A, S, 2)), np.zeros((N_LINES, self._depth)),
                               np.zeros(1, np.int64))

    def apply(self, block: np.ndarray) -> np.ndarray:
        """Add the tail's next ``block.shape[1]`` samples into rows ``0 .. A-1`` of ``block``
        (in place; returns it). ``block``: (rows, n) float32 or float64."""
        if block.ndim != 2 or block.shape[0] <= self._max_row:
            raise ValueError(f"LateTail.apply: a (rows, n) block with at least {self._max_row + 1} rows (the outputs "
                             f"and the send rows), got shape {block.shape}")
        if block.shape[1]:
            key = state_typeof(block)
            entry = self._entries.get(key)
            if entry is None:
                entry = self._entries[key] = compiled_entry(render_tail, (self.plan, self.state, block))
            entry(self.plan, self.state, block)
        return block

    def impulse_energy(self) -> np.ndarray:
        """``|c_a|^2 / sum(m_i)`` per output ``a`` (A,): the energy per sample output ``a`` has
        (before its gains) after a unit impulse into one send row of weight 1 (a unit vector
        into the lines), times ``exp(n / (f_s tau_b))``, once the lines have mixed (module
        docstring)."""
        p = self.plan
        return (p.out_gain ** 2).sum(axis=1) / p.line_len.sum()


@njit_inner(cache=True)
def _hadamard_in_place(v):
    """``v <- H_8 v``: the fast Walsh-Hadamard transform of 8 values (Sylvester's order),
    unrolled (three stages of butterflies)."""
    b0, b1, b2, b3 = v[0] + v[1], v[0] - v[1], v[2] + v[3], v[2] - v[3]
    b4, b5, b6, b7 = v[4] + v[5], v[4] - v[5], v[6] + v[7], v[6] - v[7]
    c0, c1, c2, c3 = b0 + b2, b1 + b3, b0 - b2, b1 - b3
    c4, c5, c6, c7 = b4 + b6, b5 + b7, b4 - b6, b5 - b7
    v[0], v[1], v[2], v[3] = c0 + c4, c1 + c5, c2 + c6, c3 + c7
    v[4], v[5], v[6], v[7] = c0 - c4, c1 - c5, c2 - c6, c3 - c7


@njit(cache=True)
def render_tail(plan, state, block):
    """The tail's next ``n = block.shape[1]`` samples added into rows ``0 .. A-1`` of
    ``block`` (module docstring): per sample, each send row times its weight into its line's
    input ring, the taps' sum of each ring into its line, the lines' outputs through their
    gains and shelves, each output's sum through the outputs' gains and shelves into its row,
    the lines mixed by the fast Walsh-Hadamard transform over ``sqrt(L)`` and fed back with
    the inputs (spread over the lines the same way).
    Float64 inside; the state carried in ``state`` (any split into blocks gives the same
    samples).

    Parameters
    ----------
    plan : TailPlan
    state : TailState
        Updated in place.
    block : (rows, n) float32 or float64
        Read (the send rows, all ``n`` samples first) and written (rows ``0 .. A-1``).
    """
    L = N_LINES
    S = plan.line_eq.shape[0]
    A = plan.out_gain.shape[0]
    K = plan.tap_delay.shape[0]
    D = state.send_buf.shape[1]
    n = block.shape[1]
    x = np.zeros((L, n))
    for j in range(plan.send_row.shape[0]):
        r, i, w = plan.send_row[j], plan.send_line[j], plan.send_weight[j]
        xi = x[i]
        for s in range(n):
            xi[s] += w * block[r, s]
    direct = K == 1 and plan.tap_delay[0] == 0  # (one tap, no delay: no ring needed)
    v = np.empty(L)
    u = np.empty(L)
    buf, pos, off, length = state.send_buf, state.line_pos, plan.line_off, plan.line_len
    eq, z1, z2, g, c = plan.line_eq, state.z1, state.z2, plan.line_g, plan.out_gain
    oeq, oz = plan.out_eq, state.out_z
    scale = 1.0 / math.sqrt(L)
    p_in = state.send_pos[0]
    for s in range(n):
        if direct:
            for i in range(L):
                u[i] = plan.tap_gain[0] * x[i, s]
        else:
            for i in range(L):
                buf[i, p_in] = x[i, s]
                u[i] = 0.0
            for k in range(K):
                q = p_in - plan.tap_delay[k]
                q = q + D if q < 0 else q
                a_k = plan.tap_gain[k]
                for i in range(L):
                    u[i] += a_k * buf[i, q]
            p_in = p_in + 1 if p_in + 1 < D else 0
        for i in range(L):
            v[i] = state.lines[off[i] + pos[i]] * g[i]
        for st in range(S):  # the lines' shelf st, transposed direct form II
            for i in range(L):
                xi = v[i]
                yi = eq[st, 0, i] * xi + z1[st, i]
                z1[st, i] = eq[st, 1, i] * xi - eq[st, 3, i] * yi + z2[st, i]
                z2[st, i] = eq[st, 2, i] * xi - eq[st, 4, i] * yi
                v[i] = yi
        for a in range(A):
            y = 0.0
            for i in range(L):
                y += c[a, i] * v[i]
            y *= plan.out_g[a]
            for st in range(S):  # the output's shelves
                yo = oeq[st, 0] * y + oz[a, st, 0]
                oz[a, st, 0] = oeq[st, 1] * y - oeq[st, 3] * yo + oz[a, st, 1]
                oz[a, st, 1] = oeq[st, 2] * y - oeq[st, 4] * yo
                y = yo
            block[a, s] += y
        _hadamard_in_place(v)
        _hadamard_in_place(u)  # (each line's input spread over all lines: every send row's own column of H)
        for i in range(L):
            w = pos[i]
            state.lines[off[i] + w] = (v[i] + u[i]) * scale
            pos[i] = w + 1 if w + 1 < length[i] else 0
    state.send_pos[0] = p_in
