"""The audio observation's window: the newest samples of the pressure stream in full-scale
units (:class:`AudioWindow`), as a waveform or its ``log1p(|STFT|)``
(:func:`stft_log1p`). The observation side of :mod:`mjsound.env_audio`, shared by the gymnasium
(:mod:`mjsound.wrappers`) and dm_control (:mod:`mjsound.dmc`) wrappers."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np

from .jit import njit
from .synth.dispatch import EntryPoint

__all__ = ["AudioWindow", "stft_log1p", "ATMOSPHERE_PA"]

#: One atmosphere [Pa]: the largest pressure swing that is still sound (a rarefaction cannot go
#: below vacuum; well before it, air is no longer linear). An unclipped observation is bounded
#: here: a louder sample is not sound but a simulation gone wrong (counted as clipped).
ATMOSPHERE_PA = 101325.0


def _stft_setup(window: int, n_fft: int, hop: int | None):
    n = int(n_fft)
    if window < n:
        n = 1 << int(math.floor(math.log2(max(window, 2))))
    hop = int(hop) if hop else n // 2
    hop = max(1, min(hop, n))
    frames = 1 + (window - n) // hop
    win = np.hanning(n + 1)[:-1].astype(np.float32)  # periodic Hann
    return n, hop, frames, win


@functools.lru_cache(maxsize=16)
def _frame_index(n: int, n_fft: int, hop: int) -> np.ndarray:
    """Sample indices (frames, n_fft) of the STFT frames of an ``n``-sample window."""
    frames = 1 + (n - n_fft) // hop
    return np.arange(n_fft)[None, :] + hop * np.arange(frames)[:, None]


def stft_log1p(x: np.ndarray, n_fft: int, hop: int, win: np.ndarray) -> np.ndarray:
    """``log1p(|STFT|)`` of ``x`` (channels, samples) -> (channels, n_fft // 2 + 1, frames) float32.

    Frames start at sample 0 and step by ``hop`` (no centring, no padding); each is multiplied
    by ``win`` and transformed with ``scipy.fft.rfft`` (no normalisation; float32 in, so
    single precision).
    """
    import scipy.fft

    x = np.ascontiguousarray(x, dtype=np.float32)
    seg = x[:, _frame_index(x.shape[1], int(n_fft), int(hop))] * win  # (C, T, n_fft)
    mag = np.abs(scipy.fft.rfft(seg, axis=-1))  # (C, T, F); single precision stays single
    return np.log1p(mag).transpose(0, 2, 1).astype(np.float32)


class AudioWindow:
    """The newest ``window`` samples of a pressure stream, as an observation.

    Pressure blocks [Pa] are divided by ``full_scale_pa`` and appended; :meth:`observe` gives
    the window (``"waveform"``) or its ``log1p(|STFT|)`` (``"spectrogram"``, see
    :func:`stft_log1p`). Samples are clipped at ``limit`` full-scale units: 1 with ``clip=True``
    (the observation is a clipping microphone), else :data:`ATMOSPHERE_PA` / ``full_scale_pa``
    (nothing that is sound is clipped). Clipped and non-finite samples are counted; NaN becomes 0.
    """

    def __init__(self, channels: int, window: int, full_scale_pa: float = 20.0, mode: str = "waveform",
                 n_fft: int = 256, hop: int | None = None, clip: bool = False):
        if mode not in ("waveform", "spectrogram"):
            raise ValueError(f"mode={mode!r}: choose 'waveform' or 'spectrogram'")
        fsp = float(full_scale_pa)
        if not (math.isfinite(fsp) and fsp > 0):
            raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure [Pa]")
        if int(window) < 2:
            raise ValueError(f"audio window of {window} samples is too short")
        if not isinstance(clip, (bool, np.bool_)):
            raise ValueError(f"clip={clip!r} must be True (clip at full scale) or False (keep every level)")
        self.channels, self.window, self.full_scale_pa, self.mode = int(channels), int(window), fsp, mode
        self.clip = bool(clip)
        self.limit = 1.0 if clip else ATMOSPHERE_PA / fsp  # (full-scale units)
        C, W = self.channels, self.window
        if mode == "waveform":
            self.space = gym.spaces.Box(-self.limit, self.limit, (C, W), np.float32)
        else:
            self.n_fft, self.hop, frames, self.win = _stft_setup(W, n_fft, hop)
            top = float(np.log1p(self.win.astype(np.float64).sum() * self.limit)) + 1e-3
            self.space = gym.spaces.Box(0.0, top, (C, self.n_fft // 2 + 1, frames), np.float32)
        self.buf = np.zeros((C, W), np.float32)
        self._push = EntryPoint(_push_kernel)  # (its compiled entry point: numba's dispatch types every call)

    def reset(self) -> None:
        self.buf[:] = 0.0

    def observe(self) -> np.ndarray:
        if self.mode == "waveform":
            return self.buf.copy()
        return stft_log1p(self.buf, self.n_fft, self.hop, self.win)

    def push(self, block: np.ndarray) -> tuple[int, float]:
        """Append a (channels, n) pressure block; returns (clipped samples, peak |p| [Pa])."""
        if block.shape[1] == 0:
            return 0, 0.0
        block = np.ascontiguousarray(block, dtype=np.float32)  # (the block itself when it is already)
        fsp = self.full_scale_pa
        clipped, peak = self._push((self.buf,), block, 1.0 / fsp, self.limit)  # (a Python int and float)
        return clipped, peak * fsp


@njit(cache=True)
def _push_kernel(buf, block, scale, limit):
    """Shift ``buf`` (C, W) left and append ``block * scale`` clipped to [-limit, limit] (NaN/Inf:
    0 and counted as clipped). Returns (clipped samples, peak |x| before clipping, NaN excluded)."""
    C, W = buf.shape
    n = block.shape[1]
    clipped = 0
    peak = 0.0
    keep = W - n if n < W else 0
    for c in range(C):
        for k in range(keep):
            buf[c, k] = buf[c, k + n]
        for k in range(n):
            x = block[c, k] * scale
            if not np.isfinite(x):
                clipped += 1
                x = 0.0
            else:
                a = abs(x)
                if a > peak:
                    peak = a
                if a > limit:
                    clipped += 1
                    x = limit if x > 0 else -limit
            j = k - (n - W) if n > W else keep + k
            if j >= 0:
                buf[c, j] = x
    return clipped, peak
