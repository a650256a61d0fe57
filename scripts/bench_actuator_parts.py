#!/usr/bin/env python
"""Where the actuators' per-block time goes (benchmark, not a test): a gymnasium env wrapped
in ``AudioObservation`` with a preset on every actuator is stepped with seeded random
actions; then

* **in the env**: the time of each block's drive call (``ActuatorSound.render_due``: the
  kernel call and the Python around it, after the physics step, caches as they are), its
  10th, 25th and 50th percentile over the steps;
* **hot loop**: each part of :func:`mjsound.synth.drive_lines.lines_drive` called ``--n``
  times in a numba loop on the state after the first block past ``--steps`` with a running
  resonant broadband (else the last block), the fastest and the median of 15 repeats [us per call]: the driven
  bodies' gains, the lines' weights with the direction factors made again (their cache
  invalidated each call: every body turned) and with them cached, the housing's part, the
  resonant broadband's modes, its force and its run, the lines' samples and static
  broadband, and the whole block but its read and gains (as a block resumed after the
  pulse track grew), every direction factor made again. The parts write the state as a block does; what they compute is thrown away.

    python scripts/bench_actuator_parts.py                       # Ant-v5, qdd, 16 kHz
    python scripts/bench_actuator_parts.py --env FetchPickAndPlace-v4 --preset servo --sample-rate 48000

Compare two commits in the same session (the machine's load moves every figure).
"""

import argparse
import json
import sys
import time

import numpy as np
from numba import njit

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_actuators import make  # noqa: E402

from mjsound.sim.actuators import ActuatorSound  # noqa: E402
from mjsound.synth.drive_broadband import broadband_force, broadband_modes, broadband_resonant  # noqa: E402
from mjsound.synth.drive_gains import bodies_gains  # noqa: E402
from mjsound.synth.drive_housing import housing_weights  # noqa: E402
from mjsound.synth.drive_lines import lines_drive, lines_render  # noqa: E402
from mjsound.synth.drive_weights import line_weights  # noqa: E402
from mjsound.wrappers import AudioObservation  # noqa: E402


@njit
def _gains(ks, act, bg, anchor, axis, k0, regain, n):
    for _ in range(n):
        bodies_gains(ks, act, bg, anchor, axis, k0, regain)


@njit
def _weights(view, act, lw, bg, fs, fresh_directions, n):
    for _ in range(n):
        if fresh_directions:
            bg.U[:] = np.nan  # (the direction factors' cache: made again)
        line_weights(view, act, lw, bg, fs)


@njit
def _housing(ks, act, lw, anchor, fs, n):
    for _ in range(n):
        housing_weights(ks, act, lw, anchor, fs)


@njit
def _modes(act, lw, bg, n):
    for _ in range(n):
        broadband_modes(act, lw, bg)


@njit
def _force(act, lw, fs, F, n):
    for _ in range(n):
        broadband_force(act, lw, fs, F)


@njit
def _resonant(view, act, lw, bg, track, k0, F, n):
    for _ in range(n):
        broadband_resonant(view, act, lw, bg, track, k0, F, False)


@njit
def _render(track, act, lw, k0, L, fs, F, n):
    for _ in range(n):
        lines_render(track, act, lw, k0, L, fs, F)


@njit
def _block(state, k0, L, fs, regain, F, n):
    bg, io = state[3], state[8]
    for _ in range(n):
        bg.U[:] = np.nan  # (every body turned: its direction factors made again, as Ant's links in most blocks)
        io[4] = 1  # (resumed: the block's read and gains kept, some joint moving)
        lines_drive(state, k0, L, fs, False, True, regain, F)


def timed(fn, *args, n=200, repeats=15):
    """(fastest, median) of ``repeats`` runs of ``fn(*args, n)`` [us per call]."""
    fn(*args, 2)
    runs = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn(*args, n)
        runs.append((time.perf_counter() - t) / n * 1e6)
    return float(np.min(runs)), float(np.median(runs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="Ant-v5")
    ap.add_argument("--preset", default="qdd")
    ap.add_argument("--sample-rate", type=int, default=16000)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--n", type=int, default=200, help="calls per hot-loop run")
    args = ap.parse_args()
    env = AudioObservation(make(args.env), sample_rate=args.sample_rate, sim_kwargs={"actuators": args.preset})
    env.reset(seed=0)
    calls, kept_state = [], {}
    render_due = ActuatorSound.render_due

    def spy(self):
        t = time.perf_counter()
        out = render_due(self)
        calls.append(time.perf_counter() - t)
        kept_state.update(sound=self, due=self._due, lines=self.lines_rendered, kept=self.modes_kept)
        return out

    ActuatorSound.render_due = spy
    rng = np.random.default_rng(0)
    space = env.action_space
    try:  # (then on to a block with modes kept, if one comes within 200 more steps: its state is timed)
        for i, a in enumerate(rng.uniform(space.low, space.high, (args.steps + 200, space.shape[0]))):
            _, _, term, trunc, _ = env.step(a)
            if i + 1 >= args.steps and kept_state.get("kept"):
                break  # (before a reset: the state is that block's)
            if term or trunc:
                env.reset(seed=0)
    finally:
        ActuatorSound.render_due = render_due
    calls = calls[: args.steps]
    if not kept_state:
        raise SystemExit(f"{args.env}: no actuator block was rendered (is the preset heard at {args.sample_rate} Hz?)")
    s = kept_state["sound"]
    k0, L, _ = kept_state["due"]
    synth, d = s._sim.synth, s._sim.data
    state = s._lines_state(synth, d)
    rd, act, lw, bg, view, ks, track, dv, io = state
    fs, regain, F = s._fs, s._regain, s._force
    in_env = 1e6 * np.array(calls[20:] if len(calls) > 40 else calls)
    parts = {
        "gains": timed(_gains, ks, act, bg, d.xanchor, d.xaxis, k0, regain, n=args.n),
        "weights, directions made": timed(_weights, view, act, lw, bg, fs, True, n=args.n),
        "weights, directions cached": timed(_weights, view, act, lw, bg, fs, False, n=args.n),
        "housing": timed(_housing, ks, act, lw, d.xanchor, fs, n=args.n),
        "broadband modes": timed(_modes, act, lw, bg, n=args.n),
        "broadband force": timed(_force, act, lw, fs, F, n=args.n),
        "broadband resonant": timed(_resonant, view, act, lw, bg, track, k0, F, n=args.n),
        "lines and static broadband": timed(_render, track, act, lw, k0, L, fs, F, n=args.n),
        "whole block": timed(_block, state, k0, L, fs, regain, F, n=args.n),
    }
    print(json.dumps({"env": args.env, "preset": args.preset, "sample_rate": args.sample_rate, "block": int(L),
                      "lines": kept_state["lines"], "modes_kept": kept_state["kept"]}))
    p10, p25, p50 = np.percentile(in_env, [10, 25, 50])
    print(f"in the env, per block (p10 / p25 / p50): {p10:.1f} / {p25:.1f} / {p50:.1f} us")
    print("hot loop [us per call, fastest / median]:")
    for name, (fast, med) in parts.items():
        print(f"  {name:28s} {fast:6.1f} / {med:6.1f}")


if __name__ == "__main__":
    main()
