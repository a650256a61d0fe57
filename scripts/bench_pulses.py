#!/usr/bin/env python
"""Cost of rendering band-limited impact pulses (``mjsound.synth.bandlimited``), benchmark.

Times, per call of the compiled kernels (wall microseconds, the median of ``--rounds`` rounds
of ``--calls`` calls each, alternated so that machine load hits both alike):

* ``fft_recomputed_us``: :func:`fft_inplace` of ``--n`` points, which computes its ``n - 1``
  twiddle factors on every call (the baseline);
* ``fft_table_us``: :func:`fft_with` with a kept table (:func:`twiddles`), as the pulse track
  renders; ``fft_ratio`` = table / recomputed, and whether both give the same bits;
* ``render_pulses_us``: the pulse track's kernel on two pulses whose window is ``--n``
  samples (Ant-v5's impacts at 16 kHz mostly have 256-sample windows).

Usage: python scripts/bench_pulses.py [--n 256] [--calls 5000] [--rounds 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def _per_call(fn, args, calls: int) -> float:
    t = time.perf_counter()
    for _ in range(calls):
        fn(*args)
    return (time.perf_counter() - t) / calls * 1e6


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=256, help="transform length, a power of two (default 256)")
    p.add_argument("--calls", type=int, default=5000)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    if args.n < 2 or args.n & (args.n - 1):
        p.error(f"--n {args.n}: a power of two >= 2")
    from numba import typeof

    from mjsound.synth import bandlimited as bl

    fs = 16000.0
    x = np.random.default_rng(0).standard_normal(args.n) + 0j
    table = bl.twiddles(args.n, True)
    a, b = x.copy(), x.copy()
    bl.fft_inplace(a, True)
    bl.fft_with(b, table, True)
    same_bits = bool(np.array_equal(a, b))

    # two pulses whose window is args.n samples: a short pulse ringing for the rest of it
    pulses = np.zeros(2, bl.PULSE_DTYPE)
    pulses["time_s"], pulses["tau_s"], pulses["b0"], pulses["channel"] = [0.1, 0.1003], 2e-4, 1.0, 0
    pulses["d1"] = max((0.7 * args.n - bl.LEAD - bl.TAIL) / fs / bl.RING_TIME_CONSTANTS, 0.0)
    dv = np.array([0.3, 0.2])
    n_window, _ = bl.pulse_extent(pulses, dv, len(pulses), fs)
    track = bl.PulseTrack(1, fs)
    track.add_trusted(pulses, dv)  # (grows the track's ring and scratch to the window; compiles)
    call = (track.state, pulses, dv, len(pulses))
    render = bl.add_pulses.overloads[tuple(typeof(v) for v in call)].entry_point

    rec, tab, ren = [], [], []
    for _ in range(args.rounds):
        rec.append(_per_call(bl.fft_inplace, (x.copy(), True), args.calls))
        tab.append(_per_call(bl.fft_with, (x.copy(), table, True), args.calls))
        ren.append(_per_call(render, call, args.calls))
    res = {"n": args.n, "fft_recomputed_us": float(np.median(rec)), "fft_table_us": float(np.median(tab)),
           "fft_ratio": float(np.median(np.array(tab) / np.array(rec))), "same_bits": same_bits,
           "render_window": int(n_window), "render_pulses_us": float(np.median(ren))}
    if args.json:
        print(json.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k:18s} {v:.3f}" if isinstance(v, float) else f"{k:18s} {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
