"""A private audio device that records what it is played, at real-time pace (no sound card):
how ``tests/test_live.py`` and ``scripts/live_timing.py`` check live playback, and a way to
run ``mjsound view`` on a headless machine (docs/live.md).

A PulseAudio server of our own with a null sink (its clock is the wall clock), a silent
keep-alive stream (without it new streams stall 0.2-1.8 s), and an ALSA ``livetap`` PCM that
writes what it is given to a WAV file and passes it on to the server. The variables of
:attr:`PulseTap.env` must be set before ``sounddevice`` is imported (PortAudio reads the
ALSA configuration once): run the code under test in a subprocess with them. Open the
device by name (``livetap``): ``default`` is re-pointed at PulseAudio by libasound2-plugins.

The tap writes the stream's own sample format: float32 data under a header that says
32-bit PCM; :func:`read_tap` reads it as such.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time

import numpy as np

__all__ = ["PulseTap", "read_tap", "align"]

NEEDED = ("pulseaudio", "pacat")


class PulseTap:
    """Start with :meth:`start` (about 3 s), stop with :meth:`stop`; ``directory`` holds the
    server socket, the ALSA configuration and one recording per tap: ``NAME.wav`` for each
    ALSA device name in ``names`` (:attr:`wav`: the first one's)."""

    def __init__(self, directory, names=("livetap",)):
        self.dir = os.fspath(directory)
        self.names = tuple(names)
        self.wav = self.wav_of(self.names[0])
        self.procs = []
        # the clients' environment (their HOME, so caches stay where they are) and the server's
        self.env = dict(os.environ, PULSE_RUNTIME_PATH=self.dir, PULSE_SERVER=f"unix:{self.dir}/native",
                        ALSA_CONFIG_PATH=f"/usr/share/alsa/alsa.conf:{self.dir}/asound.conf")
        self.server_env = dict(self.env, HOME=self.dir)

    def wav_of(self, name: str) -> str:
        """The recording of the tap ``name``."""
        return os.path.join(self.dir, f"{name}.wav")

    def start(self) -> "PulseTap":
        missing = [t for t in NEEDED if shutil.which(t) is None]
        if missing:
            raise RuntimeError(f"{', '.join(missing)} not found: apt-get install -y --no-install-recommends "
                               "libportaudio2 pulseaudio pulseaudio-utils libasound2-plugins xvfb xauth (as .ci/run does)")
        with open(os.path.join(self.dir, "asound.conf"), "w") as f:
            for name in self.names:
                f.write(f'pcm.{name} {{\n  type file\n  slave.pcm "pulse"\n'
                        f'  file "{self.wav_of(name)}"\n  format "wav"\n  truncate true\n'
                        '  hint { show on description "file tap -> pulse null sink" }\n}\n')
        server = subprocess.Popen(
            ["pulseaudio", "-n", "--daemonize=no", "--exit-idle-time=-1", "--disallow-exit=yes", "--use-pid-file=no",
             "--system=no", "--disable-shm=yes",
             "-L", f"module-native-protocol-unix socket={self.dir}/native auth-anonymous=1",
             "-L", "module-null-sink sink_name=nullsink rate=48000 channels=2 format=s16le",
             "-L", "module-always-sink"],
            env=self.server_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.procs.append(server)
        deadline = time.monotonic() + 10
        while not os.path.exists(os.path.join(self.dir, "native")):
            if server.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError("the private PulseAudio server did not start")
            time.sleep(0.05)
        with open("/dev/zero", "rb") as zeros:  # (silence, endlessly)
            keep_alive = subprocess.Popen(
                ["pacat", "-p", "--raw", "--rate=48000", "--channels=2", "--format=s16le", "--latency-msec=10"],
                env=self.server_env, stdin=zeros, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.procs.append(keep_alive)
        time.sleep(2.5)  # (measured: the first stream is late without it)
        if keep_alive.poll() is not None:
            self.stop()
            raise RuntimeError("pacat (the keep-alive stream) ended: the PulseAudio server is not usable")
        return self

    def stop(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(5)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        self.procs = []


def read_tap(path) -> tuple[np.ndarray, int]:
    """The samples the tap recorded: ``(frames, channels)`` float32 and the sample rate.

    The ALSA file plugin writes the stream's float32 data under a WAV header that says
    32-bit PCM, so the header's format code is not trusted: its ``fmt`` gives the channels
    and rate, its ``data`` chunk (whose size may be unset) the samples."""
    raw = open(path, "rb").read()
    if raw[:4] != b"RIFF" or raw[8:12] != b"WAVE":
        raise ValueError(f"{path}: not a WAV file")
    pos, channels, rate, bits, data = 12, None, None, None, None
    while pos + 8 <= len(raw):
        tag, size = raw[pos:pos + 4], int.from_bytes(raw[pos + 4:pos + 8], "little")
        body = pos + 8
        if tag == b"fmt ":
            channels = int.from_bytes(raw[body + 2:body + 4], "little")
            rate = int.from_bytes(raw[body + 4:body + 8], "little")
            bits = int.from_bytes(raw[body + 14:body + 16], "little")
        elif tag == b"data":
            end = len(raw) if size in (0, 0xFFFFFFFF) or body + size > len(raw) else body + size
            data = raw[body:end]
            break
        pos = body + size + (size & 1)
    if bits != 32 or data is None:
        raise ValueError(f"{path}: expected 32-bit samples and a data chunk (the tap of a float32 stream)")
    n = len(data) // (4 * channels)
    return np.frombuffer(data[:n * 4 * channels], "<f4").reshape(n, channels), rate


def align(played: np.ndarray, sent: np.ndarray) -> tuple[int, float]:
    """Offset ``k`` (frames) at which ``sent`` (n, ch) best matches ``played[k:k + n]``, and
    the match there: the normalised cross-correlation of the first channel,

    .. math:: \\rho_k = \\frac{\\sum_i p_{k+i} s_i}{\\sqrt{\\sum_i p_{k+i}^2 \\sum_i s_i^2}} \\le 1,

    1 exactly where ``played`` holds a multiple of ``sent`` (Cauchy-Schwarz; unnormalised,
    a loud stretch elsewhere can win)."""
    a, b = played[:, 0].astype(np.float64), sent[:, 0].astype(np.float64)
    if len(a) < len(b) or not np.any(b):
        return 0, 0.0
    nfft = 1 << int(np.ceil(np.log2(len(a) + len(b))))
    xc = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)[:len(a) - len(b) + 1]
    c = np.concatenate([[0.0], np.cumsum(a * a)])
    energy = (c[len(b):] - c[:len(a) - len(b) + 1]) * np.dot(b, b)
    rho = np.where(energy > 0, xc / np.sqrt(np.maximum(energy, 1e-300)), 0.0)
    k = int(np.argmax(rho))
    return k, float(rho[k])
