"""Fitting a modal model to one impact recording: :func:`fit_recording` (method in
:mod:`mjsound.fit`)."""

from __future__ import annotations

import math
import os
import time as _time
import warnings
from typing import NamedTuple

import numpy as np

from .result import FitResult, FitWarning
from .signal import _blas_single, _correlate_valid, _esprit, _frames, _kaiser_lowpass, _ls_amplitudes
from ..user_frame import user_stacklevel

__all__ = ["fit_recording", "read_recording"]

#: Shortest usable recording / analysed decay [s].
MIN_DURATION_S = 0.02
#: Envelope frame length [s] (onset, end of decay, second-impact detection).
FRAME_S = 0.0025
#: An impact must rise this far above the noise floor [dB].
MIN_PEAK_DB = 15.0
#: A later frame this far above every frame of the previous 20 ms is a new impact [dB].
SECOND_ONSET_DB = 6.0
#: Largest number of Hankel rows per band (bounds the SVD cost).
MAX_ROWS = 192
#: Fewer quantisation steps than this under the peak: a plateau there is quantisation, not clipping.
QUANT_LEVELS = 256
#: Largest number of decimated samples used per band.
MAX_BAND_SAMPLES = 4096


# ====================================================================== input
def read_recording(path):
    """``(samples (n, channels) float64, sample_rate)`` of an audio file (soundfile)."""
    import soundfile as sf

    try:
        data, fs = sf.read(os.fspath(path), dtype="float64", always_2d=True)
    except Exception as exc:  # soundfile.LibsndfileError, RuntimeError, OSError
        raise ValueError(f"{path}: cannot read audio ({type(exc).__name__}: {exc}); give a WAV/FLAC/OGG file") from exc
    return data, int(fs)


def _to_mono(audio, channel):
    """1-D float64 signal and a description. 2-D input is (samples, channels) as soundfile
    reads it, or (channels, samples) when the first axis is short (<= 16) and the second long
    (the synthesizer's layout). ``channel=None`` mixes (mean), an int picks one."""
    try:
        x = np.asarray(audio, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("audio must be a numeric array (samples,) or (samples, channels), or a file path") from None
    if x.ndim == 1:
        return x, "mono"
    if x.ndim != 2:
        raise ValueError(f"audio must be 1-D or 2-D (samples, channels), got shape {x.shape}")
    if x.shape[0] <= 16 and x.shape[1] > x.shape[0]:
        x = x.T
    nch = x.shape[1]
    if nch == 1:
        return x[:, 0], "mono"
    if channel is None or channel == "mix":
        return x.mean(axis=1), f"mix of {nch}"
    c = int(channel)
    if not -nch <= c < nch:
        raise ValueError(f"channel={channel!r} is out of range for {nch} channels (0..{nch - 1}, or None to mix)")
    return x[:, c], f"channel {c % nch} of {nch}"


def _clipped_samples(x, peak):
    """Indices of the samples on clipping plateaus of ``x`` (1-D), ascending.

    A plateau is a run of consecutive samples at the extreme level ``peak`` (within 1e-6):
    at least 3 samples, or 2 at the digital rail of float audio (``0.999 <= peak <= 1``). A
    single loud sample repeated (identical strikes) is not a plateau. A plateau is only
    quantisation, not clipping, when the loudest part of the signal uses fewer than
    ``QUANT_LEVELS`` quantisation steps (a quiet strike in a 16-bit file: -60 dBFS is 33 steps)
    and is not at the rail.
    """
    at = np.abs(x) >= peak * (1 - 1e-6)
    at_rail = 0.999 <= peak <= 1.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], at.astype(np.int8), [0]])))
    starts, ends = edges[0::2], edges[1::2]
    long = (ends - starts) >= (2 if at_rail else 3)
    if not long.any():
        return np.zeros(0, np.int64)
    if not at_rail:
        top = np.unique(np.abs(x[np.abs(x) >= 0.5 * peak]))
        step = float(np.min(np.diff(top))) if len(top) > 1 else peak
        if peak / step < QUANT_LEVELS:
            return np.zeros(0, np.int64)
    return np.concatenate([np.arange(a, b) for a, b in zip(starts[long], ends[long])])


def _warn(msgs, text):
    msgs.append(text)
    warnings.warn(text, FitWarning, stacklevel=user_stacklevel())  # the caller of fit_recording


def fit_recording(audio, sample_rate: int | None = None, n_modes: int | None = None, *, channel=None,
                  f_min: float = 20.0, f_max: float | None = None, min_snr_db: float = 15.0,
                  max_seconds: float = 4.0, skip_s: float = 0.002, band_hz: float = 1000.0,
                  max_decay_per_s: float = 2000.0) -> FitResult:
    """Fit a modal model ``{f, d, A, phi}`` to an impact recording (band-split ESPRIT).

    Parameters
    ----------
    audio : array_like or path
        Samples (1-D, (samples, channels) or (channels, samples)), or an audio file path.
    sample_rate : int
        Samples per second (read from the file for a path).
    n_modes : int, optional
        Keep at most this many modes, the most energetic (default: every mode above
        ``min_snr_db``).
    channel : None or int
        ``None`` mixes the channels (their mean: every channel hears the same modes, with its
        own amplitudes and phases); an int fits that channel only.
    f_min, f_max : float
        Frequency range [Hz]; ``f_max`` defaults to 0.45 fs (what the synthesizer plays).
    min_snr_db : float
        A mode must have this matched-filter SNR (its energy over the noise density) [dB].
    max_seconds : float
        Longest stretch of the decay analysed [s].
    skip_s : float
        Skip this long after the onset before fitting (the contact transient, which is not
        modal) [s].
    band_hz : float
        Band width B of the filter bank [Hz] (decimated rate about 2 B).
    max_decay_per_s : float
        Poles decaying faster than this are treated as transients, not modes [1/s].

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        Silent or noise-only, too short, non-finite input, or a bad parameter.
    """
    with _blas_single():
        return _fit_core(audio, sample_rate, n_modes, channel, f_min, f_max, min_snr_db, max_seconds, skip_s,
                         band_hz, max_decay_per_s)


class _Impact(NamedTuple):
    """Where the first impact of a recording is and what of it the fit analyses (sample
    indices into the mean-free mono recording)."""

    n_on: int  # the onset
    n_a: int  # the analysed span's start (after the contact transient and any clipping)
    n_e: int  # its end (the end of the decay, a second impact, or max_seconds)
    floor: float  # noise variance per sample
    snr_db: float  # the loudest frame over the noise floor [dB]


def _fit_core(audio, sample_rate, n_modes, channel, f_min, f_max, min_snr_db, max_seconds, skip_s, band_hz,
              max_decay_per_s):
    """:func:`fit_recording`'s stages: checked input, the impact and its analysed span, the
    band-split ESPRIT poles, the full-rate amplitudes pruned by SNR, the onset refined from the
    phases."""
    t_start = _time.perf_counter()
    x, fs, chdesc, f_max, source = _checked_input(audio, sample_rate, n_modes, channel, f_min, f_max)
    msgs: list[str] = []
    imp = _find_impact(x, fs, f_min, f_max, skip_s, max_seconds, msgs)
    x = x - np.mean(x)
    seg = x[imp.n_a:imp.n_e]
    if n_modes is not None and len(seg) < 8 * n_modes:
        raise ValueError(f"recording too short for {n_modes} modes: {len(seg)} samples of decay; need about "
                         f"{8 * n_modes} (ask for fewer modes or record the whole ring-out)")
    tau_a = (imp.n_a - imp.n_on) / fs  # time of seg[0] after the onset
    lam, noise_k = _band_poles(seg, fs, f_min, f_max, band_hz, min_snr_db, max_decay_per_s)
    lam, b, res, n_significant = _significant_modes(seg, fs, tau_a, lam, noise_k, n_modes, min_snr_db)
    if n_modes is not None and n_significant < n_modes:
        _warn(msgs, f"{n_modes} modes asked for, but the recording supports only {n_significant} above "
                    f"min_snr_db={min_snr_db:g} dB; the fit returns those and invents none. Record longer, closer "
                    "or with less noise for more")
    if len(lam) == 0:
        _warn(msgs, "no mode rose above the noise: the fit is empty. Record closer to the object, strike harder "
                    "or lower min_snr_db")
    sig_e = float(np.sum(seg**2))
    residual_db = 10 * math.log10(max(float(np.sum(res**2)), 1e-300) / max(sig_e, 1e-300))
    b, t0, impulse_like = _refine_onset(lam, b, fs, tau_a, imp.n_on / fs, msgs)

    d = -lam.real
    fd = lam.imag / (2 * np.pi)
    f0 = np.sqrt((2 * np.pi * fd) ** 2 + d**2) / (2 * np.pi)
    order = np.argsort(f0)
    return FitResult(
        frequencies_hz=f0[order],
        decay_per_s=d[order],
        amplitudes=np.abs(b)[order],
        phases_rad=np.angle(b)[order],
        sample_rate=fs,
        onset_s=float(t0),
        residual_db=float(residual_db),
        snr_db=float(imp.snr_db),
        noise_rms=float(math.sqrt(imp.floor)),
        analysis_start_s=imp.n_a / fs,
        analysis_end_s=imp.n_e / fs,
        channels=chdesc,
        impulse_like=impulse_like,
        warnings=msgs,
        modes_supported=n_significant,
        seconds=_time.perf_counter() - t_start,
        source=source,
    )


def _checked_input(audio, sample_rate, n_modes, channel, f_min, f_max):
    """The recording as a mono float array with its rate, checked: ``(x, fs, channels'
    description, f_max, source)``. Raises ValueError naming the bad input and the fix."""
    source = "array"
    if isinstance(audio, (str, os.PathLike)):
        source = os.fspath(audio)
        audio, fs_file = read_recording(audio)
        if sample_rate is not None and int(sample_rate) != fs_file:
            raise ValueError(f"sample_rate={sample_rate} but {source} is at {fs_file} Hz; leave sample_rate out for files")
        sample_rate = fs_file
    if sample_rate is None:
        raise ValueError("sample_rate is required for an array recording (samples per second, e.g. 48000)")
    try:
        fs = float(sample_rate)
    except (TypeError, ValueError):
        fs = float("nan")
    if not (math.isfinite(fs) and fs >= 1000 and fs == int(fs)):
        raise ValueError(f"sample_rate={sample_rate!r} is invalid: give an integer rate in Hz (>= 1000), e.g. 48000")
    fs = int(fs)
    x, chdesc = _to_mono(audio, channel)
    if not np.all(np.isfinite(x)):
        raise ValueError("recording contains NaN or Inf samples; fix or re-export the file")
    if n_modes is not None and (int(n_modes) != n_modes or n_modes < 1):
        raise ValueError(f"n_modes={n_modes!r} must be a positive integer (or None for all significant modes)")
    f_max = 0.45 * fs if f_max is None else float(f_max)
    if not (0 <= f_min < f_max <= 0.5 * fs):
        raise ValueError(f"need 0 <= f_min < f_max <= fs/2, got f_min={f_min}, f_max={f_max}, fs={fs}")
    n = len(x)
    if n / fs < MIN_DURATION_S:
        raise ValueError(
            f"recording too short: {n / fs * 1000:.1f} ms ({n} samples at {fs} Hz); a fit needs at least "
            f"{MIN_DURATION_S * 1000:.0f} ms of decay: record the whole ring-out"
        )
    if float(np.max(np.abs(x))) == 0.0:
        raise ValueError("recording is silent (all samples are zero): check the input channel / microphone and record the impact again")
    return x, fs, chdesc, f_max, source


def _find_impact(x, fs, f_min, f_max, skip_s, max_seconds, msgs) -> _Impact:
    """The first impact of the mono recording ``x``: noise floor (the lower of the quietest
    frames' level and the band's spectral median), onset, a second impact (warned), clipping
    (warned, skipped) and the analysed span from ``skip_s`` after the onset to the end of the
    decay. Raises ValueError when there is no impact or too little decay."""
    n = len(x)
    peak = float(np.max(np.abs(x)))
    # ---------------------------------------------------------------- clipping
    clip_idx = _clipped_samples(x, peak)
    n_clip = len(clip_idx)
    clip_end = int(clip_idx[-1]) if n_clip else -1
    x = x - np.mean(x)

    # ---------------------------------------------------------------- envelope, noise floor
    Lf = max(int(round(FRAME_S * fs)), 8)
    e = _frames(x, Lf)
    nfr = len(e)
    X = np.fft.rfft(x)
    fbin = np.fft.rfftfreq(n, 1 / fs)
    inband = (fbin >= max(f_min, 1.0)) & (fbin <= f_max)
    P = np.abs(X) ** 2 / n
    # the spectral median is the noise variance of the analysed band (white-noise equivalent)
    spec_var = float(np.median(P[inband]) / math.log(2))
    srt = np.sort(e)
    frame_floor = float(np.mean(srt[: max(1, nfr // 5)]))
    floor = max(min(frame_floor, spec_var), 1e-300)
    kp = int(np.argmax(e))
    snr_db = 10 * math.log10(max(e[kp], 1e-300) / floor)
    if snr_db < MIN_PEAK_DB:
        raise ValueError(
            f"no impact found: the loudest {FRAME_S * 1000:.1f} ms is only {snr_db:.1f} dB above the noise floor "
            f"(need {MIN_PEAK_DB:.0f} dB). The recording is silent or noise; check the input level and "
            "record the strike closer to the object"
        )
    # ---------------------------------------------------------------- onset
    thr_on = max(floor * 10.0, e[kp] * 1e-4)
    k_on = int(np.flatnonzero(e > thr_on)[0])
    s0 = max(0, (k_on - 1) * Lf)
    seg_on = np.abs(x[s0: (k_on + 1) * Lf])
    amp_thr = max(5.0 * math.sqrt(floor), 0.05 * float(seg_on.max()))
    n_on = s0 + int(np.flatnonzero(seg_on > amp_thr)[0])
    # first event's peak: loudest frame within 20 ms of the onset
    k_pk = k_on + int(np.argmax(e[k_on: k_on + 9]))
    # ---------------------------------------------------------------- second impact
    n_end_event = n
    W = 8
    for k in range(max(k_pk + W, k_on + W + 1), nfr):
        if e[k] > floor * 10 ** (MIN_PEAK_DB / 10) and e[k] > 10 ** (SECOND_ONSET_DB / 10) * e[k - W: k].max():
            n_end_event = (k - 1) * Lf
            _warn(msgs, f"recording has more than one impact: a second onset at {k * Lf / fs:.3f} s "
                        f"({(k * Lf - n_on) / fs * 1000:.0f} ms after the first); only the first impact is fitted "
                        "(up to the second). Trim the recording to one strike, or fit each strike separately")
            break
    # ---------------------------------------------------------------- analysed span
    n_a = max(n_on + int(round(skip_s * fs)), clip_end + 1)
    # end of decay: last frame of the first event above the noise floor (+6 dB)
    kmax = min(n_end_event // Lf, nfr)
    above = np.flatnonzero(e[:kmax] > 4.0 * floor)
    n_e = min(n_end_event, (int(above[-1]) + 2) * Lf if len(above) else n, n)
    n_e = min(n_e, n_a + int(round(max_seconds * fs)))
    if clip_end >= 0 and (n_e - n_a) < MIN_DURATION_S * fs:
        raise ValueError(
            f"recording is clipped for too long: after the last clipped sample ({clip_end / fs * 1000:.0f} ms) only "
            f"{max(n_e - n_a, 0) / fs * 1000:.1f} ms of decay remain. Record at a lower gain"
        )
    if clip_end >= 0:
        _warn(msgs, f"recording is clipped: {n_clip} samples at +/-{peak:.4g} (full scale); the fit skips "
                    f"everything up to the last clipped sample ({clip_end / fs * 1000:.1f} ms) and the amplitudes "
                    "are extrapolated back. Record at a lower gain for a faithful attack")
    if n_e - n_a < MIN_DURATION_S * fs:
        raise ValueError(
            f"recording too short: only {max(n_e - n_a, 0) / fs * 1000:.1f} ms of decay after the onset at "
            f"{n_on / fs:.3f} s (need {MIN_DURATION_S * 1000:.0f} ms). Record the whole ring-out"
            + (" and leave time between strikes" if n_end_event < n else "")
        )
    return _Impact(n_on, n_a, n_e, floor, snr_db)


def _band_poles(seg, fs, f_min, f_max, band_hz, min_snr_db, max_decay_per_s):
    """The poles ``lam`` (complex, [1/s]) of the significant modes of the decay ``seg``, and
    each one's band noise density: the band ``[f_min, f_max]`` cut into bands of ``band_hz``,
    each shifted to baseband, low-passed, decimated and fitted by ESPRIT (:func:`.signal._esprit`);
    a pole is kept when it lies in its band's centre, decays (slower than ``max_decay_per_s``,
    underdamped) and carries ``min_snr_db`` over the band's noise."""
    N = len(seg)
    Xs = np.fft.rfft(seg)
    Ps = np.abs(Xs) ** 2 / N
    fb = np.fft.rfftfreq(N, 1 / fs)
    B = float(band_hz)
    if not B > 0:
        raise ValueError("band_hz must be positive")
    B = min(B, max(f_max - f_min, 1.0))
    D = max(1, int(fs // (2 * B)))
    fs_b = fs / D
    h = _kaiser_lowpass(fs, 0.75 * B, 1.5 * B)
    m_full = np.arange(N)
    sig_min = 3e-8 * float(np.max(np.abs(seg)))  # float32 quantisation: no noise floor is lower
    cand_lam, cand_noise = [], []
    centers = np.arange(f_min + B / 2, f_max + B / 2, B)
    for fc in centers:
        lo, hi = fc - B / 2, min(fc + B / 2, f_max)
        sel = (fb >= lo) & (fb < hi)
        if not sel.any():
            continue
        noise_b = float(np.median(Ps[sel]) / math.log(2))  # per-sample variance density here
        if Ps[sel].max() < noise_b * 10 ** (min_snr_db / 10):
            continue
        hh = h
        if len(h) > N // 2:  # a short recording: a shorter filter with a wider transition band
            hh = _kaiser_lowpass(fs, 0.75 * B, 1.5 * B, numtaps=max(N // 2, 9))
        xd = seg * np.exp(-2j * np.pi * fc / fs * m_full)
        yb = _correlate_valid(xd, hh)[::D]
        sig2 = noise_b * float(np.sum(hh**2))
        # keep the part above the band noise
        Nb = len(yb)
        w = max(8, Nb // 50)
        mov = np.convolve(np.abs(yb) ** 2, np.ones(w) / w, mode="same")
        ab = np.flatnonzero(mov > 3.0 * sig2)
        Nu = (int(ab[-1]) + w) if len(ab) else Nb
        Nu = int(np.clip(Nu, min(Nb, 64), min(Nb, MAX_BAND_SAMPLES)))
        yb = yb[:Nu]
        if Nu < 8:
            continue
        L = min(Nu // 3, MAX_ROWS)
        h2 = float(np.sum(hh**2))
        z, sig2_e = _esprit(yb, L, max_order=min(40, L - 2), min_sig=sig_min * math.sqrt(h2))
        sig2 = min(sig2, sig2_e)  # the band's own noise level (see _esprit)
        noise_b = sig2 / h2
        if len(z) == 0:
            continue
        z = z[np.abs(z) > 1e-12]
        lam = np.log(z) * fs_b + 2j * np.pi * fc
        # band-level amplitudes with all poles, then keep the significant centre ones
        Vm = np.exp(np.outer(np.arange(Nu) / fs_b, lam - 2j * np.pi * fc))
        alpha, *_ = np.linalg.lstsq(Vm, yb, rcond=None)
        energy = np.abs(alpha) ** 2 * np.sum(np.abs(Vm) ** 2, axis=0)
        f_l = lam.imag / (2 * np.pi)
        d_l = -lam.real
        keep = (f_l >= lo) & (f_l < hi) & (f_l >= f_min) & (d_l > 0) & (d_l < max_decay_per_s) \
            & (d_l < lam.imag) & (energy > sig2 * 10 ** (min_snr_db / 10))
        cand_lam.extend(lam[keep].tolist())
        cand_noise.extend([noise_b] * int(keep.sum()))
    lam = np.array(cand_lam, complex)
    noise_k = np.array(cand_noise, float)
    return np.array(cand_lam, complex), np.array(cand_noise, float)


def _significant_modes(seg, fs, tau_a, lam, noise_k, n_modes, min_snr_db):
    """Full-rate amplitudes of the poles ``lam`` (least squares over ``seg``, which starts
    ``tau_a`` after the onset), pruned up to three times to the modes whose energy over the
    span is ``min_snr_db`` above their band's noise (at most ``n_modes``, the most energetic):
    ``(lam, amplitudes, residual, modes significant before the n_modes limit)``."""
    N = len(seg)
    b, res = _ls_amplitudes(seg, fs, tau_a, lam)
    beyond_limit = 0  # significant modes dropped by the n_modes limit
    for _ in range(3):
        if len(lam) == 0:
            break
        tau = tau_a + np.arange(N) / fs
        # energy of each mode over the analysed span, per unit noise variance
        d = -lam.real
        span = np.where(d > 0, (np.exp(-2 * d * tau[0]) - np.exp(-2 * d * tau[-1])) / (2 * np.maximum(d, 1e-12)),
                        tau[-1] - tau[0]) * fs
        en = np.abs(b) ** 2 / 2 * span
        ok = en > noise_k * 10 ** (min_snr_db / 10)
        if n_modes is not None and ok.sum() > n_modes:
            beyond_limit += int(ok.sum()) - int(n_modes)
            ranks = np.argsort(-np.where(ok, en, -1.0))
            ok = np.zeros(len(lam), bool)
            ok[ranks[: int(n_modes)]] = True
        if ok.all():
            break
        lam, noise_k = lam[ok], noise_k[ok]
        b, res = _ls_amplitudes(seg, fs, tau_a, lam)
    return lam, b, res, len(lam) + beyond_limit


def _refine_onset(lam, b, fs, tau_a, t0, msgs):
    """The onset refined from the modes' phases: the shift (within -1 .. +0.5 ms) that makes
    the phases those of one impulse, applied to the amplitudes ``b`` when they fit one
    (mismatch under 0.05; warned when far from one). Returns ``(b, onset [s], impulse-like)``."""
    wd = lam.imag
    impulse_like = False
    if len(lam):
        wgt = np.abs(b) ** 2
        ph = np.angle(b)
        deltas = np.arange(-1.0e-3, 0.5e-3 + 1e-12, 1.0 / (fs * 32))
        deltas = deltas[deltas <= tau_a]
        cost = (wgt[None, :] * np.sin(ph[None, :] + wd[None, :] * deltas[:, None]) ** 2).sum(1) / wgt.sum()
        j = int(np.argmin(cost))
        # polish on a finer grid around the minimum
        fine = deltas[j] + np.linspace(-1.0 / (fs * 32), 1.0 / (fs * 32), 65)
        cf = (wgt[None, :] * np.sin(ph[None, :] + wd[None, :] * fine[:, None]) ** 2).sum(1) / wgt.sum()
        jf = int(np.argmin(cf))
        if cf[jf] < 0.05:
            impulse_like = True
            delta = float(fine[jf])
            b = b * np.exp(lam * delta)
            t0 = t0 + delta
        elif cost[np.argmin(np.abs(deltas))] >= 0.05:
            _warn(msgs, f"the phases are not those of a single short impulse (mismatch {cf[jf]:.2f}); the "
                        "modal model replays the amplitudes with impulse phases. A mallet or a long contact "
                        "does this; it is harmless for synthesis")
    return b, t0, impulse_like
