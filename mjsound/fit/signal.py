"""Signal-processing pieces of the fit: ESPRIT poles, a Kaiser low-pass, FFT correlation and
least-squares amplitudes of damped exponentials."""

from __future__ import annotations

import math

import numpy as np


def _frames(x, L):
    n = len(x) // L
    e = np.mean(x[: n * L].reshape(n, L) ** 2, axis=1) if n else np.zeros(0)
    return e


#: Components this far below a band's strongest one are not resolved [dB]. The Gram matrix
#: ``H H^H`` squares the condition number, so singular values below about 1e-8 of the largest
#: are rounding noise; without this floor a noise-free recording "finds" dozens of modes
#: whose huge, cancelling amplitudes fit that noise.
MAX_DYNAMIC_RANGE_DB = 90.0


def _esprit(y, L, max_order, min_sig=0.0):
    """Poles z of a complex signal y by ESPRIT with L Hankel rows.

    The signal subspace comes from the eigenvectors of the L x L Gram matrix H H^H (much
    cheaper than an SVD of H and as accurate here). The model order is the number of singular
    values above the largest one that noise alone would give, ``sigma (sqrt(L) + sqrt(C))``
    for an L x C noise matrix, with the noise level sigma estimated from the lower half of
    the singular values themselves (they are noise when there are fewer than L/2 modes, and
    self-calibrate to the band's own noise, which a periodogram median overestimates when
    resonance skirts fill the band). The threshold is never below
    :data:`MAX_DYNAMIC_RANGE_DB` under the largest singular value. Returns ``(z, sigma^2)``."""
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
    spread = math.sqrt(L) + math.sqrt(C)
    floor = float(s[0]) * 10 ** (-MAX_DYNAMIC_RANGE_DB / 20) / (1.1 * spread)
    sig = max(float(np.median(s[L // 2:])) / math.sqrt(C), min_sig, floor)
    thr = 1.1 * sig * spread
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


def _blas_single():
    """One BLAS thread: the matrices here are small and a threaded BLAS on a busy machine
    spends far more time synchronising than computing (10x measured)."""
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(limits=1, user_api="blas")
    except ImportError:  # pragma: no cover
        import contextlib

        return contextlib.nullcontext()
