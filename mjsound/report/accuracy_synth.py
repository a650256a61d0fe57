r"""Accuracy of the synthesis against its run time (the accuracy report's synthesis section).

Synthesis
---------
A bowl model (hex, default quality, 48 kHz) struck 20 times; every variant (float32 state,
culling thresholds, fewer modes, f_max) is compared with the float64, no-culling render of
the same events: error = RMS(y - y_ref) / RMS(y_ref) in dB, against ns per mode-sample.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .accuracy_modal import ALU

__all__ = ["run_synth"]


def _synth_model(quick):
    from ..modal.analyze import analyze

    t0 = time.perf_counter()
    m = analyze("bowl:0.1,0.004", ALU, method="hex", quality="draft" if quick else "default", sample_rate=48000,
                error_estimate=False)
    return m, time.perf_counter() - t0


def _render(model, events, dur, fs=48000, block=1024, repeats=1, **kw):
    """Render the events; returns (audio (n,), best wall time [s], modes run)."""
    from ..synth.synthesizer import Synthesizer

    best = float("inf")
    y = None
    n_modes = 0
    for _ in range(repeats):
        syn = Synthesizer(fs, microphones=[[0.0, -0.5, 0.2]], **kw)
        syn.add_object("bowl", model)
        n_modes = syn.n_modes("bowl")
        P, J, T = events
        syn.impacts("bowl", P, J, T, pulse_s=5e-5)
        n = int(dur * fs)
        out = np.zeros(n, np.float32)
        t0 = time.perf_counter()
        for a in range(0, n, block):
            out[a: a + block] = syn.render(min(block, n - a))[0]
        best = min(best, time.perf_counter() - t0)
        y = out
    return y.astype(np.float64), best, n_modes


def _err_db(y, ref):
    num = np.sqrt(np.mean((y - ref) ** 2))
    den = np.sqrt(np.mean(ref**2))
    return 20 * math.log10(max(num, 1e-300) / den) if den > 0 else float("nan")


def run_synth(quick, log):
    model, t_an = _synth_model(quick)
    rng = np.random.default_rng(1)
    k = 20
    idx = rng.integers(0, len(model.points), k)
    P = np.asarray(model.points, float)[idx]
    J = -np.asarray(model.normals, float)[idx] * rng.uniform(1e-3, 1e-2, (k, 1))
    T = np.sort(rng.uniform(0, 1.0, k))
    T[0] = 0.0
    ev = (P, J, T)
    dur = 1.0 if quick else 3.0
    rep = 1 if quick else 3
    _render(model, ev, 0.05)  # JIT / warm
    ref, t_ref, n_all = _render(model, ev, dur, dtype="float64", cull_db=None, repeats=rep)
    rows = []

    def add(label, knob, y, t, n_run):
        ns = 1e9 * t / (n_all * len(ref))
        rows.append({"label": label, "knob": knob, "err_db": _err_db(y, ref), "ns_per_mode_sample": ns,
                     "wall_s": t, "modes_run": n_run, "peak_err_db": 20 * math.log10(
                         max(np.max(np.abs(y - ref)), 1e-300) / np.max(np.abs(ref)))})
        log(f"  synth {label:28s} err {rows[-1]['err_db']:8.1f} dB  {ns:6.3f} ns/mode-sample")

    add("float64, no culling (reference)", "reference", ref, t_ref, n_all)
    for dt in ("float32", "float64"):
        if dt == "float32":
            y, t, n = _render(model, ev, dur, dtype=dt, cull_db=None, repeats=rep)
            add("float32, no culling", "dtype", y, t, n)
        for c in ((-60.0, -100.0) if quick else (-60.0, -80.0, -100.0, -120.0)):
            y, t, n = _render(model, ev, dur, dtype=dt, cull_db=c, repeats=rep)
            add(f"{dt}, cull {c:.0f} dB", f"cull_{dt}", y, t, n)
    for nm in ((32,) if quick else (128, 64, 32, 16, 8)):
        if nm >= n_all:
            continue
        y, t, n = _render(model.truncated(n_modes=nm), ev, dur, dtype="float32", cull_db=-100.0, repeats=rep)
        add(f"lowest {nm} modes (float32, -100 dB)", "modes", y, t, n)
    for fm in ((5000.0,) if quick else (2500.0, 5000.0, 10000.0)):
        y, t, n = _render(model, ev, dur, dtype="float32", cull_db=-100.0, repeats=rep, f_max=fm)
        add(f"synth f_max {fm:.0f} Hz (float32, -100 dB)", "f_max", y, t, n)
    return {"rows": rows, "n_modes": n_all, "analysis_s": t_an, "duration_s": dur, "events": k,
            "model": f"bowl:0.1,0.004 aluminium, hex {'draft' if quick else 'default'}, {n_all} modes to 21.6 kHz"}
