"""The audio observation's window: the newest samples of the pressure stream, scaled to full
scale and clipped (:class:`AudioWindow`), as a waveform or its ``log1p(|STFT|)``
(:func:`stft_log1p`). The observation side of :mod:`mjsound.env_audio`, shared by the gymnasium
(:mod:`mjsound.wrappers`) and dm_control (:mod:`mjsound.dmc`) wrappers."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np

from .jit import njit
from .synth.dispatch import EntryPoint

__all__ = ["AudioWindow", "stft_log1p"]


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

    Pressure blocks [Pa] are divided by ``full_scale_pa``, clipped to [-1, 1] (clipped and
    non-finite samples counted; NaN becomes 0) and appended; :meth:`observe` gives the window
    (``"waveform"``) or its ``log1p(|STFT|)`` (``"spectrogram"``, see :func:`stft_log1p`).
    """

    def __init__(self, channels: int, window: int, full_scale_pa: float = 20.0, mode: str = "waveform",
                 n_fft: int = 256, hop: int | None = None):
        if mode not in ("waveform", "spectrogram"):
            raise ValueError(f"mode={mode!r}: choose 'waveform' or 'spectrogram'")
        fsp = float(full_scale_pa)
        if not (math.isfinite(fsp) and fsp > 0):
            raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure [Pa]")
        if int(window) < 2:
            raise ValueError(f"audio window of {window} samples is too short")
        self.channels, self.window, self.full_scale_pa, self.mode = int(channels), int(window), fsp, mode
        C, W = self.channels, self.window
        if mode == "waveform":
            self.space = gym.spaces.Box(-1.0, 1.0, (C, W), np.float32)
        else:
            self.n_fft, self.hop, frames, self.win = _stft_setup(W, n_fft, hop)
            top = float(np.log1p(self.win.astype(np.float64).sum())) + 1e-3
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
        clipped, peak = self._push((self.buf,), block, 1.0 / fsp)  # (a Python int and float)
        return clipped, peak * fsp


@njit(cache=True)
def _push_kernel(buf, block, scale):
    """Shift ``buf`` (C, W) left and append ``block * scale`` clipped to [-1, 1] (NaN/Inf: 0 and
    counted as clipped). Returns (clipped samples, peak |x| before clipping, NaN excluded)."""
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
                if a > 1.0:
                    clipped += 1
                    x = 1.0 if x > 0 else -1.0
            j = k - (n - W) if n > W else keep + k
            if j >= 0:
                buf[c, j] = x
    return clipped, peak
