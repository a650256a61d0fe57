"""Measuring one report point: the machine, and a call in a forked child process with its wall
time and peak memory (:func:`measure`)."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import traceback

import numpy as np

__all__ = ["machine_info", "measure", "cents"]


def cents(f, ref):
    """1200 log2(f / ref)."""
    return 1200.0 * np.log2(np.asarray(f, float) / np.asarray(ref, float))


# ---------------------------------------------------------------------------- machine
def machine_info() -> dict:
    import scipy

    info = {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "load_start": [round(x, 2) for x in os.getloadavg()],
    }
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["processor"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    for mod in ("skfem", "numba", "mujoco", "matplotlib", "tetgen"):
        try:
            m = __import__(mod)
            info[mod] = getattr(m, "__version__", "?")
        except Exception:
            info[mod] = "not installed"
    from ..modal.eigen import backend_name

    info["sparse_backend"] = backend_name()
    return info


# ---------------------------------------------------------------------------- measuring
def _status_kb(field):
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def _child(conn, fn, args):
    import resource

    rss0 = _status_kb("VmRSS")
    reset = False
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")  # reset VmHWM to the current RSS
        reset = True
    except OSError:
        pass
    maxrss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    try:
        out = fn(*args)
        err = None
    except BaseException as exc:  # report, never hang the parent
        out, err = None, f"{type(exc).__name__}: {exc}"
        tb = traceback.format_exc(limit=3)
        err += " | " + tb.strip().splitlines()[-1] if tb else ""
    hwm = _status_kb("VmHWM")
    if reset and hwm is not None and rss0 is not None:
        peak_mb = (hwm - rss0) / 1024
    else:
        peak_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - maxrss0) / 1024
    conn.send({"out": out, "error": err, "peak_mb": peak_mb})
    conn.close()


def measure(fn, args=(), timeout=300.0) -> dict:
    """Run ``fn(*args)`` in a forked child; ``{"out", "error", "peak_mb", "timeout"}``.

    ``fn`` times itself (the result should carry its wall time); the child's peak memory
    is measured around the call.
    """
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    a, b = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(b, fn, args), daemon=True)
    p.start()
    b.close()
    res = None
    if a.poll(timeout):
        try:
            res = a.recv()
        except EOFError:
            res = None
    if res is None:
        timed_out = p.is_alive()
        if timed_out:
            p.kill()
        p.join(5)
        return {"out": None, "error": "timeout" if timed_out else f"child died (exit {p.exitcode})",
                "peak_mb": float("nan"), "timeout": timed_out}
    p.join(10)
    res["timeout"] = False
    return res
