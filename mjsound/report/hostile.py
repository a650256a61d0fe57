r"""Hostile inputs and interruptions: each case runs ``mjsound`` in a child process and records
its outcome and its memory high-water mark.

Every case runs through a small monitor process (``MONITOR`` in ``mjsound/report/hostile.py``) that starts the command as
its only child, optionally sends it a signal once its temporary output has grown past a size,
and reports the child's exit status, the peak resident memory of the child
(``getrusage(RUSAGE_CHILDREN).ru_maxrss``, so each case is measured alone) and the
temporary files left in the output directory.

Pass criteria
-------------
* a refused input exits with status 2 and one ``error:`` line naming it (no traceback),
  before any analysis or simulation: its wall time is the interpreter start and imports, its
  peak memory that of a bare start;
* an interrupted take (Ctrl-C, SIGTERM) exits 130 / 143 and leaves the earlier files of the
  same name untouched and no temporary file; a killed one (SIGKILL) leaves its temporary file,
  which the next run into that directory removes;
* a streamed take's peak memory does not grow with its duration (the long take may exceed the
  short one by less than half of its audio held as float32);
* a batch driver (the local process pool of ``sonify-batch``) killed with SIGKILL takes its
  workers with it within seconds.
"""

from __future__ import annotations

import io
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
import zipfile

import numpy as np

__all__ = ["run_hostile_cases", "to_markdown", "MONITOR"]

#: Runs ``argv`` as a child: ``monitor.py DIR SIGNAL MIN_BYTES -- ARGV...``; prints one JSON line.
MONITOR = r"""
import json, os, resource, signal, subprocess, sys, time
d, sig, min_bytes = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
argv = sys.argv[5:]
def sigint_default():  # a background start (cmd &) ignores SIGINT, and children inherit it
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=sigint_default)
def temps():
    return [n for n in os.listdir(d) if n.startswith(".mjsound-tmp-")]
if sig:
    t_end = time.monotonic() + 600
    while p.poll() is None and time.monotonic() < t_end:
        if any(os.path.getsize(os.path.join(d, n)) >= min_bytes for n in temps() if os.path.exists(os.path.join(d, n))):
            p.send_signal(sig)
            break
        time.sleep(0.02)
err = p.communicate()[1]
print(json.dumps({"code": p.returncode, "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
                  "stderr": err[-2000:], "temps": temps()}))
"""


class HostileRow:
    def __init__(self, case, inp, ok, outcome, peak_mb, seconds):
        self.case, self.inp, self.ok, self.outcome = case, inp, bool(ok), outcome
        self.peak_mb, self.seconds = peak_mb, seconds


def _monitor(argv, d, sig=0, min_bytes=0, preexec=None, env=None):
    t0 = time.perf_counter()
    cmd = [sys.executable, "-c", MONITOR, str(d), str(int(sig)), str(int(min_bytes)), "--", *map(str, argv)]
    r = subprocess.run(cmd, capture_output=True, text=True, preexec_fn=preexec, env=env, timeout=1800)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out["seconds"] = time.perf_counter() - t0
    return out


def _mjsound(*args):
    return [sys.executable, "-m", "mjsound.cli", *map(str, args)]


#: A stand-in batch driver: a process pool set up as ``sonify-batch`` sets it up, one worker busy.
DRIVER = r"""
import os, sys, time, multiprocessing
from concurrent.futures import ProcessPoolExecutor
from mjsound.batch import _init_local_worker

def busy(path):
    with open(path, "w") as fh:
        fh.write(str(os.getpid()))
    time.sleep(600)

if __name__ == "__main__":
    ex = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=_init_local_worker,
                             initargs=({}, os.getpid()))
    ex.submit(busy, sys.argv[1])
    time.sleep(600)
"""


def _batch_driver_killed(tmp) -> HostileRow:
    script, marker = os.path.join(tmp, "driver.py"), os.path.join(tmp, "worker.pid")
    with open(script, "w") as fh:
        fh.write(DRIVER)
    t0 = time.perf_counter()
    driver = subprocess.Popen([sys.executable, script, marker], cwd=tmp)
    t_end = time.monotonic() + 120
    while not (os.path.exists(marker) and open(marker).read()) and time.monotonic() < t_end:
        time.sleep(0.05)
    worker = int(open(marker).read())
    with open(f"/proc/{driver.pid}/status") as fh:  # the driver's high-water mark, just before the kill
        peak = next(int(line.split()[1]) for line in fh if line.startswith("VmHWM")) / 1024
    driver.kill()
    driver.wait()
    t_kill = time.monotonic()

    def alive():
        try:
            with open(f"/proc/{worker}/stat") as fh:
                return fh.read().split(")")[-1].split()[0] != "Z"
        except OSError:
            return False

    while alive() and time.monotonic() - t_kill < 30:
        time.sleep(0.05)
    gone = not alive()
    return HostileRow("batch driver killed", "SIGKILL to the sonify-batch driver, a worker busy", gone,
                      f"worker {'gone' if gone else 'STILL RUNNING'} {time.monotonic() - t_kill:.2f} s after the kill",
                      peak, time.perf_counter() - t0)


def _first_error(stderr):
    for line in stderr.splitlines():
        if "error:" in line or "interrupted" in line:
            return line.split("error:", 1)[-1].strip()
    return stderr.strip().splitlines()[-1] if stderr.strip() else ""


def _refused(case, inp, argv, d, expect, env=None, preexec=None):
    r = _monitor(argv, d, env=env, preexec=preexec)
    msg = _first_error(r["stderr"])
    ok = r["code"] == 2 and "Traceback" not in r["stderr"] and expect in msg and not r["temps"]
    short = msg if len(msg) <= 150 else msg[:147] + "..."
    return HostileRow(case, inp, ok, f"exit {r['code']}: {short}", r["peak_mb"], r["seconds"])


def _bomb(path, frames, nq, nv):
    """An .npz whose array headers claim ``frames`` frames (the data is not there)."""
    with zipfile.ZipFile(path, "w") as zf:
        for name, width in (("time", None), ("qpos", nq), ("qvel", nv)):
            buf = io.BytesIO()
            shape = (frames,) if width is None else (frames, width)
            np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
            zf.writestr(name + ".npy", buf.getvalue() + b"\0" * 64)


def run_hostile_cases(quick: bool = False, log=print, scene=None) -> list:
    """Run every hostile-input and interruption case; returns :class:`HostileRow` rows.

    ``scene``: the MJCF scene for the takes (default: the built-in demo scene, analysed at
    draft quality and cached on the first run).
    """
    from ..sim.demo import find_demo_scene

    scene = scene or find_demo_scene()
    rows = []
    with tempfile.TemporaryDirectory(prefix="mjsound-hostile-") as tmp:
        d = os.path.join(tmp, "out")
        os.makedirs(d)
        wav = os.path.join(d, "take.wav")

        def add(row):
            rows.append(row)
            log(f"{'PASS' if row.ok else 'FAIL'}  {row.case}: {row.inp} -> {row.outcome} "
                f"[{row.peak_mb:.0f} MB, {row.seconds:.1f} s]")

        for rate in ("1", "100", "10000000"):
            add(_refused("sample rate", f"sonify --sample-rate {rate}",
                         _mjsound("sonify", scene, "--sample-rate", rate, "-o", wav), d, "1000..768000"))
        for dur in ("inf", "nan", "-5", "1e7"):
            add(_refused("duration", f"sonify --duration {dur}",
                         _mjsound("sonify", scene, "--duration", dur, "-o", wav), d, "duration="))
        add(_refused("timestep", "sonify --timestep 1e-12",
                     _mjsound("sonify", scene, "--timestep", "1e-12", "-o", wav), d, "timestep=1e-12"))
        add(_refused("output type", "sonify -o x.mp3", _mjsound("sonify", scene, "-o", os.path.join(d, "x.mp3")), d,
                     "not supported"))
        add(_refused("output is a directory", "sonify -o DIR", _mjsound("sonify", scene, "-o", d), d, "is a directory"))
        a_file = os.path.join(tmp, "a_file")
        open(a_file, "w").close()
        add(_refused("batch output is a file", "sonify-batch -o FILE",
                     _mjsound("sonify-batch", tmp, "--scene", scene, "-o", a_file), d, "is a file"))
        add(_refused("materials", "--materials '[\"steel\"]'",
                     _mjsound("sonify", scene, "--materials", '["steel"]', "-o", wav), d, "JSON list"))
        deep = os.path.join(tmp, "deep.json")
        with open(deep, "w") as fh:
            fh.write("[" * 100000 + "]" * 100000)
        add(_refused("deep JSON", "100 000-deep events file", _mjsound("render-events", deep, "-o", wav), d,
                     "nested too deeply"))
        junk = os.path.join(tmp, "junk.json")
        with open(junk, "wb") as fh:
            fh.write(bytes(range(128, 256)) * 64)
        add(_refused("junk events file", "8 KB of non-UTF-8 bytes", _mjsound("render-events", junk, "-o", wav), d,
                     "junk.json"))
        ev = os.path.join(tmp, "long.json")
        with open(ev, "w") as fh:
            json.dump({"duration": 1e9, "objects": [{"name": "a", "mesh": "box:0.1,0.1,0.1", "material": "steel"}]}, fh)
        add(_refused("events duration", "duration 1e9 s", _mjsound("render-events", ev, "-o", wav), d, "one day"))
        ns = os.path.join(tmp, "ns.npz")
        import mujoco

        m = mujoco.MjModel.from_xml_path(scene)
        np.savez(ns, time=np.array([0.0, 1e9]), qpos=np.tile(m.qpos0, (2, 1)), qvel=np.zeros((2, m.nv)))
        add(_refused("rollout in nanoseconds", "time spans [0, 1e9] s",
                     _mjsound("sonify", scene, "--rollout", ns, "-o", wav), d, "milliseconds or nanoseconds"))
        bomb = os.path.join(tmp, "bomb.npz")
        _bomb(bomb, 10**9, m.nq, m.nv)
        add(_refused("inflating rollout", f"npz headers claim 1e9 frames of {m.nq} + {m.nv} + 1 numbers",
                     _mjsound("sonify", scene, "--rollout", bomb, "-o", wav), d, "GB of memory"))

        def fsize():
            resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 20, 1 << 20))

        add(_refused("full disk", "file size limit 1 MiB (EFBIG), 30 s take",
                     _mjsound("sonify", scene, "--quality", "draft", "--duration", "30", "-o", wav), d,
                     "cannot write the audio file", preexec=fsize))

        # ---------------------------------------------------------------- interruptions
        rrd = os.path.join(d, "take.rrd")
        for sig, code, name in ((signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")):
            with open(wav, "wb") as fh:
                fh.write(b"earlier take")
            with open(rrd, "wb") as fh:
                fh.write(b"earlier recording")
            r = _monitor(_mjsound("sonify", scene, "--quality", "draft", "--duration", "600", "-o", wav, "--rrd", rrd),
                         d, sig=sig, min_bytes=1 << 20)
            kept = open(wav, "rb").read() == b"earlier take" and open(rrd, "rb").read() == b"earlier recording"
            ok = r["code"] == code and kept and not r["temps"]
            why = "" if ok else f" ({_first_error(r['stderr'])[:200]})"
            add(HostileRow("interrupted take", f"{name} during a 600 s take with --rrd", ok,
                           f"exit {r['code']}; earlier WAV and rrd {'kept' if kept else 'LOST'}; "
                           f"{len(r['temps'])} temp file(s) left{why}", r["peak_mb"], r["seconds"]))
        os.unlink(rrd)
        r = _monitor(_mjsound("sonify", scene, "--quality", "draft", "--duration", "600", "-o", wav), d,
                     sig=signal.SIGKILL, min_bytes=1 << 20)
        left = len(r["temps"])
        r2 = _monitor(_mjsound("sonify", scene, "--quality", "draft", "--duration", "0.1", "-o", wav), d)
        ok = r["code"] == -signal.SIGKILL and left == 1 and r2["code"] == 0 and not r2["temps"]
        add(HostileRow("killed take", "SIGKILL during a 600 s take, then a 0.1 s take into the same directory", ok,
                       f"{left} temp file left by the kill; {len(r2['temps'])} after the next run", r["peak_mb"],
                       r["seconds"] + r2["seconds"]))

        if sys.platform.startswith("linux"):
            add(_batch_driver_killed(tmp))

        # ---------------------------------------------------------------- streamed takes
        fs = 96000
        peaks = {}
        for dur in ((5, 60) if quick else (10, 600)):
            r = _monitor(_mjsound("sonify", scene, "--quality", "draft", "--duration", dur, "--sample-rate", fs,
                                  "-o", wav), d)
            peaks[dur] = r
        (s, rs), (l, rl) = sorted(peaks.items())
        held_mb = l * fs * 2 * 4 / 2**20  # two microphones, float32
        grow = rl["peak_mb"] - rs["peak_mb"]
        ok = rs["code"] == rl["code"] == 0 and grow < 0.5 * held_mb
        add(HostileRow("long take streamed", f"demo scene {s} s and {l} s at {fs} Hz", ok,
                       f"peak {rs['peak_mb']:.0f} MB and {rl['peak_mb']:.0f} MB (+{grow:.0f} MB; the take is "
                       f"{held_mb:.0f} MB of float32)", rl["peak_mb"], rs["seconds"] + rl["seconds"]))
    return rows


def to_markdown(rows) -> str:
    """The hostile-input table (Markdown)."""
    L = ["| result | case | input | outcome | peak memory MB | s |", "|---|---|---|---|---:|---:|"]
    for r in rows:
        L.append(f"| {'PASS' if r.ok else '**FAIL**'} | {r.case} | {r.inp} | {r.outcome.replace('|', '/')} | "
                 f"{r.peak_mb:.0f} | {r.seconds:.1f} |")
    n_fail = sum(not r.ok for r in rows)
    L += ["", f"{len(rows) - n_fail} of {len(rows)} cases pass."]
    return "\n".join(L) + "\n"
