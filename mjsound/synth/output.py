"""Pressure to full scale, and audio files (WAV/FLAC via soundfile), streamed and atomic.

Full scale
----------
The synthesizer outputs sound pressure in pascals. Files and observations map a documented
full-scale pressure ``full_scale_pa`` to 1.0 (``DEFAULT_FULL_SCALE_PA = 20 Pa``, i.e.
120 dB SPL re 20 uPa: a loud hammer blow close to the ear just fits). Samples beyond +-1
are clipped and counted; NaN is mapped to 0 and counted as clipped (never written).

``soundfile`` is imported only when a file is written.
"""

from __future__ import annotations

import errno
import os
import shutil

import numpy as np

from ..io import commit_temp, discard_temp, temp_beside

__all__ = ["DEFAULT_FULL_SCALE_PA", "AUDIO_SUFFIXES", "WAV_MAX_BYTES", "to_full_scale", "normalize_peak",
           "AudioWriter", "write_audio"]

#: Audio file types mjsound writes (soundfile; WAV float or FLAC 24-bit).
AUDIO_SUFFIXES = (".wav", ".flac")
#: Largest WAV file (its RIFF header counts bytes in 32 bits); longer takes need FLAC.
WAV_MAX_BYTES = (1 << 32) - 1024
#: Frames per block of the second pass of a normalised file.
_PASS_FRAMES = 1 << 16

#: Pressure [Pa] mapped to digital full scale (1.0): 20 Pa = 120 dB SPL.
DEFAULT_FULL_SCALE_PA = 20.0


def to_full_scale(pressure, full_scale_pa: float = DEFAULT_FULL_SCALE_PA):
    """Map pressure [Pa] to [-1, 1].

    Parameters
    ----------
    pressure : array_like
        Sound pressure [Pa], any shape (e.g. (channels, n)).
    full_scale_pa : float
        Pressure mapped to 1.0 (> 0).

    Returns
    -------
    audio : float32 ndarray, same shape, in [-1, 1]
    n_clipped : int
        Number of samples that were outside [-1, 1] or not finite.
    """
    fs_pa = float(full_scale_pa)
    if not np.isfinite(fs_pa) or fs_pa <= 0:
        raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure in Pa (e.g. 20)")
    x = np.asarray(pressure, dtype=np.float64) / fs_pa
    bad = ~np.isfinite(x)
    over = np.abs(np.where(bad, 0.0, x)) > 1.0
    n_clipped = int(bad.sum() + over.sum())
    x = np.where(bad, 0.0, np.clip(x, -1.0, 1.0))
    return x.astype(np.float32), n_clipped


def normalize_peak(audio, peak: float = 0.891):
    """Scale so that the largest |sample| is ``peak`` (default -1 dBFS); silence stays silent.

    For offline files only: it discards the absolute level. Returns float32.
    """
    a = np.nan_to_num(np.asarray(audio, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    m = np.abs(a).max() if a.size else 0.0
    if m > 0:
        a = a * (float(peak) / m)
    return a.astype(np.float32)


def _format_for(path, fmt):
    if fmt:
        return fmt.upper()
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in AUDIO_SUFFIXES:
        raise ValueError(f"{os.fspath(path)!r}: cannot write {ext or 'a file without a suffix'!r} audio; "
                         f"name the file {' or '.join('*' + e for e in AUDIO_SUFFIXES)}")
    return ext.lstrip(".").upper()


def _write_error(path, exc) -> OSError:
    """An ``OSError`` naming ``path`` for a failed write (soundfile raises its own errors)."""
    if isinstance(exc, OSError) and exc.errno:
        code, why = exc.errno, exc.strerror or str(exc)
    else:
        try:
            full = shutil.disk_usage(os.path.dirname(os.path.abspath(path))).free < (1 << 20)
        except OSError:
            full = False
        code = errno.ENOSPC if full else errno.EIO
        why = (os.strerror(code) if full else "is the disk full, or a file size limit reached?") + f" soundfile: {exc}"
    return OSError(code, f"cannot write the audio file ({why})", os.fspath(path))


class AudioWriter:
    """Stream audio blocks to a WAV/FLAC file; the file appears complete or not at all.

    Blocks are written to a temporary file in the target's directory and renamed over
    ``path`` by :meth:`close` (``os.replace``, atomic); an exception inside a ``with`` block
    (or :meth:`abort`) deletes the temporary file and leaves ``path`` untouched.

    Parameters
    ----------
    path : str or PathLike
        Output file (.wav or .flac).
    sample_rate : int
        [Hz].
    channels : int
        Number of channels.
    subtype : str, optional
        soundfile subtype; default ``"FLOAT"`` for WAV (exact, keeps values beyond 1) and
        ``"PCM_24"`` for FLAC (integer only).
    full_scale_pa : float or None
        If given, blocks are pressure [Pa] and are mapped with :func:`to_full_scale`; if
        ``None`` they are written as given (already in [-1, 1]; NaN becomes 0).
    normalize : bool or float
        Peak-normalise (``True``: to -1 dBFS, or to the given peak; the level is lost). The
        blocks go to a raw float32 temporary file first and are scaled in a second pass at
        :meth:`close`, so memory stays one block whatever the length.

    Attributes
    ----------
    n_clipped : int
        Clipped samples so far.  frames : int  Frames written.

    Examples
    --------
    >>> with AudioWriter("out.wav", 48000, 1, full_scale_pa=20.0) as w:   # doctest: +SKIP
    ...     w.write(syn.render(4800))          # (channels, n) blocks
    """

    def __init__(self, path, sample_rate, channels=1, subtype=None, format=None, full_scale_pa=None,
                 normalize=False):
        self.path = os.fspath(path)
        if os.path.isdir(self.path):
            raise ValueError(f"{self.path!r} is a directory: give an audio file name (e.g. out.wav)")
        self.sample_rate = int(sample_rate)
        self.channels = int(channels)
        if self.channels < 1:
            raise ValueError("channels must be >= 1")
        self.format = _format_for(self.path, format)
        if subtype is None:
            subtype = "FLOAT" if self.format == "WAV" else "PCM_24"
        self.subtype = subtype
        self.full_scale_pa = None if normalize else full_scale_pa
        self.normalize = normalize
        self.n_clipped = 0
        self.frames = 0
        self.peak = 0.0
        self._raw = None
        self._closed = True
        fd, self._tmp = temp_beside(self.path, "." + self.format.lower())
        os.close(fd)
        try:
            if normalize:
                fd, raw = temp_beside(self.path, ".f32")
                self._raw = os.fdopen(fd, "wb")
                self._raw_path = raw
            self._f = self._open(self._tmp)
        except BaseException:
            self._discard()
            raise
        self._closed = False

    def _open(self, tmp):
        import soundfile as sf

        return sf.SoundFile(tmp, "w", samplerate=self.sample_rate, channels=self.channels,
                            subtype=self.subtype, format=self.format)

    def _discard(self) -> None:
        discard_temp(self._tmp)
        if self._raw is not None:
            self._raw.close()
            discard_temp(self._raw_path)

    def write(self, block) -> None:
        """Write a (channels, n) block (a 1-D array is one channel)."""
        if self._closed:
            raise ValueError("AudioWriter is closed")
        b = np.asarray(block)
        if b.ndim == 1:
            b = b[None, :]
        if b.shape[0] != self.channels:
            raise ValueError(f"block has {b.shape[0]} channels, the writer {self.channels}; give (channels, n)")
        if self.format == "WAV" and (self.frames + b.shape[1]) * self.channels * 4 > WAV_MAX_BYTES:
            raise ValueError(f"{self.path}: a WAV file holds at most 4 GiB ({WAV_MAX_BYTES // (4 * self.channels)} "
                             "frames here); write a .flac file for a take this long")
        if self._raw is not None:  # first pass of a normalised file: raw pressure, scaled at close
            b = np.nan_to_num(np.asarray(b, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
            if b.size:
                self.peak = max(self.peak, float(np.abs(b).max()))
            try:
                self._raw.write(np.ascontiguousarray(b.T).tobytes())
            except OSError as exc:
                raise _write_error(self.path, exc) from exc
            self.frames += b.shape[1]
            return
        if self.full_scale_pa is not None:
            b, nc = to_full_scale(b, self.full_scale_pa)
        else:
            bad = ~np.isfinite(b)
            nc = int(bad.sum())
            b = np.where(bad, 0.0, b).astype(np.float32)
            if self.subtype.startswith("PCM"):
                over = np.abs(b) > 1
                nc += int(over.sum())
                b = np.clip(b, -1, 1)
        self.n_clipped += nc
        try:
            self._f.write(np.ascontiguousarray(b.T))
        except Exception as exc:  # soundfile.LibsndfileError (a full disk, a file size limit)
            raise _write_error(self.path, exc) from exc
        self.frames += b.shape[1]

    def _second_pass(self) -> None:
        """Scale the raw first pass to the normalised peak, block by block, into the file."""
        self._raw.close()
        target = 0.891 if self.normalize is True else float(self.normalize)
        gain = target / self.peak if self.peak > 0 else 1.0
        step = _PASS_FRAMES * self.channels
        with open(self._raw_path, "rb") as fh:
            while True:
                x = np.fromfile(fh, dtype=np.float32, count=step)
                if not x.size:
                    break
                self._f.write((x.reshape(-1, self.channels).astype(np.float64) * gain).astype(np.float32))
        discard_temp(self._raw_path)
        self._raw = None

    def close(self) -> None:
        """Finish the file and move it into place (atomic)."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._raw is not None:
                self._second_pass()
            self._f.close()
            commit_temp(self._tmp, self.path)
        except BaseException as exc:
            self._discard()
            if isinstance(exc, Exception) and not isinstance(exc, ValueError):
                raise _write_error(self.path, exc) from exc
            raise

    def abort(self) -> None:
        """Discard everything written; ``path`` is left as it was."""
        if self._closed:
            return
        self._closed = True
        try:
            self._f.close()
        except Exception:  # a full disk can fail the close too: the file is discarded anyway
            pass
        finally:
            self._discard()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


def write_audio(path, audio, sample_rate, *, full_scale_pa=None, normalize=False, subtype=None, format=None) -> int:
    """Write a whole (channels, n) array (or 1-D) to ``path`` atomically.

    Parameters
    ----------
    audio : array_like
        Pressure [Pa] if ``full_scale_pa`` is given, else samples in [-1, 1].
    normalize : bool or float
        Peak-normalise first (``True``: to -1 dBFS, or the given peak); the level is lost.

    Returns
    -------
    int : number of clipped samples.
    """
    a = np.asarray(audio, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    n = 0
    if normalize:
        a = normalize_peak(a, 0.891 if normalize is True else float(normalize))
    elif full_scale_pa is not None:
        a, n = to_full_scale(a, full_scale_pa)
    with AudioWriter(path, sample_rate, a.shape[0], subtype=subtype, format=format) as w:
        w.write(a)
    return n + w.n_clipped
