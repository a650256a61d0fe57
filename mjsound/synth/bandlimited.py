"""Band-limited contact pulses through a second-order transfer, rendered sample-exactly.

An impact's rigid-body acceleration is a half-sine pulse of length ``tau`` (the Hertz contact
time of :mod:`.pulse`) and total velocity change ``dv``::

    a(t) = dv * pi / (2 tau) * sin(pi t / tau),   0 <= t <= tau   (0 elsewhere)
    A(w) = dv * S(w tau)                          (S: :func:`.pulse.half_sine`)

Everything this module renders is such a pulse seen through a rational transfer of at most
second order, arriving at time ``t_a``::

    P(w) = A(w) * (b0 + b1 s) / (1 + d1 s + d2 s^2) * e^{-s t_a},     s = j w

(the click of a rigid body at a microphone, :mod:`.accel_noise`, and the rigid-body
acceleration at a contact microphone, :mod:`.contact_mic`, where ``b1 = d1 = d2 = 0``).

Sampling ``p(t)`` directly would alias: a 10 us steel pulse is flat to 60 kHz. Instead the
samples are those of ``p`` band-limited by a zero-phase low-pass ``G``::

    p_n = (1 / 2 pi) int P(w) G(w) e^{j w n / fs} dw,
    G = 1 below 0.40 fs, a raised-cosine taper to 0 at fs / 2 (and above)

which is exact in amplitude and sub-sample timing in the band. The integral is evaluated on
the DFT grid of a window of ``N`` samples (a power of two) starting ``LEAD`` samples before the
arrival: by Poisson's summation this is exact up to the part of the signal outside the window,
which is the low-pass's own tails (``LEAD = TAIL = 32`` samples: -70 dB of the kernel's
energy) and the transfer's ringing after ``RING_TIME_CONSTANTS`` of its slowest pole
(``e^-16``). The inverse DFT is a radix-2 FFT in numba (:func:`fft_inplace`). On the grid
``w_k = k w_1`` the two phase factors of each bin, the half-sine's end ``e^{-j w_k tau}`` and the
arrival's ``e^{-j w_k t}``, are each the previous bin's times a constant rotation, recomputed
exactly every :data:`RESEED` bins (:func:`render_pulse`).

Cost is per pulse only (one FFT of 64 to about a thousand points per pulse and channel, one
for a click and its images, :func:`pulse_group`; a hollow body's long contact, :mod:`.pulse`,
makes the long ones); a render with no pulses pending touches nothing (:class:`PulseTrack`). The low-pass is non-causal: the
at most ``LEAD`` samples of its pre-ringing that fall before audio already handed out are
dropped (a pulse on a sample boundary loses about 4 % of its energy, -0.2 dB).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner
from .bank_loops import FAST
from .dispatch import EntryPoint
from .interrupt import interruptible
from .pulse import half_sine_rotated
from .records import TRACK, TrackState

__all__ = ["PULSE_DTYPE", "LEAD", "TAIL", "PASS_FRACTION", "RING_TIME_CONSTANTS", "MAX_PULSE_SAMPLES", "RESEED",
           "fft_inplace", "fft_with", "twiddles", "lowpass", "transfer", "pulse_window", "group_window", "render_pulse",
           "pulse_group", "render_group", "GROUP_GROWTH", "mix_pulse", "ring_add",
           "pulse_extent", "add_pulses", "take_into_block", "PulseTrack"]

#: One pulse at one output channel: arrival time [s], pulse length [s], velocity change times
#: transfer numerator ``b0`` [channel unit / (m/s)] and ``b1`` [channel unit s / (m/s)],
#: transfer denominator ``d1`` [s] and ``d2`` [s^2], the output channel, and ``joins``: non-zero
#: asks that the pulse be rendered in the window of the row before it (an image microphone's
#: click, :func:`pulse_group`; honoured only where the two are the same pulse at the same
#: channel).
PULSE_DTYPE = np.dtype([("time_s", np.float64), ("tau_s", np.float64), ("b0", np.float64), ("b1", np.float64),
                        ("d1", np.float64), ("d2", np.float64), ("channel", np.int64), ("joins", np.int64)])

#: Samples of the window before the arrival sample (the low-pass's pre-ringing).
LEAD = 32
#: Samples of the window after the pulse and its ringing (the low-pass's post-ringing).
TAIL = 32
#: ``G(f) = 1`` up to this fraction of the sample rate; raised-cosine taper to 0 at 0.5.
PASS_FRACTION = 0.40
#: Ringing is kept for this many time constants of the transfer's slowest pole (e^-16).
RING_TIME_CONSTANTS = 16.0
#: Longest window [samples] one pulse may need; :func:`pulse_window` reports longer ones.
MAX_PULSE_SAMPLES = 1 << 16
#: :func:`render_pulse` computes its phase factors exactly every this many bins and rotates
#: them in between.
RESEED = 32


@njit(cache=True)
def twiddles(n, inverse):
    """The twiddle factors of :func:`fft_with` for every transform length up to ``n`` (a
    power of two): stage ``L`` (butterflies ``L / 2`` apart) reads ``e^{-+2 pi j k / L}``,
    ``k < L / 2``, at index ``L / 2 - 1 + k`` (``-`` forward, ``+`` with ``inverse``). A table
    kept by the caller saves the ``n - 1`` sines and cosines of every transform (most of a
    short one's time); each factor is computed as the transform would compute it itself."""
    t = np.empty(max(n - 1, 1), np.complex128)
    sign = 1.0 if inverse else -1.0
    length = 2
    while length <= n:
        half = length // 2
        step = sign * 2.0 * math.pi / length
        for k in range(half):
            t[half - 1 + k] = complex(math.cos(step * k), math.sin(step * k))
        length *= 2
    return t


@njit(cache=True)
def fft_with(x, table, inverse):
    """Radix-2 complex FFT of ``x`` (complex128, length a power of two), in place, with the
    twiddle factors ``table`` (:func:`twiddles` of at least ``len(x)`` and the same ``inverse``).

    ``inverse=False``: ``X_k = sum_n x_n e^{-2 pi j k n / N}``; ``inverse=True``: the same with
    ``+j`` and a factor ``1 / N`` (``numpy.fft.fft`` / ``ifft``).
    """
    n = x.shape[0]
    j = 0
    for i in range(1, n):  # bit-reversal permutation
        bit = n >> 1
        while j & bit:
            j ^= bit
            bit >>= 1
        j |= bit
        if i < j:
            t = x[i]
            x[i] = x[j]
            x[j] = t
    length = 2
    while length <= n:
        half = length // 2
        for k in range(half):
            w = table[half - 1 + k]
            for start in range(0, n, length):
                a = x[start + k]
                b = x[start + k + half] * w
                x[start + k] = a + b
                x[start + k + half] = a - b
        length *= 2
    if inverse:
        for i in range(n):
            x[i] = x[i] / n


@njit(cache=True)
def fft_inplace(x, inverse):
    """:func:`fft_with` with its twiddle factors computed for this one transform."""
    fft_with(x, twiddles(x.shape[0], inverse), inverse)


@njit_inner(cache=True)
def lowpass(f_over_fs):
    """The band limit ``G`` at ``f / fs`` (see the module docstring), for ``f >= 0``."""
    if f_over_fs <= PASS_FRACTION:
        return 1.0
    if f_over_fs >= 0.5:
        return 0.0
    x = (f_over_fs - PASS_FRACTION) / (0.5 - PASS_FRACTION)
    return 0.5 * (1.0 + math.cos(math.pi * x))


@njit_inner(cache=True)
def transfer(s, b0, b1, d1, d2):
    """``(b0 + b1 s) / (1 + d1 s + d2 s^2)`` at complex ``s``."""
    return (b0 + b1 * s) / (1.0 + d1 * s + d2 * s * s)


@njit_inner(cache=True)
def _slowest_time_constant(d1, d2):
    """Longest time constant [s] of the poles of ``1 + d1 s + d2 s^2`` (0: no pole)."""
    if d2 == 0.0:
        return d1 if d1 > 0.0 else 0.0
    disc = d1 * d1 - 4.0 * d2
    if disc < 0.0:
        return 2.0 * d2 / d1 if d1 > 0.0 else 1e300  # complex pair, decay d1 / (2 d2)
    slow = -d1 + math.sqrt(disc)  # root closest to 0, times 2 d2
    if slow >= 0.0:
        return 1e300  # unstable or marginal: refused by pulse_window
    return -2.0 * d2 / slow


@njit_inner(cache=True)
def pulse_window(tau, d1, d2, fs):
    """Window length ``N`` [samples] (a power of two) for a pulse, or 0 when it would exceed
    :data:`MAX_PULSE_SAMPLES` (a pulse longer than about a second at the sample rate, or a
    transfer that does not decay)."""
    return group_window(tau, d1, d2, fs, 0)


@njit_inner(cache=True)
def group_window(tau, d1, d2, fs, spread):
    """:func:`pulse_window` for copies of a pulse arriving over ``spread`` samples (the last
    one's arrival sample minus the first one's)."""
    tc = _slowest_time_constant(d1, d2)
    body = (tau + RING_TIME_CONSTANTS * tc) * fs
    if not body < MAX_PULSE_SAMPLES:
        return 0
    need = LEAD + int(math.ceil(body)) + TAIL + 2 + spread
    n = 64
    while n < need:
        n *= 2
    return n if n <= MAX_PULSE_SAMPLES else 0


@njit_inner(cache=True)
def _usable(p, fs):
    """Whether pulse record ``p`` has finite fields and a time whose sample fits int64."""
    ok = np.isfinite(p.time_s) and np.isfinite(p.tau_s) and np.isfinite(p.b0) and np.isfinite(p.b1)
    ok = ok and np.isfinite(p.d1) and np.isfinite(p.d2)
    return ok and abs(p.time_s * fs) < 2.0**61


@njit(cache=True)
def render_pulse(pulse, dv, fs, work, out, table):
    """Band-limited samples of one pulse (see the module docstring).

    Parameters
    ----------
    pulse : PULSE_DTYPE record
        Arrival time, length and transfer.
    dv : float
        Velocity change [m/s] that scales the pulse.
    fs : float
        Sample rate [Hz].
    work : complex128 array
        Scratch, at least the window length long.
    out : float64 array
        Receives the samples, at least the window length long.
    table : complex128 array
        The inverse transform's twiddle factors, ``twiddles(len(work), True)``.

    Returns
    -------
    (first, n) : (int, int)
        ``out[:n]`` are samples ``first .. first + n - 1`` (absolute, sample k at time k / fs);
        ``n == 0`` when the pulse does not fit (:func:`pulse_window`) or has a non-finite field.
    """
    if not _usable(pulse, fs):
        return 0, 0
    n = pulse_window(pulse.tau_s, pulse.d1, pulse.d2, fs)
    if n == 0 or n > work.shape[0] or n > out.shape[0] or n > table.shape[0] + 1:
        return 0, 0
    first = int(math.floor(pulse.time_s * fs)) - LEAD
    shift = pulse.time_s - first / fs  # arrival after the window's first sample [s]
    tau = pulse.tau_s
    w1 = 2.0 * math.pi * fs / n  # the DFT grid's spacing [rad/s]
    # e^{-j w tau} (the half-sine's end) and e^{-j w shift} (the arrival) on the grid, by
    # rotation from bin to bin; recomputed every RESEED bins, so the products' rounding stays
    # within a few ulps (two complex exponentials per bin were most of a pulse's time)
    step_end = np.exp(-1j * w1 * tau)
    step_arrival = np.exp(-1j * w1 * shift)
    end = arrival = 1.0 + 0.0j
    work[:n] = 0.0
    for k in range(n // 2 + 1):
        if k % RESEED == 0:
            end = np.exp(-1j * (k * w1) * tau)
            arrival = np.exp(-1j * (k * w1) * shift)
        g = lowpass(k / n)  # (k / n: cycles per sample)
        if g != 0.0:
            w = k * w1
            s = 1j * w
            v = dv * half_sine_rotated(w * tau, end) * transfer(s, pulse.b0, pulse.b1, pulse.d1, pulse.d2)
            v = v * g * arrival * fs
            work[k] = v
            if 0 < k < n // 2:
                work[n - k] = v.conjugate()
        end *= step_end
        arrival *= step_arrival
    fft_with(work[:n], table, True)
    for i in range(n):
        out[i] = work[i].real
    return first, n


#: A pulse joins the window of the rows before it (:func:`pulse_group`) only while the window
#: stays at most this many times the first row's own.
GROUP_GROWTH = 2


@njit_inner(cache=True)
def _joinable(pulses, dv, i, j, fs):
    """Whether row ``j`` asks to join row ``i``'s window and is the same pulse (length,
    transfer denominator, velocity change) at the same channel, with usable fields."""
    p = pulses[i]
    q = pulses[j]
    return (q.joins != 0 and q.channel == p.channel and q.tau_s == p.tau_s and q.d1 == p.d1 and q.d2 == p.d2
            and dv[j] == dv[i] and _usable(q, fs))


@njit_inner(cache=True)
def pulse_group(pulses, dv, i, n, fs):
    """``(end, first, window)``: the rows ``i .. end - 1`` rendered in one window of ``window``
    samples from sample ``first`` (:func:`render_group`): row ``i`` and the rows after it that
    join it (:func:`_joinable`) while that window stays within :data:`GROUP_GROWTH` times row
    ``i``'s own; ``window = 0`` (``end = i + 1``): row ``i`` renders alone (:func:`render_pulse`).

    Copies of one pulse along different paths (a click and its images in the floor,
    :mod:`mjsound.sim.images`) differ only in arrival and numerator; their sum's spectrum is
    ``A(w) G(w) / (1 + d1 s + d2 s^2) sum_k (b0_k + b1_k s) e^{-s t_k}``: one inverse FFT."""
    p = pulses[i]
    if i + 1 >= n or pulses[i + 1].joins == 0 or not (np.isfinite(dv[i]) and _usable(p, fs)):
        return i + 1, 0, 0
    base = pulse_window(p.tau_s, p.d1, p.d2, fs)
    if base == 0:
        return i + 1, 0, 0
    lo = int(math.floor(p.time_s * fs))
    hi = lo
    window = base
    end = i + 1
    while end < n and _joinable(pulses, dv, i, end, fs):
        k = int(math.floor(pulses[end].time_s * fs))
        w = group_window(p.tau_s, p.d1, p.d2, fs, max(hi, k) - min(lo, k))
        if w == 0 or w > GROUP_GROWTH * base:
            break
        lo = min(lo, k)
        hi = max(hi, k)
        window = w
        end += 1
    if end == i + 1:
        return end, 0, 0
    return end, lo - LEAD, window


@njit(cache=True)
def render_group(pulses, i, end, dv, fs, first, n, work, out, table):
    """Band-limited samples of the sum of the pulses ``pulses[i:end]`` (one :func:`pulse_group`,
    scaled by ``dv[i]``) in the window of ``n`` samples from absolute sample ``first``:
    :func:`render_pulse`'s spectrum with the numerators and arrivals summed per bin, one inverse
    FFT. Fills ``out[:n]``."""
    p = pulses[i]
    k_rows = end - i
    tau = p.tau_s
    w1 = 2.0 * math.pi * fs / n
    shift = np.empty(k_rows)
    arrival = np.empty(k_rows, np.complex128)
    step_arrival = np.empty(k_rows, np.complex128)
    for r in range(k_rows):
        shift[r] = pulses[i + r].time_s - first / fs
        step_arrival[r] = np.exp(-1j * w1 * shift[r])
    step_end = np.exp(-1j * w1 * tau)
    end_phase = 1.0 + 0.0j
    work[:n] = 0.0
    for k in range(n // 2 + 1):
        if k % RESEED == 0:
            end_phase = np.exp(-1j * (k * w1) * tau)
            for r in range(k_rows):
                arrival[r] = np.exp(-1j * (k * w1) * shift[r])
        g = lowpass(k / n)
        if g != 0.0:
            w = k * w1
            s = 1j * w
            num = 0.0 + 0.0j
            for r in range(k_rows):
                q = pulses[i + r]
                num += (q.b0 + q.b1 * s) * arrival[r]
            v = dv[i] * half_sine_rotated(w * tau, end_phase) * num / (1.0 + p.d1 * s + p.d2 * s * s)
            v = v * g * fs
            work[k] = v
            if 0 < k < n // 2:
                work[n - k] = v.conjugate()
        end_phase *= step_end
        for r in range(k_rows):
            arrival[r] *= step_arrival[r]
    fft_with(work[:n], table, True)
    for j in range(n):
        out[j] = work[j].real


@njit(cache=True, fastmath=FAST)
def ring_add(acc, m, off, first, x):
    """Add ``x`` (n,) into row ``m`` of the ring ``acc`` (channels x capacity, a power of two;
    absolute sample ``k`` at ``k & (capacity - 1)``) at absolute samples ``off + q``, those
    before ``first`` left out: in at most two contiguous runs (the ring's wrap)."""
    n = x.shape[0]
    cap = acc.shape[1]
    row = acc[m]
    q = max(0, first - off)
    while q < n:
        i = (off + q) & (cap - 1)
        run = min(n - q, cap - i)
        dst = row[i:i + run]
        src = x[q:q + run]
        for t in range(run):  # (over views, indexed from 0: the loop is vectorised)
            dst[t] += src[t]
        q += run


@njit_inner(cache=True)
def mix_pulse(acc, start, channel, first, samples):
    """Add ``samples`` (absolute sample ``first`` onwards) into row ``channel`` of the ring
    accumulator ``acc`` (channels, capacity a power of two) whose oldest kept sample is
    ``start``; samples before ``start`` are dropped (:func:`ring_add`). Returns the last
    sample written + 1 (``start`` if none)."""
    n = samples.shape[0]
    ring_add(acc, channel, first, start, samples)
    return max(start, first + n) if n > 0 else start


@njit(cache=True)
def pulse_extent(pulses, dv, n, fs):
    """``(longest window, last absolute sample)`` of the rows ``pulses[:n]`` that render: a
    finite velocity change ``dv`` and a window that fits (:func:`pulse_window`; others count 0)."""
    n_max = 0
    last = -(2**62)
    i = 0
    while i < n:
        end, first, w = pulse_group(pulses, dv, i, n, fs)
        if w == 0:
            p = pulses[i]
            w = pulse_window(p.tau_s, p.d1, p.d2, fs) if np.isfinite(dv[i]) and _usable(p, fs) else 0
            first = int(math.floor(p.time_s * fs)) - LEAD
        if w > 0:
            n_max = max(n_max, w)
            last = max(last, first + w - 1)
        i = end
    return n_max, last


@njit(cache=True)
def add_pulses(track, pulses, dv, n):
    """Render the rows ``pulses[:n]`` (PULSE_DTYPE) scaled by ``dv[:n]`` [m/s] into the track
    :class:`~mjsound.synth.records.TrackState` ``track`` (:func:`render_pulse`, :func:`mix_pulse`,
    in row order; a row with a non-finite ``dv`` or one that does not render is dropped and
    counted in ``rec.dropped``; samples before ``rec.start`` are dropped).

    Returns False, having changed nothing, when the scratch is shorter than the longest
    window or the ring cannot hold the last sample: the owner grows them
    (:meth:`PulseTrack.add_trusted`) and calls again. The step kernel calls it after its
    substeps, :meth:`PulseTrack.add_trusted` from Python."""
    rec = track.rec[0]
    fs = rec.fs
    n_max, last = pulse_extent(pulses, dv, n, fs)
    if n_max > track.work.shape[0] or (last >= rec.start and last - rec.start + 1 > track.acc.shape[1]):
        return False
    start = rec.start
    dropped = 0
    lo = 2**62
    hi = -(2**62)
    i = 0
    while i < n:
        nxt, first, m = pulse_group(pulses, dv, i, n, fs)
        if m > 0:  # (copies of one pulse: one window)
            render_group(pulses, i, nxt, dv, fs, first, m, track.work, track.out, track.table)
        elif not np.isfinite(dv[i]):
            dropped += 1
        else:
            first, m = render_pulse(pulses[i], dv[i], fs, track.work, track.out, track.table)
            if m == 0:
                dropped += 1
        ch = pulses[i].channel
        i = nxt
        if m == 0 or first + m <= start:
            continue
        end = mix_pulse(track.acc, start, ch, first, track.out[:m])
        if end > start:
            lo = min(lo, max(first, start))
            hi = max(hi, end)
    rec.dropped += dropped
    if hi > lo:
        rec.pending_from = lo if rec.pending_until <= start else min(rec.pending_from, lo)
        rec.pending_until = max(rec.pending_until, hi)
    return True


@njit(cache=True)
def take_into_block(track, block):
    """Add the track's next ``block.shape[1]`` samples of every channel into ``block``
    (channels, n) float32 in place, each rounded to float32 first (as ``block +=
    take(n).astype(float32)``; a non-finite sample adds nothing), and remove them from the
    track (``rec.start`` advances by ``n``; nothing to add when no pending pulse reaches them)."""
    rec = track.rec[0]
    n0 = rec.start
    n1 = n0 + block.shape[1]
    rec.start = n1
    lo = max(n0, rec.pending_from)
    hi = min(n1, rec.pending_until)
    if hi <= lo:
        return
    acc = track.acc
    cap = acc.shape[1]
    u = lo
    while u < hi:  # (in contiguous runs of the ring: no wrap inside a run, so the loop vectorises)
        i0 = u & (cap - 1)
        n = min(hi - u, cap - i0)
        for c in range(acc.shape[0]):
            _take_run(acc[c, i0:i0 + n], block[c, u - n0:u - n0 + n])
        u += n
    rec.pending_from = hi


@njit(cache=True)
def _take_run(src, dst):
    """``dst += float32(src)`` where ``src`` is finite (else nothing), and ``src`` zeroed (no
    fastmath: the finiteness test must stay)."""
    for q in range(src.shape[0]):
        x = src[q]
        src[q] = 0.0
        dst[q] += np.float32(x) if np.abs(x) < np.inf else np.float32(0.0)


class PulseTrack:
    """Pending band-limited pulses of several output channels, mixed into rendered blocks.

    Its state is a :class:`~mjsound.synth.records.TrackState` (:attr:`state`), which the step
    kernel renders into and mixes from as well (:func:`add_pulses`, :func:`take_into_block`).

    Parameters
    ----------
    n_channels : int
        Output channels.
    sample_rate : int
        [Hz].

    Attributes
    ----------
    state : TrackState
        The ring, the scratch and the :data:`~mjsound.synth.records.TRACK` record (replaced
        when the ring or the scratch grows).
    start : int
        First sample not handed out yet by :meth:`take`.
    pending_from, pending_until : int
        The samples pending pulses reach lie in ``[pending_from, pending_until)`` (empty:
        nothing pending).
    dropped : int
        Pulses not rendered: a window over :data:`MAX_PULSE_SAMPLES`, a non-finite field or
        velocity change.
    """

    def __init__(self, n_channels: int, sample_rate: int):
        if int(n_channels) != n_channels or n_channels < 0:
            raise ValueError(f"n_channels={n_channels!r} must be a non-negative integer")
        if not (float(sample_rate) > 0 and math.isfinite(float(sample_rate))):
            raise ValueError(f"sample_rate={sample_rate!r} must be a positive number of samples per second")
        self.n_channels = int(n_channels)
        rec = np.zeros(1, TRACK)
        rec[0]["fs"] = float(sample_rate)
        self.state = TrackState(rec, np.zeros((self.n_channels, 1024)), np.zeros(256, np.complex128), np.zeros(256),
                                twiddles(256, True))
        self._rec = rec[0]
        # (compiled entry points: numba's dispatch types a record in Python)
        self._add, self._extent, self._take_into = map(EntryPoint, (add_pulses, pulse_extent, take_into_block))

    fs = property(lambda self: float(self._rec["fs"]), doc="Sample rate [Hz].")
    start = property(lambda self: int(self._rec["start"]))
    pending_from = property(lambda self: int(self._rec["pending_from"]))
    pending_until = property(lambda self: int(self._rec["pending_until"]))
    dropped = property(lambda self: int(self._rec["dropped"]))

    def reset(self, start: int = 0) -> None:
        """Forget every pending pulse; the next sample handed out is ``start``."""
        self.state.acc[:] = 0.0
        r = self._rec
        r["start"] = r["pending_from"] = r["pending_until"] = int(start)

    def _grow(self, n_max: int, last: int) -> None:
        """Scratch for windows of ``n_max`` samples and a ring holding samples ``start .. last``
        (the pending ones laid out again); a new :attr:`state` when either grows."""
        st = self.state
        work, out, table = st.work, st.out, st.table
        if n_max > len(work):
            work, out, table = np.zeros(n_max, np.complex128), np.zeros(n_max), twiddles(n_max, True)
        acc = st.acc
        cap = acc.shape[1]
        need = last - self.start + 1
        if need > cap:
            new = cap
            while new < need:
                new *= 2
            acc = np.zeros((self.n_channels, new))
            if self.pending_until > self.start:
                k = np.arange(self.start, self.pending_until)
                acc[:, k & (new - 1)] = st.acc[:, k & (cap - 1)]
        if acc is not st.acc or work is not st.work:
            self.state = TrackState(st.rec, acc, work, out, table)

    def add(self, pulses: np.ndarray, dv: np.ndarray) -> None:
        """Render ``pulses`` (PULSE_DTYPE array) scaled by ``dv`` [m/s] (one per pulse) into
        their channels. Arrival times may be anywhere at or after the current position; a
        pulse's samples before :attr:`start` are dropped."""
        pulses = np.asarray(pulses, dtype=PULSE_DTYPE).reshape(-1)
        dv = np.ascontiguousarray(np.broadcast_to(np.asarray(dv, dtype=np.float64), pulses.shape))
        if not (np.all(np.isfinite(dv)) and all(np.all(np.isfinite(pulses[f])) for f in PULSE_DTYPE.names)):
            raise ValueError("pulses and dv must be finite (times in s, velocities in m/s)")
        if np.any((pulses["channel"] < 0) | (pulses["channel"] >= self.n_channels)):
            raise ValueError(f"pulse channel out of range 0..{self.n_channels - 1}")
        if np.any(pulses["tau_s"] < 0) or np.any(pulses["d1"] < 0) or np.any(pulses["d2"] < 0):
            raise ValueError("pulse length tau_s and transfer denominators d1, d2 must be >= 0")
        self.add_trusted(pulses, dv)

    @interruptible
    def add_trusted(self, pulses: np.ndarray, dv: np.ndarray) -> None:
        """:meth:`add` without its checks (``pulses`` a PULSE_DTYPE array, ``dv`` a float64
        array of the same length; a non-finite ``dv`` drops that pulse)."""
        if not len(pulses):
            return
        pulses = np.ascontiguousarray(pulses, dtype=PULSE_DTYPE)
        dv = np.ascontiguousarray(dv, dtype=np.float64)
        if not self._add((self.state,), pulses, dv, len(pulses)):
            self._grow(*self._extent((), pulses, dv, len(pulses), self.fs))
            self._add((self.state,), pulses, dv, len(pulses))  # (fits now)

    def take_into(self, block: np.ndarray) -> None:
        """Add the next ``block.shape[1]`` samples of every channel into ``block`` (channels, n)
        float32 in place and remove them from the track, as ``block += take(n)`` does (a
        non-finite sample adds nothing): :func:`take_into_block`."""
        self._take_into((self.state,), block)

    def take(self, n: int) -> np.ndarray | None:
        """The next ``n`` samples of every channel, (channels, n), removed from the track; ``None``
        (nothing to add) when no pulse reaches them."""
        r = self._rec
        n0 = int(r["start"])
        n1 = n0 + int(n)
        r["start"] = n1
        lo, hi = max(n0, self.pending_from), min(n1, self.pending_until)
        if hi <= lo:
            return None
        acc = self.state.acc
        cap = acc.shape[1]
        block = np.zeros((self.n_channels, n1 - n0))
        a = lo & (cap - 1)
        if a + (hi - lo) <= cap:  # no wrap: slices
            block[:, lo - n0:hi - n0] = acc[:, a:a + hi - lo]
            acc[:, a:a + hi - lo] = 0.0
        else:
            k = np.arange(lo, hi) & (cap - 1)
            block[:, lo - n0:hi - n0] = acc[:, k]
            acc[:, k] = 0.0
        r["pending_from"] = hi
        return block
