"""Interruptions and resource faults (issue 17): Ctrl-C / SIGTERM / SIGKILL during a take, a
killed batch driver, a full disk, and memory that does not grow with a streamed take.

Each case runs ``mjsound`` in a child process (stub modal models, no analysis)."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from mjsound.io import TEMP_PREFIX
from mjsound.report.hostile import DRIVER
from scenes import PLATE_BALL_XML

XML = PLATE_BALL_XML

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX signals and /proc")

#: ``mjsound ARGS`` with stub modal models (8 modes at 430 Hz...), in a child process.
RUN = """
import sys
import mjsound.modal.analyze as an
from mjsound.sim.stub import stub_model
an.analyze = lambda mesh, material, **kw: stub_model(mesh, material, 8, 430.0)
from mjsound.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _env():
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _temps(d):
    return sorted(n for n in os.listdir(d) if n.startswith(TEMP_PREFIX))


def _sigint_default(then=None):
    """A ``preexec_fn`` that gives the child the default Ctrl-C disposition before ``then``.

    A process started in the background by a non-interactive shell (``cmd &``, as a CI runner
    may start the suite) has SIGINT ignored, and children inherit that: Python then installs no
    KeyboardInterrupt handler and a Ctrl-C test would wait forever."""

    def preexec():
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        if then is not None:
            then()

    return preexec


def _start(args, preexec_fn=None, **kw):
    kw["preexec_fn"] = _sigint_default(preexec_fn)
    return subprocess.Popen([sys.executable, "-c", RUN, *map(str, args)], env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _wait_for_temp(proc, d, min_bytes=100_000, timeout=120.0):
    """Wait until the child's temporary WAV holds ``min_bytes`` (the take is under way)."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        assert proc.poll() is None, proc.communicate()
        for n in _temps(d):
            try:
                if n.endswith(".wav") and os.path.getsize(os.path.join(d, n)) >= min_bytes:
                    return
            except FileNotFoundError:
                pass
        time.sleep(0.05)
    proc.kill()
    raise AssertionError("the take never started")


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupt_keeps_earlier_outputs_and_leaves_no_temp(tmp_path, sig, code):
    (tmp_path / "scene.xml").write_text(XML)
    out, rrd = tmp_path / "take.wav", tmp_path / "take.rrd"
    out.write_bytes(b"earlier good take")
    rrd.write_bytes(b"earlier good recording")
    proc = _start(["sonify", tmp_path / "scene.xml", "--duration", "600", "-o", out, "--rrd", rrd])
    _wait_for_temp(proc, tmp_path)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert out.read_bytes() == b"earlier good take"
    assert rrd.read_bytes() == b"earlier good recording"
    assert _temps(tmp_path) == []


def test_killed_run_leaves_a_temp_that_the_next_run_removes(tmp_path, capsys):
    from mjsound.cli import main

    (tmp_path / "scene.xml").write_text(XML)
    proc = _start(["sonify", tmp_path / "scene.xml", "--duration", "600", "-o", tmp_path / "a.wav"])
    _wait_for_temp(proc, tmp_path)
    proc.kill()
    proc.wait()
    (left,) = _temps(tmp_path)
    assert f"-{proc.pid}-" in left
    # a later run writing into the same directory finds and removes it
    import mjsound.modal.analyze as an
    from mjsound.sim.stub import stub_model

    keep = an.analyze
    an.analyze = lambda mesh, material, **kw: stub_model(mesh, material, 8, 430.0)
    try:
        assert main(["sonify", str(tmp_path / "scene.xml"), "--duration", "0.05", "-o", str(tmp_path / "b.wav")]) == 0
    finally:
        an.analyze = keep
    assert _temps(tmp_path) == [] and not (tmp_path / "a.wav").exists() and (tmp_path / "b.wav").exists()


def test_full_disk_is_a_clear_error(tmp_path):
    """A file-size limit (RLIMIT_FSIZE: writes fail with EFBIG, as on a full disk)."""
    (tmp_path / "scene.xml").write_text(XML)
    out = tmp_path / "a.wav"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    proc = _start(["sonify", tmp_path / "scene.xml", "--duration", "5", "-o", out], preexec_fn=limit)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2, err
    assert "cannot write the audio file" in err and str(out) in err and "Traceback" not in err
    assert not out.exists() and _temps(tmp_path) == []




def test_batch_workers_die_with_their_driver(tmp_path):
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)  # the report's stand-in batch driver
    marker = tmp_path / "worker.pid"
    driver = subprocess.Popen([sys.executable, str(script), str(marker)], env=_env(), cwd=tmp_path)
    t_end = time.monotonic() + 120
    while not (marker.exists() and marker.read_text()) and time.monotonic() < t_end:
        time.sleep(0.05)
    worker = int(marker.read_text())
    driver.kill()  # as the OOM killer does: no clean-up code runs in the driver
    driver.wait()
    t_end = time.monotonic() + 10
    while os.path.exists(f"/proc/{worker}") and time.monotonic() < t_end:
        with open(f"/proc/{worker}/stat") as fh:
            if fh.read().split(")")[-1].split()[0] == "Z":  # a zombie: dead, waiting for a reaper
                break
        time.sleep(0.05)
    assert not os.path.exists(f"/proc/{worker}") or open(f"/proc/{worker}/stat").read().split(")")[-1].split()[0] == "Z"


PEAK = """
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:], capture_output=True, text=True)
print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.stderr.write(r.stderr)
"""


def _peak_rss_mb(args):
    cmd = [sys.executable, "-c", PEAK, sys.executable, "-c", RUN, *map(str, args)]
    r = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=300)
    code, kb = r.stdout.split()
    assert code == "0", r.stderr
    return int(kb) / 1024


def test_streamed_take_memory_does_not_grow_with_duration(tmp_path):
    (tmp_path / "scene.xml").write_text(XML)
    common = ["sonify", tmp_path / "scene.xml", "--sample-rate", "192000", "--json"]
    short = _peak_rss_mb(common + ["--duration", "1", "-o", tmp_path / "s.wav"])
    long = _peak_rss_mb(common + ["--duration", "40", "-o", tmp_path / "l.wav"])
    take_mb = 40 * 192000 * 4 / 2**20  # 29 MiB of float32 samples: held whole, it would be several times that
    assert long - short < 0.5 * take_mb, (short, long)
    import soundfile as sf

    info = sf.info(str(tmp_path / "l.wav"))
    assert info.frames == 40 * 192000
    x, _ = sf.read(str(tmp_path / "l.wav"), frames=192000)
    assert np.abs(x).max() > 0  # the ball's impact is in the first second
