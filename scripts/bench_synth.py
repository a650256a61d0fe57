#!/usr/bin/env python
"""Benchmark of the synthesis engine (issue 3, "Speed").

Prints
* ns per mode-sample for 1000 active modes at 48 kHz, one thread, float32 and float64
  (the bare kernel, and through ``Synthesizer.render``);
* the time for 100 impacts on ten-mode objects, each rendered as its own 1 s clip
  (one Synthesizer reused with ``reset()``: add-impact-render per clip);
* ns per (mode-sample of all modes) with 10 objects x 500 modes of which 90 % have decayed
  (culled), i.e. what decayed modes cost.

``--json`` prints one JSON object instead.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from mjsound import ModalModel, get_material  # noqa: E402
from mjsound.synth import kernels  # noqa: E402
from mjsound.synth.synthesizer import Synthesizer  # noqa: E402

FS = 48000


def model(n, seed=0, decay=None):
    rng = np.random.default_rng(seed)
    f = np.sort(rng.uniform(100, 20000, n))
    d = np.full(n, 2.0) if decay is None else decay
    return ModalModel(f, d, rng.normal(size=(8, 3)) * 0.05, np.tile([0, 0, 1.0], (8, 1)),
                      rng.normal(size=(8, 3, n)), np.ones(n), get_material("steel"), mass_kg=0.5)


def best(fn, repeat=5):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def bare_kernel(dtype, n_modes=1000, n=FS):
    dt = np.dtype(dtype)
    rng = np.random.default_rng(0)
    w = rng.uniform(100, 20000, n_modes) * 2 * np.pi / FS
    p = np.exp(-1e-5 + 1j * w)
    pr, pi = p.real.astype(dt), p.imag.astype(dt)
    wr = rng.normal(size=n_modes).astype(dt)
    wi = rng.normal(size=n_modes).astype(dt)
    out = np.zeros(n, dt)
    kernels.bank_free((wr, wi, pr, pi), n_modes, out, 0, 16, dt.type(0))
    return best(lambda: kernels.bank_free((wr, wi, pr, pi), n_modes, out, 0, n, dt.type(0))) / (n * n_modes) * 1e9


def synth_dense(dtype, n_modes=1000, seconds=1.0):
    syn = Synthesizer(FS, dtype=dtype, cull_db=None)
    m = model(n_modes, decay=np.full(n_modes, 0.01))
    syn.add_object("o", m)
    syn.impact("o", m.points[0], [0.3, 0.2, 0.1], 0.0)
    syn.render(4800)  # compile + start
    n = int(seconds * FS)
    block = 480
    t = best(lambda: [syn.render(block) for _ in range(n // block)], repeat=3)
    return t / (n * n_modes) * 1e9, syn.active_modes("o")


def impacts_100():
    syn = Synthesizer(FS)
    models = [model(10, seed=i) for i in range(100)]
    for i, m in enumerate(models):
        syn.add_object(f"o{i}", m, position=(0.1 * i, 0, 0))
    # warm up
    syn.impact("o0", models[0].points[0], [0, 0, 0.01], 0.0)
    syn.render(FS)

    def run():
        for i, m in enumerate(models):
            syn.reset()
            syn.impact(f"o{i}", m.points[i % 8], [0, 0, 0.01], 0.0)
            clip = syn.render(FS)
            assert clip.shape == (1, FS)

    return best(run, repeat=3)


def decayed_90():
    """10 objects x 500 modes; 90 % of modes decay fast and are culled. Time per
    (total mode x sample) over 1 s of rendering after the decay."""
    syn = Synthesizer(FS)
    n = 500
    for i in range(10):
        rng = np.random.default_rng(100 + i)
        d = np.where(rng.uniform(size=n) < 0.9, 2000.0, 0.5)  # 90 % die within ~20 ms
        m = model(n, seed=100 + i, decay=d)
        syn.add_object(f"o{i}", m)
        syn.impact(f"o{i}", m.points[0], [0.2, 0.1, 0.3], 0.0)
    syn.render(FS // 5)  # let the fast modes decay (~ -170 dB) and be culled
    active = sum(syn.active_modes(f"o{i}") for i in range(10))
    t = best(lambda: [syn.render(480) for _ in range(100)], repeat=3)
    return t / (FS * 10 * n) * 1e9, active


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    r = {}
    r["ns_per_mode_sample_f32"] = bare_kernel("float32")
    r["ns_per_mode_sample_f64"] = bare_kernel("float64")
    r["render_ns_per_mode_sample_f32"], _ = synth_dense("float32")
    r["render_ns_per_mode_sample_f64"], _ = synth_dense("float64")
    r["impacts_100_seconds"] = impacts_100()
    r["decayed_90pct_ns_per_mode_sample"], r["decayed_90pct_active_modes"] = decayed_90()
    r["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus"
    if args.json:
        print(json.dumps(r))
        return
    print(f"1000 modes, 48 kHz, bare kernel:  float32 {r['ns_per_mode_sample_f32']:.3f} ns/mode-sample, "
          f"float64 {r['ns_per_mode_sample_f64']:.3f}")
    print(f"1000 modes through render (480-sample blocks): float32 {r['render_ns_per_mode_sample_f32']:.3f}, "
          f"float64 {r['render_ns_per_mode_sample_f64']:.3f} ns/mode-sample")
    print(f"100 impacts on ten-mode objects as 1 s clips: {r['impacts_100_seconds'] * 1e3:.1f} ms")
    print(f"10 objects x 500 modes, 90 % decayed ({r['decayed_90pct_active_modes']} active): "
          f"{r['decayed_90pct_ns_per_mode_sample']:.3f} ns per mode-sample of all modes")


if __name__ == "__main__":
    main()
