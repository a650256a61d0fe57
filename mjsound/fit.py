"""Modal models from recordings, example-guided materials, and sound design with force signals.

Three tools for people who have a real object and a recording of it being struck (seeds 003
and 004: "hand and hear" modal models, analysis / resynthesis, Ren, Yeh and Lin 2013,
*Example-guided physically based modal sound synthesis*):

:func:`fit_recording`
    Estimate a modal resonance model ``{f, d, A}`` from one impact recording
    (``mjsound fit RECORDING.wav``). The result converts to a :class:`~mjsound.ModalModel`
    (:meth:`FitResult.to_model`) that plays in the :class:`~mjsound.synth.synthesizer.Synthesizer`
    like an analysed one and can stand in for an analysed model in a scene.
:func:`fit_material`
    Fit Rayleigh damping (alpha, beta) and a stiffness scale of a material so that the
    analysed model of a mesh matches a recording of that object; the fitted
    :class:`~mjsound.Material` is reusable on other meshes.
:func:`render_excitation`
    Drive a model with a user force signal (a recorded scrape, a mallet) through
    :meth:`Synthesizer.excite` and return the audio.

The signal model
----------------
After the onset time ``t0`` the recording is modelled as::

    y(t) = sum_i Im(b_i e^{lambda_i (t - t0)}) = sum_i A_i e^{-d_i (t - t0)} sin(w_i (t - t0) + phi_i)

with ``lambda_i = -d_i + j w_i`` (``w_i`` the *damped* angular frequency), amplitude
``A_i = |b_i|`` (in the recording's units: pascals for a calibrated recording, else full
scale) and phase ``phi_i = arg b_i``. An ideal impulse at ``t0`` gives ``phi_i`` = 0 or pi,
and ``t0`` is refined (to a fraction of a sample) to the time that makes the phases most
impulse-like.

Method (high-resolution, band-split ESPRIT)
-------------------------------------------
1. Mix the channels (or pick one), check the input (silence, clipping, length, a second
   impact), find the onset from a 2.5 ms energy envelope and the end of the decay (where
   the envelope reaches the noise floor).
2. Split the decay into overlapping bands ``[f_c - B/2, f_c + B/2)``: heterodyne by
   ``f_c``, low-pass with an *anti-causal* Kaiser FIR (output sample n depends on samples
   n .. n + L only, so a sum of damped exponentials that starts at the analysis start stays
   exactly a sum of the same exponentials, with no filter transient lost) and decimate to
   about ``2 B``. The Hankel matrices stay small (at most ``MAX_ROWS`` rows).
3. ESPRIT in each band: SVD of the Hankel matrix, model order = number of singular values
   above the band's noise level (``sigma (sqrt(L) + sqrt(C))``, the largest singular value of
   an L x C noise matrix; the noise density is the median of the periodogram in the band),
   poles from the shift invariance of the signal subspace. Poles outside the band's centre,
   growing or too damped are dropped, and so are poles whose matched-filter SNR in the band
   is below ``min_snr_db``.
4. Complex amplitudes by linear least squares on the full-rate signal; modes below
   ``min_snr_db`` are pruned and the ``n_modes`` most energetic are kept. The residual energy
   the model leaves, relative to the signal energy over the analysed span, is
   ``residual_db`` (about minus the SNR for a clean modal sound in white noise).

Bad input raises ``ValueError`` (silent / noise only, too short, non-finite) or warns with
:class:`FitWarning` (clipped: the clipped start is skipped; a second impact: the recording is
cut before it), always naming the problem and the fix.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time as _time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .materials import Material, parse_material
from .modal.model import ModalModel

__all__ = [
    "FitResult",
    "FitWarning",
    "MaterialFit",
    "fit_recording",
    "fit_material",
    "render_excitation",
    "read_recording",
    "register_cli",
]

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
#: Largest number of decimated samples used per band.
MAX_BAND_SAMPLES = 4096


class FitWarning(UserWarning):
    """A recording could be fitted, but something about it needs attention."""


# ====================================================================== result
@dataclass
class FitResult:
    """Modal parameters fitted to an impact recording.

    Attributes
    ----------
    frequencies_hz : (n,) undamped natural frequencies ``sqrt(w^2 + d^2) / 2 pi`` [Hz],
        ascending (the :class:`ModalModel` convention; :attr:`damped_frequencies_hz` is what
        is heard and measured; they differ by d^2/(2 w^2), a few ppm).
    decay_per_s : (n,) decay rates d [1/s] (amplitude ~ e^{-d t}; T60 = 6.91 / d).
    amplitudes : (n,) |b_i| in the recording's units at ``onset_s``.
    phases_rad : (n,) arg b_i (0 or pi for an ideal impulse at ``onset_s``).
    sample_rate : int
    onset_s : float, time of the (equivalent ideal) impulse in the recording [s].
    residual_db : float, 10 log10(residual energy / signal energy) over the analysed span.
    snr_db : float, loudest 2.5 ms frame over the noise floor [dB].
    noise_rms : float, noise floor estimate (recording units).
    analysis_start_s, analysis_end_s : float, analysed span of the recording [s].
    channels : str, how channels were combined ("mono", "mix of 2", "channel 1 of 2").
    impulse_like : bool, whether the phases are those of an impulse at ``onset_s``.
    warnings : list of str, problems found (also issued as :class:`FitWarning`).
    seconds : float, fitting wall time.
    """

    frequencies_hz: np.ndarray
    decay_per_s: np.ndarray
    amplitudes: np.ndarray
    phases_rad: np.ndarray
    sample_rate: int
    onset_s: float = 0.0
    residual_db: float = float("nan")
    snr_db: float = float("nan")
    noise_rms: float = float("nan")
    analysis_start_s: float = 0.0
    analysis_end_s: float = 0.0
    channels: str = "mono"
    impulse_like: bool = True
    warnings: list = field(default_factory=list)
    seconds: float = 0.0
    source: str = "array"

    @property
    def n_modes(self) -> int:
        return len(self.frequencies_hz)

    @property
    def damped_frequencies_hz(self) -> np.ndarray:
        w2 = (2 * np.pi * self.frequencies_hz) ** 2 - self.decay_per_s**2
        return np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi)

    @property
    def gains(self) -> np.ndarray:
        """Signed amplitudes ``A_i sign(cos phi_i)``: the impulse-response amplitudes (of
        ``sin``) that :meth:`to_model` plays."""
        return self.amplitudes * np.where(np.cos(self.phases_rad) >= 0, 1.0, -1.0)

    @property
    def complex_amplitudes(self) -> np.ndarray:
        return self.amplitudes * np.exp(1j * self.phases_rad)

    def energies(self) -> np.ndarray:
        """Energy of each mode's decay, sum over t >= onset of y_i(t)^2 [units^2 s]
        (A^2 / (4 d) for d << w)."""
        return self.amplitudes**2 / (4.0 * np.maximum(self.decay_per_s, 1e-9))

    def synthesize(self, n_samples: int, sample_rate: int | None = None, onset_s: float | None = None,
                   impulse_like: bool = False) -> np.ndarray:
        """The fitted model as a signal: samples ``n / fs`` for n < ``n_samples``, zero before
        the onset. ``impulse_like=True`` uses the signed :attr:`gains` (what the
        synthesizer plays) instead of the fitted phases."""
        fs = self.sample_rate if sample_rate is None else int(sample_rate)
        t0 = self.onset_s if onset_s is None else float(onset_s)
        tau = np.arange(int(n_samples)) / fs - t0
        y = np.zeros(int(n_samples))
        on = tau >= 0
        b = self.gains.astype(complex) if impulse_like else self.complex_amplitudes
        lam = -self.decay_per_s + 2j * np.pi * self.damped_frequencies_hz
        for bi, li in zip(b, lam):
            y[on] += (bi * np.exp(li * tau[on])).imag
        return y

    def to_model(self, material=None, mass_kg: float | None = None, size_m: float | None = None,
                 impulse_ns: float = 1.0, distance_m: float = 1.0) -> ModalModel:
        """A one-point :class:`ModalModel` (no sound map) that replays the recording.

        The model has one surface point at the origin with normal +z and mode shapes
        ``phi_i = (0, 0, 1)``; ``radiation_i = gain_i w_i distance_m / impulse_ns``. With the
        synthesizer's ``c_i = (phi_i . J) / w_i S_i`` and ``p = radiation_i q_i / r``, an
        impulse of ``impulse_ns`` N s along +z, a short pulse (``S ~ 1``, e.g. ``pulse_s=0``)
        and a microphone ``distance_m`` from the object give back
        ``sum_i gain_i e^{-d_i t} sin(w_i t)``: the recording's amplitudes (same units,
        read as pascals). Other impulses scale it linearly; only the impulse's z component
        (object frame) excites it.

        Parameters
        ----------
        material : Material or spec, optional
            Stored with the model (used for Hertz contact times); default an aluminium-like
            placeholder named "fitted" carrying the Rayleigh alpha, beta fitted to the decays.
        mass_kg, size_m : float, optional
            The object's mass [kg] and size [m] (Hertz contact time in scenes; unknown: NaN /
            0, which gives ideal impulses against immovable bodies).
        impulse_ns, distance_m : float
            Reference impulse [N s] and microphone distance [m] the amplitudes stand for.

        Using it in a scene
        -------------------
        ``SoundScene.from_model(xml, models={"cup": fit.to_model(mass_kg=0.2)})`` uses it for
        geom ``cup`` in place of an analysed model (orient the geom so that its z axis is
        the struck direction); ``Synthesizer.add_object("cup", model)`` plays it directly.
        """
        if not (impulse_ns > 0 and distance_m > 0):
            raise ValueError("impulse_ns and distance_m must be positive")
        wd = 2 * np.pi * self.damped_frequencies_hz
        order = np.argsort(self.frequencies_hz, kind="stable")
        n = self.n_modes
        shapes = np.zeros((1, 3, n))
        shapes[0, 2, :] = 1.0
        if material is None:
            a, b = rayleigh_fit(self.frequencies_hz, self.decay_per_s)
            material = Material(E=70e9, nu=0.33, rho=2700, alpha=a, beta=b, name="fitted")
        else:
            material = parse_material(material)
        info = {
            "fitted": True,
            "source": self.source,
            "sample_rate": int(self.sample_rate),
            "onset_s": float(self.onset_s),
            "residual_db": float(self.residual_db),
            "snr_db": float(self.snr_db),
            "reference_impulse_ns": float(impulse_ns),
            "reference_distance_m": float(distance_m),
            "amplitudes": self.amplitudes[order].tolist(),
            "phases_rad": self.phases_rad[order].tolist(),
            "impulse_like": bool(self.impulse_like),
            "channels": self.channels,
            "size_m": float(size_m) if size_m else 0.0,
            "f_max": float(self.frequencies_hz.max()) if n else 0.0,
            "n_rigid": 0,
            "n_overdamped": 0,
        }
        return ModalModel(
            frequencies_hz=self.frequencies_hz[order],
            decay_per_s=self.decay_per_s[order],
            points=np.zeros((1, 3)),
            normals=np.array([[0.0, 0.0, 1.0]]),
            shapes=shapes,
            radiation=(self.gains * wd * distance_m / impulse_ns)[order],
            material=material,
            method="fitted",
            mass_kg=float("nan") if mass_kg is None else float(mass_kg),
            info=info,
        )

    def summary(self) -> dict:
        """JSON-able dict (the ``mjsound fit --json`` contract)."""
        return {
            "frequencies_hz": self.frequencies_hz.tolist(),
            "damped_frequencies_hz": self.damped_frequencies_hz.tolist(),
            "decay_per_s": self.decay_per_s.tolist(),
            "amplitudes": self.amplitudes.tolist(),
            "phases_rad": self.phases_rad.tolist(),
            "gains": self.gains.tolist(),
            "n_modes": self.n_modes,
            "residual_db": _num(self.residual_db),
            "snr_db": _num(self.snr_db),
            "noise_rms": _num(self.noise_rms),
            "onset_s": float(self.onset_s),
            "analysis_start_s": float(self.analysis_start_s),
            "analysis_end_s": float(self.analysis_end_s),
            "sample_rate": int(self.sample_rate),
            "channels": self.channels,
            "impulse_like": bool(self.impulse_like),
            "warnings": list(self.warnings),
            "seconds": float(self.seconds),
            "source": self.source,
        }


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


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


def _frames(x, L):
    n = len(x) // L
    e = np.mean(x[: n * L].reshape(n, L) ** 2, axis=1) if n else np.zeros(0)
    return e


def _warn(msgs, text):
    msgs.append(text)
    warnings.warn(text, FitWarning, stacklevel=4)  # the caller of fit_recording


# ====================================================================== core
def _esprit(y, L, max_order, min_sig=0.0):
    """Poles z of a complex signal y by ESPRIT with L Hankel rows.

    The signal subspace comes from the eigenvectors of the L x L Gram matrix H H^H (much
    cheaper than an SVD of H and as accurate here). The model order is the number of singular
    values above the largest one that noise alone would give, ``sigma (sqrt(L) + sqrt(C))``
    for an L x C noise matrix, with the noise level sigma estimated from the lower half of
    the singular values themselves (they are noise when there are fewer than L/2 modes, and
    self-calibrate to the band's own noise, which a periodogram median overestimates when
    resonance skirts fill the band). Returns ``(z, sigma^2)``."""
    N = len(y)
    C = N - L + 1
    idx = np.arange(L)[:, None] + np.arange(C)[None, :]
    H = y[idx]
    G = H @ H.conj().T
    try:
        ev, U = np.linalg.eigh(G)
    except np.linalg.LinAlgError:
        return np.zeros(0, complex), 0.0
    ev, U = ev[::-1], U[:, ::-1]
    s = np.sqrt(np.maximum(ev, 0.0))
    # median singular value of the noise part ~ sigma sqrt(C) (Marchenko-Pastur, C >> L)
    sig = max(float(np.median(s[L // 2:])) / math.sqrt(C), min_sig)
    thr = 1.1 * sig * (math.sqrt(L) + math.sqrt(C))
    K = int(np.sum(s > thr))
    K = min(K, max_order, L - 2)
    if K <= 0:
        return np.zeros(0, complex), sig**2
    Us = U[:, :K]
    Phi, *_ = np.linalg.lstsq(Us[:-1], Us[1:], rcond=None)
    return np.linalg.eigvals(Phi), sig**2


def _kaiser_lowpass(fs, pass_hz, stop_hz, atten_db=80.0, numtaps=None):
    """Linear-phase Kaiser-window low-pass FIR (unit DC gain), passband edge ``pass_hz``,
    stopband edge ``stop_hz`` with ``atten_db`` attenuation (Kaiser's design formulas; numpy
    only, so that scipy.signal need not be imported)."""
    width = 2 * np.pi * (stop_hz - pass_hz) / fs
    if numtaps is None:
        numtaps = int(math.ceil((atten_db - 7.95) / (2.285 * width))) + 1
    else:  # given length: the attenuation it affords
        atten_db = min(atten_db, 2.285 * width * (int(numtaps) - 1) + 7.95)
    numtaps = int(numtaps) | 1
    if atten_db > 50:
        beta = 0.1102 * (atten_db - 8.7)
    elif atten_db > 21:
        beta = 0.5842 * (atten_db - 21) ** 0.4 + 0.07886 * (atten_db - 21)
    else:
        beta = 0.0
    fc = (pass_hz + stop_hz) / 2 / fs
    m = np.arange(numtaps) - (numtaps - 1) / 2
    h = 2 * fc * np.sinc(2 * fc * m) * np.kaiser(numtaps, beta)
    return h / h.sum()


def _correlate_valid(x, h):
    """``out[m] = sum_k h[k] x[m + k]`` for m = 0 .. len(x) - len(h) (FFT)."""
    n = len(x)
    L = len(h)
    nfft = 1 << int(n + L - 1).bit_length()
    X = np.fft.fft(x, nfft)
    Hf = np.fft.fft(h[::-1], nfft)
    full = np.fft.ifft(X * Hf)
    return full[L - 1: n]


def _ls_amplitudes(seg, fs, tau0, lam):
    """Complex b minimising |seg - sum Im(b e^{lam tau})|, tau = tau0 + m/fs."""
    tau = tau0 + np.arange(len(seg)) / fs
    if len(lam) == 0:
        return np.zeros(0, complex), seg.copy()
    E = np.exp(np.outer(tau, lam))  # (N, K)
    # Im(b e) = Re(b) Im(e) + Im(b) Re(e)
    A = np.concatenate([E.imag, E.real], axis=1)
    coef, *_ = np.linalg.lstsq(A, seg, rcond=None)
    K = len(lam)
    b = coef[:K] + 1j * coef[K:]
    return b, seg - A @ coef


def rayleigh_fit(frequencies_hz, decay_per_s, weights=None):
    """Non-negative Rayleigh ``(alpha, beta)`` with ``d = (alpha + beta w^2) / 2`` fitted to
    decays in the relative sense (each mode's relative error counts equally)."""
    from scipy.optimize import nnls

    f = np.asarray(frequencies_hz, float)
    d = np.asarray(decay_per_s, float)
    ok = np.isfinite(f) & np.isfinite(d) & (d > 0) & (f > 0)
    f, d = f[ok], d[ok]
    if len(f) == 0:
        return 0.0, 0.0
    w2 = (2 * np.pi * f) ** 2
    if len(f) == 1:
        return 2.0 * float(d[0]), 0.0
    wt = 1.0 / d if weights is None else np.asarray(weights, float)[ok] / d
    scale = np.array([1.0, 1.0 / w2.max()])  # column scaling for conditioning
    A = np.stack([0.5 * np.ones_like(w2), 0.5 * w2], axis=1) * scale * wt[:, None]
    coef, _ = nnls(A, d * wt)
    coef = coef * scale
    return float(coef[0]), float(coef[1])


def _blas_single():
    """One BLAS thread: the matrices here are small and a threaded BLAS on a busy machine
    spends far more time synchronising than computing (10x measured)."""
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(limits=1, user_api="blas")
    except ImportError:  # pragma: no cover
        import contextlib

        return contextlib.nullcontext()


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


def _fit_core(audio, sample_rate, n_modes, channel, f_min, f_max, min_snr_db, max_seconds, skip_s, band_hz,
              max_decay_per_s):
    t_start = _time.perf_counter()
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
    msgs: list[str] = []
    n = len(x)
    dur = n / fs
    if dur < MIN_DURATION_S:
        raise ValueError(
            f"recording too short: {dur * 1000:.1f} ms ({n} samples at {fs} Hz); a fit needs at least "
            f"{MIN_DURATION_S * 1000:.0f} ms of decay: record the whole ring-out"
        )
    peak = float(np.max(np.abs(x)))
    if peak == 0.0:
        raise ValueError("recording is silent (all samples are zero): check the input channel / microphone and record the impact again")

    # ---------------------------------------------------------------- clipping
    clip_end = -1
    near = np.abs(x) >= peak * (1 - 1e-4)
    n_clip = int(near.sum())
    if n_clip >= 4:
        clip_idx = np.flatnonzero(near)
        clip_end = int(clip_idx[-1])
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
    seg = x[n_a:n_e]
    N = len(seg)
    if n_modes is not None and N < 8 * n_modes:
        raise ValueError(f"recording too short for {n_modes} modes: {N} samples of decay; need about {8 * n_modes} "
                         "(ask for fewer modes or record the whole ring-out)")
    tau_a = (n_a - n_on) / fs  # time of seg[0] after the onset

    # ---------------------------------------------------------------- bands
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

    # ---------------------------------------------------------------- full-rate amplitudes, pruning
    b, res = _ls_amplitudes(seg, fs, tau_a, lam)
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
            ranks = np.argsort(-np.where(ok, en, -1.0))
            ok = np.zeros(len(lam), bool)
            ok[ranks[: int(n_modes)]] = True
        if ok.all():
            break
        lam, noise_k = lam[ok], noise_k[ok]
        b, res = _ls_amplitudes(seg, fs, tau_a, lam)

    if len(lam) == 0:
        _warn(msgs, "no mode rose above the noise: the fit is empty. Record closer to the object, strike harder "
                    "or lower min_snr_db")
    sig_e = float(np.sum(seg**2))
    residual_db = 10 * math.log10(max(float(np.sum(res**2)), 1e-300) / max(sig_e, 1e-300))

    # ---------------------------------------------------------------- onset refinement from phases
    wd = lam.imag
    t0 = n_on / fs
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
        snr_db=float(snr_db),
        noise_rms=float(math.sqrt(floor)),
        analysis_start_s=n_a / fs,
        analysis_end_s=n_e / fs,
        channels=chdesc,
        impulse_like=impulse_like,
        warnings=msgs,
        seconds=_time.perf_counter() - t_start,
        source=source,
    )


# ====================================================================== material fitting
@dataclass
class MaterialFit:
    """Result of :func:`fit_material`.

    Attributes
    ----------
    material : Material
        The base material with ``E`` scaled by ``stiffness_scale`` and the fitted Rayleigh
        ``alpha``, ``beta``; named "fitted". Reusable on other meshes.
    frequency_scale : float
        s: recorded / analysed frequencies (frequencies scale as sqrt(E / rho)).
    stiffness_scale : float
        s^2 (E is scaled, rho kept: only E / rho is observable from frequencies).
    alpha, beta : float
        Rayleigh damping [1/s], [s] with d = (alpha + beta w^2) / 2.
    matches : list of dict
        One per matched mode: fitted_hz, analysed_hz (at the reference material),
        predicted_hz (= s * analysed_hz), cents, fitted_decay, predicted_decay, amplitude.
    unmatched_hz : list of float
        Fitted modes with no analysed mode within ``tolerance_cents``.
    rms_cents : float
        RMS frequency error of the matched modes after scaling.
    decay_rms_rel : float
        RMS relative error of the matched decays against the Rayleigh fit.
    reference_model : ModalModel
        The model analysed at the reference material (frequencies before scaling).
    fit : FitResult
    """

    material: Material
    frequency_scale: float
    stiffness_scale: float
    alpha: float
    beta: float
    matches: list
    unmatched_hz: list
    rms_cents: float
    decay_rms_rel: float
    reference_model: ModalModel
    fit: FitResult

    def summary(self) -> dict:
        return {
            "material": self.material.to_dict(),
            "frequency_scale": self.frequency_scale,
            "stiffness_scale": self.stiffness_scale,
            "alpha": self.alpha,
            "beta": self.beta,
            "n_matched": len(self.matches),
            "matches": self.matches,
            "unmatched_hz": self.unmatched_hz,
            "rms_cents": _num(self.rms_cents),
            "decay_rms_rel": _num(self.decay_rms_rel),
        }


def _match_cost(dlog, g, tau2):
    """Truncated quadratic cost of the fitted modes against the analysed ones shifted by log
    scale g: dlog (n_fit, n_an) = log f_fit - log f_an; g (G,) -> (G,)."""
    r = dlog[None, :, :] - g[:, None, None]
    return np.minimum(np.min(r**2, axis=2), tau2).sum(axis=1)


def fit_material(mesh, recording, base_material=None, *, sample_rate: int | None = None,
                 model: ModalModel | None = None, scale_range=(0.5, 2.0), tolerance_cents: float = 35.0,
                 n_modes: int | None = None, method: str = "hex", quality: str = "default",
                 f_max: float | None = None, cache: bool = True, **fit_kwargs) -> MaterialFit:
    """Example-guided material fitting (Ren, Yeh and Lin 2013): stiffness scale and Rayleigh
    damping so that the analysed model of ``mesh`` matches a recording of the object.

    The mesh is analysed **once**, at the reference material (``base_material``, or the
    material of a given ``model``): frequencies scale exactly as sqrt(E / rho), so the scale
    s is found by matching log-frequencies (a grid search over ``scale_range`` of a
    truncated-quadratic distance from every fitted mode to its nearest analysed mode, then a
    one-to-one assignment (Hungarian) within ``tolerance_cents`` and a least-squares s in log
    frequency, iterated). The decays of the matched modes then give alpha, beta by a
    non-negative least-squares fit of d = (alpha + beta w^2) / 2 in the relative sense.

    Parameters
    ----------
    mesh : anything :func:`mjsound.analyze` accepts (ignored when ``model`` is given).
    recording : FitResult, array or path
        A :class:`FitResult`, or a recording (then fitted with :func:`fit_recording`).
    base_material : Material or spec
        Reference material (nu, rho, restitution are kept; E is scaled). Default: the
        ``model``'s material.
    sample_rate : int, for an array recording.
    model : ModalModel, optional
        The mesh already analysed at the reference material (skips the analysis).
    scale_range : (lo, hi)
        Range of the frequency scale s searched (E scale s^2).
    tolerance_cents : float
        Largest mismatch of a matched mode after scaling [cents].
    n_modes : int, optional
        Passed to :func:`fit_recording`.
    method, quality, f_max, cache :
        Analysis settings (``f_max`` default: the highest fitted frequency / ``scale_range[0]``).

    Returns
    -------
    MaterialFit
    """
    from scipy.optimize import linear_sum_assignment

    fit = recording if isinstance(recording, FitResult) else fit_recording(
        recording, sample_rate, n_modes, **fit_kwargs)
    if fit.n_modes == 0:
        raise ValueError("the recording gave no modes to match; check the recording (see its warnings)")
    lo, hi = (float(v) for v in scale_range)
    if not 0 < lo < hi:
        raise ValueError(f"scale_range={scale_range!r} must be (lo, hi) with 0 < lo < hi")
    if model is None:
        if base_material is None:
            raise ValueError("give base_material (the reference material the mesh is analysed with) or model=")
        ref = parse_material(base_material)
        from .modal.analyze import analyze

        fm = f_max if f_max is not None else min(20000.0, 1.05 * float(fit.frequencies_hz.max()) / lo)
        model = analyze(mesh, ref, method=method, quality=quality, f_max=fm, cache=cache, error_estimate=False)
    else:
        ref = model.material if base_material is None else parse_material(base_material)
    # frequencies at the reference material (the model may have been analysed at another E / rho)
    fa = np.asarray(model.frequencies_hz, float) * math.sqrt(
        (ref.E / ref.rho) / (model.material.E / model.material.rho))
    if len(fa) == 0:
        raise ValueError("the analysed model has no modes; raise f_max or check the mesh")
    ff = fit.frequencies_hz
    dlog = np.log(ff)[:, None] - np.log(fa)[None, :]
    tau = tolerance_cents / 1200.0 * math.log(2.0)
    step = tau / 8
    grid = np.arange(math.log(lo), math.log(hi) + step, step)
    cost = np.concatenate([_match_cost(dlog, grid[i: i + 256], tau**2) for i in range(0, len(grid), 256)])
    g = float(grid[int(np.argmin(cost))])
    fine = g + np.linspace(-step, step, 41)
    g = float(fine[int(np.argmin(_match_cost(dlog, fine, tau**2)))])
    pairs = []
    for _ in range(4):
        r = np.abs(dlog - g)
        big = 1e6
        cm = np.where(r <= tau, r, big)
        rows, cols = linear_sum_assignment(cm)
        pairs = [(i, j) for i, j in zip(rows, cols) if cm[i, j] < big]
        if not pairs:
            break
        ii = np.array([p[0] for p in pairs])
        jj = np.array([p[1] for p in pairs])
        w = np.sqrt(fit.energies()[ii])  # louder modes are measured better
        g_new = float(np.sum(w * dlog[ii, jj]) / np.sum(w))
        if abs(g_new - g) < 1e-12:
            break
        g = g_new
    if not pairs:
        raise ValueError(
            f"no analysed mode matches the recording within {tolerance_cents} cents for a frequency scale in "
            f"{scale_range}; widen scale_range, raise f_max, or check that the mesh is the recorded object"
        )
    s = math.exp(g)
    ii = np.array([p[0] for p in pairs])
    jj = np.array([p[1] for p in pairs])
    order = np.argsort(ff[ii])
    ii, jj = ii[order], jj[order]
    alpha, beta = rayleigh_fit(ff[ii], fit.decay_per_s[ii])
    w = 2 * np.pi * ff[ii]
    dpred = (alpha + beta * w**2) / 2
    matches = [
        {
            "fitted_hz": float(ff[i]),
            "analysed_hz": float(fa[j]),
            "predicted_hz": float(s * fa[j]),
            "cents": float(1200 * math.log2(ff[i] / (s * fa[j]))),
            "fitted_decay": float(fit.decay_per_s[i]),
            "predicted_decay": float(dp),
            "amplitude": float(fit.amplitudes[i]),
        }
        for i, j, dp in zip(ii, jj, dpred)
    ]
    cents = np.array([m["cents"] for m in matches])
    rel = fit.decay_per_s[ii] / dpred - 1
    unmatched = sorted(float(ff[i]) for i in set(range(len(ff))) - set(ii.tolist()))
    mat = replace(ref, E=ref.E * s * s, alpha=alpha, beta=beta, name="fitted")
    return MaterialFit(
        material=mat,
        frequency_scale=s,
        stiffness_scale=s * s,
        alpha=alpha,
        beta=beta,
        matches=matches,
        unmatched_hz=unmatched,
        rms_cents=float(np.sqrt(np.mean(cents**2))),
        decay_rms_rel=float(np.sqrt(np.mean(rel**2))),
        reference_model=model,
        fit=fit,
    )


# ====================================================================== sound design
def render_excitation(model: ModalModel, signal, sample_rate: int, point=None, direction=None, *,
                      tail_s: float | None = None, distance_m: float = 1.0, dtype: str = "float64",
                      radiation: bool = True) -> np.ndarray:
    """Audio of ``model`` driven by a user force signal (sound design: a recorded scrape, a
    mallet, a bow), through :meth:`Synthesizer.excite`.

    Parameters
    ----------
    model : ModalModel
        Analysed or fitted (:meth:`FitResult.to_model`).
    signal : (k,) array_like
        Force [N] at ``sample_rate``; sample j acts at time j / fs (an impulse of
        ``signal[j] / fs`` N s). ``signal = [fs, 0, 0, ...]`` is a 1 N s impulse.
    sample_rate : int
    point : (3,) array_like, optional
        Point in the object frame [m]; default: the single point of a fitted model, else the
        surface sample whose normal response is loudest.
    direction : (3,) array_like, optional
        Force direction in the object frame; default the normal at ``point`` (for a fitted
        model, the direction that replays the recording).
    tail_s : float, optional
        Render this long after the signal ends [s]; default until the slowest mode has decayed
        by 60 dB (at most 5 s).
    distance_m : float
        Microphone distance from the object's origin [m] (1/r; the propagation delay is
        removed so output sample j lines up with force sample j).
    dtype : "float64" (default, exact linear system) or "float32" (faster).
    radiation : bool
        Synthesizer radiation model (see :class:`Synthesizer`).

    Returns
    -------
    (len(signal) + tail,) float64 array of pressure [Pa] at the microphone.
    The output is linear in ``signal`` and equals ``np.convolve(signal / fs, h)`` with ``h`` the
    response to a 1 N s impulse.
    """
    from .synth.synthesizer import Synthesizer

    if not isinstance(model, ModalModel):
        raise ValueError(f"model must be a mjsound.ModalModel, got {type(model).__name__}")
    f = np.asarray(signal, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(f)):
        raise ValueError("signal contains NaN or Inf; give a finite force signal in N")
    fs = int(sample_rate)
    if point is None:
        if len(model.points) == 1:
            k = 0
        else:
            nrm = np.einsum("pcn,pc->pn", model.shapes.astype(np.float64), model.normals.astype(np.float64))
            wd = np.maximum(2 * np.pi * model.damped_frequencies_hz, 1e-9)
            k = int(np.argmax(np.sum((nrm * model.radiation[None, :] / wd[None, :]) ** 2, axis=1)))
        point = model.points[k]
        if direction is None:
            direction = model.normals[k]
    elif direction is None:
        direction = model.normals[int(model.nearest_points(np.reshape(point, (1, 3)))[0])]
    d = model.decay_per_s[(model.frequencies_hz < 0.45 * fs) & (model.decay_per_s > 0)]
    if tail_s is None:
        tail_s = min(6.91 / float(d.min()), 5.0) if len(d) else 0.0
    n = len(f) + int(round(float(tail_s) * fs))
    syn = Synthesizer(fs, microphones=[[0.0, 0.0, float(distance_m)]], dtype=dtype, cull_db=None,
                      radiation=radiation, speed_of_sound=1e12)
    syn.add_object("object", model)
    syn.excite("object", np.asarray(point, float), np.asarray(direction, float), f, 0.0)
    return syn.render(n)[0].astype(np.float64)


# ====================================================================== CLI
def register_cli(subparsers) -> argparse.ArgumentParser:
    """Add the ``fit`` subcommand to an argparse ``subparsers`` object."""
    p = subparsers.add_parser(
        "fit",
        help="fit a modal model (frequencies, decays, amplitudes) to an impact recording",
        description=(
            "Estimate the modes of an impact recording with band-split ESPRIT and least squares, "
            "report the residual the model leaves, and optionally write a one-point ModalModel "
            "(.npz) that plays in the synthesizer. Multi-channel files are mixed to mono unless "
            "--channel is given. With --mesh, also fit a material (stiffness scale, Rayleigh "
            "alpha/beta) so that the analysed mesh matches the recording."
        ),
    )
    p.add_argument("recording", help="impact recording (WAV/FLAC/OGG)")
    p.add_argument("--modes", type=int, default=None, help="keep at most N modes (the most energetic)")
    p.add_argument("-o", "--output", default=None, help="write the fitted ModalModel to this .npz")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--channel", type=int, default=None, help="fit this channel only (default: mix all)")
    p.add_argument("--f-min", type=float, default=20.0, help="lowest frequency [Hz] (default 20)")
    p.add_argument("--f-max", type=float, default=None, help="highest frequency [Hz] (default 0.45 * sample rate)")
    p.add_argument("--min-snr-db", type=float, default=15.0, help="significance of a mode [dB] (default 15)")
    p.add_argument("--mass-kg", type=float, default=None, help="object mass stored in the model (Hertz contact)")
    p.add_argument("--mesh", default=None, help="also fit a material for this mesh / built-in shape")
    p.add_argument("--material", default="aluminium", help="reference material for --mesh (default aluminium)")
    p.set_defaults(func=_run_cli)
    return p


def _run_cli(args) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)  # reported below / in the JSON
        fit = fit_recording(args.recording, n_modes=args.modes, channel=args.channel, f_min=args.f_min,
                            f_max=args.f_max, min_snr_db=args.min_snr_db)
    mfit = None
    if args.mesh:
        mfit = fit_material(args.mesh, fit, args.material)
    if args.output:
        fit.to_model(material=mfit.material if mfit else None, mass_kg=args.mass_kg).save(args.output)
    if args.json:
        out = fit.summary()
        if mfit is not None:
            out["material_fit"] = mfit.summary()
        if args.output:
            out["output"] = args.output
        print(json.dumps(out))
        return 0
    import sys

    for w in fit.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"recording  {args.recording} ({fit.channels}, {fit.sample_rate} Hz)")
    print(f"onset      {fit.onset_s:.5f} s; analysed {fit.analysis_start_s:.3f}..{fit.analysis_end_s:.3f} s; "
          f"peak {fit.snr_db:.1f} dB over the noise floor")
    print(f"modes      {fit.n_modes}; residual {fit.residual_db:.1f} dB; {fit.seconds:.2f} s")
    print("   f [Hz]    d [1/s]   T60 [s]   amplitude")
    for f, d, a in zip(fit.frequencies_hz, fit.decay_per_s, fit.amplitudes):
        print(f"{f:9.2f}  {d:9.3f}  {6.91 / d:8.3f}  {a:10.4g}")
    if mfit is not None:
        m = mfit.material
        print(f"material   E={m.E:.4g} Pa (x{mfit.stiffness_scale:.4f}), alpha={m.alpha:.4g} 1/s, beta={m.beta:.4g} s; "
              f"{len(mfit.matches)} modes matched, rms {mfit.rms_cents:.1f} cents")
    if args.output:
        print(f"wrote      {args.output}")
    return 0
