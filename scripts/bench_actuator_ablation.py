#!/usr/bin/env python
"""What each part of the drives' rendering adds to a wrapped env step (benchmark, not a test):
:mod:`bench_actuators`' ratio (env step with a preset on every actuator over the same without,
CPU time, interleaved rounds) with one part of the lines' kernel taken out at a time.

Each variant runs in a process of its own whose numba cache starts empty and whose shipped
kernels are off (``MJSOUND_SHIPPED_KERNELS=0``): a part is taken out by replacing a global of
the kernels' modules before they compile (numba reads a kernel's globals when it compiles it),
so every variant, the full one included, is compiled for this host the same way. Variants:

* ``full``: the drives as shipped;
* ``no-kernel``: the block's kernel (:func:`mjsound.synth.drive_lines.lines_drive`) returns at
  once: what is left is the step's hand-back and the Python around the call;
* ``no-line-samples``: the lines' per-sample lanes (:func:`mjsound.synth.drive_lanes.lines_pass`)
  write nothing: the per-block work (reads, gains, weights, broadband) is left;
* ``no-resonant``: the broadband part never goes through the modes
  (:data:`mjsound.synth.drive_broadband.RESONANT_ON` infinite);
* ``no-directions``: the lines' weights without the links' direction factors
  (:func:`mjsound.synth.drive_weights.direction_factors` does nothing);
* ``per-block-only``: no line samples, no resonant broadband, no direction factors together.

The audio of every variant but ``full`` is wrong on purpose: this apportions the cost, it is
not a rendering option. About 2 minutes per variant here (most of it compiling).

    python scripts/bench_actuator_ablation.py --rounds 8 --steps 100
    python scripts/bench_actuator_ablation.py --variants full no-kernel
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

import bench_actuators  # noqa: E402  (its options and measurement; compiles nothing when imported)

VARIANTS = ("full", "no-kernel", "no-line-samples", "no-resonant", "no-directions", "per-block-only")


def take_out(variant: str) -> None:
    """Replace the globals of the kernels' modules that ``variant`` takes out (before any
    kernel compiles: call first in a fresh process with an empty numba cache)."""
    import math

    from mjsound.jit import njit
    from mjsound.synth import drive_broadband, drive_lines, drive_weights

    parts = {"per-block-only": ("no-line-samples", "no-resonant", "no-directions")}.get(variant, (variant,))
    for part in parts:
        if part == "no-kernel":
            @njit
            def lines_drive(state, k0, L, fs, fresh, resume, regain, F):
                state[8][0] = 0  # (io: DONE)

            drive_lines.lines_drive = lines_drive
        elif part == "no-line-samples":
            @njit
            def lines_pass(acc, first, off0, off1, two, L, S, V, span, n, work):
                pass

            drive_lines.lines_pass = lines_pass
        elif part == "no-resonant":
            drive_broadband.RESONANT_ON = math.inf
        elif part == "no-directions":
            @njit
            def direction_factors(xr, xi, n, o, view, U, Fd, heard):
                pass

            drive_weights.direction_factors = direction_factors
        elif part != "full":
            raise SystemExit(f"bench_actuator_ablation: unknown variant {part!r}; give one of {VARIANTS}")


def child(args) -> None:
    take_out(args.child)
    out = bench_actuators.measure(*(getattr(args, k) for k in bench_actuators.OPTIONS))
    print(json.dumps({"variant": args.child, **out}), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bench_actuators.add_arguments(ap, rounds=8)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args)
    rows = []
    for v in args.variants:
        with tempfile.TemporaryDirectory(prefix="mjsound-ablation-") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, MJSOUND_SHIPPED_KERNELS="0",
                       PYTHONPATH=os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")]))
            cmd = [sys.executable, os.path.abspath(__file__), "--child", v]
            for k in bench_actuators.OPTIONS:
                cmd += ["--" + k.replace("_", "-"), str(getattr(args, k))]
            res = subprocess.run(cmd, env=env, capture_output=True, text=True)
        line = [ln for ln in res.stdout.splitlines() if ln.startswith("{")]
        if res.returncode or not line:
            raise SystemExit(f"bench_actuator_ablation: variant {v} failed:\n{res.stderr[-3000:]}")
        rows.append(json.loads(line[-1]))
        r = rows[-1]
        print(f"{v:16s} ratio {r['ratio']:.3f}  (off {1e3 * r['off_ms']:.0f} us, on {1e3 * r['on_ms']:.0f} us, "
              f"added {1e3 * (r['on_ms'] - r['off_ms']):.0f} us)", flush=True)
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
