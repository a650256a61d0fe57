"""Live playback: a simulation's audio blocks to an audio device, paced to its clock.

:class:`LivePlayer` keeps a ring buffer that the simulation fills (:meth:`LivePlayer.push`)
and a PortAudio output stream (``sounddevice``, the optional extra ``mjsound[live]``) drains
in its callback thread. The device's clock paces the simulation: ``push`` returns once no
more than ``lead_s`` of audio waits in the ring, so the simulation runs no further ahead of
what is heard than that, and sample ``s`` of the simulation is played at

.. math:: t_{play}(s) = t_0 + s / f_s + \\sum_{gaps \\le s} g

with :math:`t_0` the start and :math:`g` the silent gaps inserted when the simulation fell
behind. Nothing is resampled, dropped or repeated: audio and simulation time never drift
apart, and without gaps the device plays exactly the pushed samples.

When the ring runs dry (the simulation is slower than real time for a moment), the callback
ramps the last sample to zero over ``FADE_S`` instead of jumping (a jump is the click), counts
the underflow itself (PortAudio's status flags miss some on some back-ends) and waits until
``lead_s`` of audio is queued again before it resumes, with the first ``FADE_S`` faded in: the
timeline is re-anchored once per gap, not stuttered block by block. The first gap is logged
(``logging.getLogger("mjsound.live")``) with how far the simulation fell behind;
:meth:`LivePlayer.stats` counts them all.

Example
-------
>>> player = LivePlayer(48000, channels=2)                      # doctest: +SKIP
>>> for _ in range(200):                                         # doctest: +SKIP
...     player.push(sim.advance(10)[:2] / 20.0)   # 10 ms of pressure, 20 Pa full scale
>>> player.close()                                               # doctest: +SKIP
"""

from __future__ import annotations

import logging
import math
import threading
import time

import numpy as np

__all__ = ["LivePlayer", "LiveAudioError", "open_sounddevice", "check_output_device", "output_channels", "FADE_S"]

log = logging.getLogger("mjsound.live")

FADE_S = 0.002
"""Length of the ramp to silence at an underflow and of the fade-in after it [s]."""

_INSTALL = ("live playback needs the sounddevice package and the PortAudio library: "
            "pip install 'mjsound[live]' (sounddevice), and on Debian/Ubuntu apt-get install libportaudio2")


class LiveAudioError(OSError):
    """Live playback cannot start or went wrong: the message names the cause and the fix."""


def open_sounddevice():
    """Import ``sounddevice`` (it loads PortAudio at import), or raise an error naming the fix.

    Returns
    -------
    module
        The ``sounddevice`` module.

    Raises
    ------
    ImportError
        sounddevice is not installed, or the PortAudio library is missing.
    """
    try:
        import sounddevice
    except ImportError as exc:
        raise ImportError(f"{_INSTALL} ({exc})") from None
    except OSError as exc:  # sounddevice raises OSError('PortAudio library not found')
        raise ImportError(f"{_INSTALL} ({exc})") from None
    return sounddevice


def output_channels(n_channels: int, contact_channels=()) -> list[int]:
    """The simulator channels a listener hears: the first two air microphones (stereo) or
    the one there is (mono); contact microphones (accelerations, not sound) are left out.

    Parameters
    ----------
    n_channels : int
        The simulator's channel count (``AudioSimulator.n_channels``).
    contact_channels : sequence of int
        Its contact-microphone channels (``AudioSimulator.contact_channels``).

    Returns
    -------
    list[int]
        One or two channel indices.
    """
    contact = {int(c) for c in contact_channels}
    air = [c for c in range(int(n_channels)) if c not in contact]
    if not air:
        raise ValueError("the scene has no air microphone to listen to (only contact microphones); "
                         "add a site named mic* or let mjsound place the default microphone")
    return air[:2]


def _device_error(sd, device, exc) -> LiveAudioError:
    """A device that cannot be opened: the message lists the output devices there are."""
    try:
        names = [d["name"] for d in sd.query_devices() if d["max_output_channels"] > 0]
    except Exception:  # (PortAudio may be unable to list them either)
        names = []
    which = "the default output device" if device is None else f"audio device {device!r}"
    listed = ", ".join(repr(n) for n in names) if names else "none found"
    return LiveAudioError(f"cannot play on {which}: {exc}. Output devices: {listed}. Pick one with "
                          "--audio-device NAME (device=NAME); on a machine without a sound card, see "
                          "docs/live.md for a PulseAudio null sink")


def check_output_device(device=None, sample_rate: int = 48000) -> None:
    """Raise :class:`LiveAudioError` (listing the output devices) unless ``device`` (None: the
    default) can play float32 audio at ``sample_rate``; a check before a long set-up."""
    sd = open_sounddevice()
    try:
        sd.check_output_settings(device=device, channels=1, dtype="float32", samplerate=sample_rate)
    except (ValueError, sd.PortAudioError) as exc:
        raise _device_error(sd, device, exc) from None


class LivePlayer:
    """Plays pushed audio blocks on an output device in real time (see the module docstring).

    Parameters
    ----------
    sample_rate : int
        Sample rate of the pushed audio [Hz] (the stream runs at it; the audio system
        converts when the device does not).
    channels : int
        Channels of the pushed blocks (1 or 2 for a listener).
    device : str | int | None
        Output device (a name or part of it, or a PortAudio index; None: the default).
    lead_s : float
        Audio queued ahead of the device at most, and the amount queued before playing
        starts or resumes after a gap [s]. Smaller is less latency, larger survives longer
        hiccups of the simulation.
    block_s : float
        The device callback's block [s] (480 frames at 48 kHz: 10 ms).
    device_latency_s : float, optional
        The latency asked of PortAudio [s] (None: its default for output, about 40 ms on
        ALSA); more survives longer delays of the callback thread on a busy machine.
    keep_log : int
        Callbacks and pushes whose timing :meth:`timing` keeps (the first this many).

    Notes
    -----
    Blocks are float32 in full-scale units (1.0 = the device's full scale): the caller
    chooses the gain (e.g. pressure / 20 Pa). Values beyond +-1 are clipped and counted.
    """

    def __init__(self, sample_rate: int, channels: int = 2, device=None, lead_s: float = 0.05,
                 block_s: float = 0.01, device_latency_s: float | None = None, keep_log: int = 65536):
        if isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, np.integer)) or not 8000 <= sample_rate <= 384000:
            raise ValueError(f"sample_rate={sample_rate!r} must be an integer number of Hz in 8000..384000")
        if channels not in (1, 2):
            raise ValueError(f"channels={channels!r}: a listener hears 1 (mono) or 2 (stereo) channels")
        for name, v in (("lead_s", lead_s), ("block_s", block_s)) + ((("device_latency_s", device_latency_s),)
                                                                   if device_latency_s is not None else ()):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.001 <= v <= 2.0):
                raise ValueError(f"{name}={v!r} must be a duration in seconds between 0.001 and 2")
        self.sample_rate = int(sample_rate)
        self.channels = int(channels)
        self.device = device
        self.device_latency = "high" if device_latency_s is None else float(device_latency_s)
        self.block = max(16, int(round(block_s * sample_rate)))
        self.lead = max(self.block, int(round(lead_s * sample_rate)))
        self._fade = max(1, int(round(FADE_S * sample_rate)))
        self._ramp_up = (np.arange(1, self._fade + 1, dtype=np.float32) / self._fade)[:, None]
        self._ramp_down = self._ramp_up[::-1] - np.float32(1.0 / self._fade)
        cap = 1 << int(math.ceil(math.log2(self.lead + 2 * self.block + 1)))
        self._ring = np.zeros((cap, self.channels), np.float32)
        self._lock = threading.Lock()
        self._w = 0  # sim frames pushed (absolute)
        self._r = 0  # sim frames handed to the device (absolute)
        self._waiting = True  # priming: silence until `lead` frames are queued
        self._draining = False
        self._fade_pos = self._fade  # (ramp-up samples applied since the last gap: none pending)
        self._tail_pos = self._fade  # (ramp-down samples written since the ring ran dry)
        self._tail_from = np.zeros(self.channels, np.float32)
        self._last = np.zeros(self.channels, np.float32)
        self._frames_out = 0  # device frames written by the callback (sim and silence)
        self._gaps = []  # (sim frame, device frame where the gap began, its length in frames when known)
        self._gap_open = None
        self._started_frame = None  # device frame of sim frame 0
        self._pa_underflows = 0
        self._clipped = 0
        self._reported = 0
        self._keep = int(keep_log)
        self._cb_log = np.zeros((self._keep, 4))  # sim frame r, frames played, DAC time, current time
        self._n_cb = 0
        self._push_log = np.zeros((self._keep, 2))  # wall time (time.monotonic) after a push, frames pushed
        self._n_push = 0
        self._stream = None
        self._latency = 0.0

    # ---------------------------------------------------------------- stream
    def start(self) -> "LivePlayer":
        """Open and start the output stream (done by the first :meth:`push` when not called)."""
        if self._stream is not None:
            return self
        sd = open_sounddevice()
        try:
            stream = sd.OutputStream(samplerate=self.sample_rate, channels=self.channels, dtype="float32",
                                     device=self.device, blocksize=self.block, latency=self.device_latency,
                                     callback=self._callback)
            stream.start()
        except (ValueError, sd.PortAudioError) as exc:
            raise _device_error(sd, self.device, exc) from None
        self._stream = stream
        self._latency = float(stream.latency)
        return self

    @property
    def latency_s(self) -> float:
        """The output stream's own latency as PortAudio reports it [s] (0 before start)."""
        return self._latency

    def _callback(self, out, frames, time_info, status) -> None:
        """The device asks for ``frames`` frames (PortAudio's thread): ring -> ``out``; the
        ramps to silence and back may span callbacks."""
        if status.output_underflow:
            self._pa_underflows += 1
        fade = self._fade
        with self._lock:
            r, w = self._r, self._w
            avail = w - r
            if self._waiting and (avail >= self.lead or (self._draining and avail > 0)):
                self._resume()
            n = 0 if self._waiting else min(frames, avail)
            cap = len(self._ring)
            i = r % cap
            k = min(n, cap - i)
            out[:k] = self._ring[i:i + k]
            out[k:n] = self._ring[:n - k]
            if self._fade_pos < fade and n:
                m = min(n, fade - self._fade_pos)
                out[:m] *= self._ramp_up[self._fade_pos:self._fade_pos + m]
                self._fade_pos += m
            if n < frames:
                if not self._waiting:  # ran dry now: ramp to silence, then wait for `lead` frames again
                    self._tail_from = out[n - 1].copy() if n else self._last
                    self._tail_pos = 0
                    self._waiting = True
                    if not self._draining:
                        self._gap_open = (r + n, self._frames_out + n)
                m = min(frames - n, fade - self._tail_pos)
                out[n:n + m] = self._tail_from * self._ramp_down[self._tail_pos:self._tail_pos + m]
                self._tail_pos += m
                out[n + m:] = 0.0
            self._last = out[frames - 1].copy()
            if n and self._n_cb < self._keep:
                self._cb_log[self._n_cb] = (r, n, time_info.outputBufferDacTime, time_info.currentTime)
                self._n_cb += 1
            self._r = r + n
            self._frames_out += frames

    def _resume(self) -> None:
        """Start playing (first time), or again after a gap with a fade-in (lock held)."""
        self._waiting = False
        if self._started_frame is None:
            self._started_frame = self._frames_out
        else:
            self._fade_pos = 0
        if self._gap_open is not None:
            s, f0 = self._gap_open
            self._gaps.append((s, f0, self._frames_out - f0))
            self._gap_open = None

    # ---------------------------------------------------------------- feeding
    def push(self, block) -> None:
        """Queue ``block`` and wait until no more than ``lead_s`` of audio is queued.

        Parameters
        ----------
        block : (channels, n) array
            Audio in full-scale units (float; clipped to +-1, clipped samples counted).

        Raises
        ------
        LiveAudioError
            The device stopped taking samples (its stream ended or hung for 2 s).
        """
        block = np.asarray(block, np.float32)
        if block.ndim != 2 or block.shape[0] != self.channels:
            raise ValueError(f"block of shape {block.shape}: expected ({self.channels}, n) samples")
        self.start()
        frames = block.T
        bad = ~(np.abs(frames) <= 1.0)  # (NaN counts as clipped)
        if bad.any():
            self._clipped += int(bad.sum())
            frames = np.nan_to_num(np.clip(frames, -1.0, 1.0), nan=0.0)
        done = 0
        while done < len(frames):
            self._wait_below(len(self._ring) - min(len(frames) - done, self.block))
            done += self._write(frames[done:])
        self._wait_below(self.lead)
        if self._n_push < self._keep:
            self._push_log[self._n_push] = (time.monotonic(), self._w)
            self._n_push += 1
        self._report_gap()

    def _write(self, frames: np.ndarray) -> int:
        """Copy as many of ``frames`` ((n, channels) float32) into the ring as it has room
        for; returns how many."""
        cap = len(self._ring)
        with self._lock:
            n = min(cap - (self._w - self._r), len(frames))
            i = self._w % cap
            k = min(n, cap - i)
            self._ring[i:i + k] = frames[:k]
            self._ring[:n - k] = frames[k:n]
            self._w += n
        return n

    def _wait_below(self, limit: int) -> None:
        """Sleep until at most ``limit`` frames are queued (the device drains them)."""
        stalled_since = None
        seen = self._r
        while self._w - self._r > limit:
            if self._stream is None or not self._stream.active:
                raise LiveAudioError("the audio stream stopped (device unplugged or closed?): live playback ended")
            now = time.monotonic()
            if self._r != seen or stalled_since is None:
                seen, stalled_since = self._r, now
            elif now - stalled_since > 2.0 + self.lead / self.sample_rate:
                raise LiveAudioError(f"the audio device {self.device or '(default)'} took no samples for 2 s: "
                                     "is it blocked by another program? Try another --audio-device")
            time.sleep(min(0.005, max(0.0005, (self._w - self._r - limit) / self.sample_rate)))

    def _report_gap(self) -> None:
        """Log the first gap (the simulation fell behind real time), once."""
        if self._reported or not self._gaps:
            return
        self._reported = 1
        s, _, g = self._gaps[0]
        log.warning("the simulation fell %.0f ms behind real time at %.2f s of its audio; the sound paused "
                    "(faded, no click) and resumes in step with the simulation: more such gaps are counted, not "
                    "reported (a lighter scene, fewer --budget-modes or a larger lead_s avoid them)",
                    1000.0 * g / self.sample_rate, s / self.sample_rate)

    # ---------------------------------------------------------------- ending
    def close(self, drain: bool = True) -> dict:
        """Play what is queued (``drain``), stop the stream; returns :meth:`stats`."""
        if self._stream is not None:
            try:
                if drain and self._stream.active:
                    with self._lock:
                        self._draining = True
                    self._wait_below(0)
                    time.sleep(self.latency_s + 2 * self.block / self.sample_rate)
            finally:
                self._stream.stop()
                self._stream.close()
                self._stream = None
        return self.stats()

    def __enter__(self):
        return self.start()

    def __exit__(self, exc_type, exc, tb):
        self.close(drain=exc_type is None)

    def stats(self) -> dict:
        """What was played: ``frames_pushed``, ``frames_played``, ``device_frames`` (sim and
        silence), ``underflows`` (gaps, counted by the player), ``behind_s`` (their total
        length), ``portaudio_underflows`` (PortAudio's flags), ``clipped`` (samples),
        ``latency_s`` (the stream's), ``lead_s``."""
        with self._lock:
            gaps = list(self._gaps)
            if self._gap_open is not None:
                s, f0 = self._gap_open
                gaps.append((s, f0, self._frames_out - f0))
            return dict(frames_pushed=int(self._w), frames_played=int(self._r), device_frames=int(self._frames_out),
                        underflows=len(gaps), behind_s=sum(g for _, _, g in gaps) / self.sample_rate,
                        gaps=[(int(s), int(g)) for s, _, g in gaps], portaudio_underflows=int(self._pa_underflows),
                        clipped=int(self._clipped), latency_s=self.latency_s,
                        lead_s=self.lead / self.sample_rate, sample_rate=self.sample_rate)

    def timing(self) -> dict:
        """Timing logs for measurement: ``callbacks`` (n, 4): sim frame at the callback's
        start, sim frames it played, PortAudio's DAC time of its first frame and its current
        time [s]; ``pushes`` (n, 2): ``time.monotonic()`` after each push [s] and the sim
        frames pushed by then. PortAudio's times on Linux are ``CLOCK_MONOTONIC``, as
        ``time.monotonic`` is."""
        return dict(callbacks=self._cb_log[:self._n_cb].copy(), pushes=self._push_log[:self._n_push].copy())
