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
  pulse track grew), every direction factor made again. The parts write the state as a block does; what they compute is thrown away;
* **in the env, by part** (``--parts-in-env``, x86-64 only): the steps are taken again with
  a copy of ``lines_drive`` that reads the processor's time-stamp counter between its parts
  (the same calls in the same order: keep :func:`_lines_drive_timed` in step with
  :func:`mjsound.synth.drive_lines.lines_drive`), the mean and the 10th / 50th / 90th
  percentile of each part over the steps [us]: what each part costs with the caches as
  the physics step leaves them (about twice the hot loop's).

    python scripts/bench_actuator_parts.py                       # Ant-v5, qdd, 16 kHz
    python scripts/bench_actuator_parts.py --env FetchPickAndPlace-v4 --preset servo --sample-rate 48000
    python scripts/bench_actuator_parts.py --parts-in-env         # and each part in the env

Compare two commits in the same session (the machine's load moves every figure).
"""

import argparse
import json
import platform
import sys
import time

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_actuators import make  # noqa: E402

from mjsound.sim.actuators import ActuatorSound  # noqa: E402
from mjsound.synth.drive_broadband import (broadband_force, broadband_modes, broadband_resonant,  # noqa: E402
                                           broadband_route)
from mjsound.synth.drive_gains import bodies_gains  # noqa: E402
from mjsound.synth.drive_housing import housing_weights  # noqa: E402
from mjsound.synth.dispatch import PackedEntry  # noqa: E402
from mjsound.synth.drive_lines import (DONE, GROW_LINES, GROW_TRACK, drive_read, lines_drive,  # noqa: E402
                                      lines_render_in, scratch_fits)
from mjsound.synth.packing import unpack  # noqa: E402
from mjsound.synth.drive_weights import line_weights  # noqa: E402
from mjsound.wrappers import AudioObservation  # noqa: E402


@njit
def _gains(ks, act, bg, anchor, axis, k0, regain, n):
    table = ks.streams.table
    for _ in range(n):
        for s in act.sidx:  # (each call makes the gains: a stream's last making after k0 marks them due;
            if s >= 0:      # else every call after the first would time the path that skips them)
                table[s].gupd = k0 + 1
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
        lines_render_in(track, act, lw, lw.scratch, k0, L, fs, F)


@njit
def _block(state, k0, L, fs, regain, F, n):
    bg, io = state[3], state[8]
    for _ in range(n):
        bg.U[:] = np.nan  # (every body turned: its direction factors made again, as Ant's links in most blocks)
        io[4] = 1  # (resumed: the block's read and gains kept, some joint moving)
        lines_drive(state, k0, L, fs, False, True, regain, F)


@intrinsic
def _ticks(typingctx):
    """The processor's time-stamp counter (``llvm.readcyclecounter``: ``rdtsc`` on x86-64)."""
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                            "llvm.readcyclecounter")
        return builder.call(fn, [])

    return types.int64(), codegen


#: The parts :func:`_lines_drive_timed` times, in its order (the ticks' columns).
PARTS = ("read and bodies' gains", "lines' weights", "housing", "broadband modes and force", "lines' samples",
         "resonant broadband", "whole block")


@njit
def _lines_drive_timed(state, k0, L, fs, fresh, resume, regain, F):
    """:func:`mjsound.synth.drive_lines.lines_drive` with the time-stamp counter read between
    its parts (``state`` ends with ``ticks`` (rows, len(PARTS)) int64 and ``row`` (1,) int64,
    the next row to write; a block that hands back or where every joint is still writes none)."""
    rd, act, lw, bg, view, ks, track, dv, io, ticks, row = state
    qvel, force, anchor, axis = dv
    t0 = _ticks()
    io[0] = DONE
    io[2] = 0
    io[3] = 0
    if not scratch_fits(lw.scratch, lw.W1.shape[0], min(lw.W1.shape[1], track.acc.shape[0]), L, act.a0.shape[0]):
        io[0] = GROW_LINES
        io[1] = L
        return
    if not resume:
        io[4] = 1 if drive_read(rd, act, qvel, force, fresh) else 0
        if io[4] == 1:
            for j in range(act.a1.shape[0]):
                act.acting[j] = act.a0[j] != 0.0 or act.a1[j] != 0.0
            bodies_gains(ks, act, bg, anchor, axis, k0, regain)
    if io[4] == 0:  # (still joints: lines_drive's ring-out path, not timed)
        lines_drive(state[:9], k0, L, fs, fresh, True, regain, F)
        return
    t1 = _ticks()
    dmax = line_weights(view, act, lw, bg, fs)
    broadband_route(lw, L, fs)
    t2 = _ticks()
    housing_weights(ks, act, lw, anchor, fs)
    for b in range(bg.D.shape[0]):
        if act.sidx[b] >= 0:
            for m in range(bg.D.shape[1]):
                dmax = max(dmax, bg.D[b, m])
    last = k0 + L + dmax
    if last - track.rec[0].start > track.acc.shape[1]:
        io[0] = GROW_TRACK
        io[1] = last + 1
        return
    some = False
    for j in range(lw.exact.shape[0]):
        some = some or lw.exact[j]
    t3 = _ticks()
    if some:
        io[3] = broadband_modes(act, lw, bg)
        broadband_force(act, lw, fs, F)
    else:
        bg.keep[:, :] = False
    if fresh:
        lw.W0[:, :] = lw.W1
        lw.B0[:, :] = lw.B1
    t4 = _ticks()
    io[2] = lines_render_in(track, act, lw, lw.scratch, k0, L, fs, F)
    t5 = _ticks()
    broadband_resonant(view, act, lw, bg, track, k0, F, fresh)
    t6 = _ticks()
    r = row[0]
    if r < ticks.shape[0]:
        ticks[r, 0], ticks[r, 1], ticks[r, 2], ticks[r, 3] = t1 - t0, t2 - t1, t3 - t2, t4 - t3
        ticks[r, 4], ticks[r, 5], ticks[r, 6] = t5 - t4, t6 - t5, t6 - t0
        row[0] = r + 1


@njit
def _lines_drive_timed_packed(table, layout, k0, L, fs, fresh, resume, regain, F):
    _lines_drive_timed(unpack(table, layout), k0, L, fs, fresh, resume, regain, F)


class _TimedCall:
    """Stands for ``ActuatorSound``'s lines kernel: the timed copy, with the ticks' arrays
    appended to its state (its ``state`` never matches: ``_drive_lines`` calls it)."""

    state = None

    def __init__(self, ticks, row):
        self.entry, self.extra = PackedEntry(_lines_drive_timed_packed), (ticks, row)

    def __call__(self, state, *args):
        return self.entry(tuple(state) + self.extra, *args)


def ticks_per_us() -> float:
    """The time-stamp counter's rate [ticks per us], against ``time.perf_counter`` over 0.2 s."""
    @njit
    def now():
        return _ticks()

    now()
    a, t0 = now(), time.perf_counter()
    time.sleep(0.2)
    b, t1 = now(), time.perf_counter()
    return (b - a) / (t1 - t0) / 1e6


def parts_in_env(env, actions, steps):
    """Each part of the drives' block in the env: the env stepped ``steps`` times more with
    :func:`_lines_drive_timed` in place of ``lines_drive``; returns (blocks, parts) [us]."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        raise SystemExit(f"--parts-in-env reads the x86-64 time-stamp counter; this is a {platform.machine()}")
    ticks, row = np.zeros((steps, len(PARTS)), np.int64), np.zeros(1, np.int64)
    timed_call = _TimedCall(ticks, row)
    render_due = ActuatorSound.render_due

    def swap(self):
        self._calls["lines"] = timed_call
        return render_due(self)

    ActuatorSound.render_due = swap
    try:
        env.reset(seed=0)
        for a in actions[:20]:  # (warm-up: the timed copy compiles)
            env.step(a)
        env.reset(seed=0)
        row[0] = 0
        for a in actions[:steps]:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset(seed=0)
    finally:
        ActuatorSound.render_due = render_due
    return ticks[: row[0]] / ticks_per_us()


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
    ap.add_argument("--parts-in-env", action="store_true", help="also time each part in the env (x86-64)")
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
    if args.parts_in_env:
        us = parts_in_env(env, rng.uniform(space.low, space.high, (args.steps + 20, space.shape[0])), args.steps)
        print(f"in the env, by part [us over {len(us)} blocks: mean, p10, p50, p90]:")
        for i, name in enumerate(PARTS):
            x = us[:, i]
            print(f"  {name:28s} {x.mean():6.1f} {np.percentile(x, 10):6.1f} {np.percentile(x, 50):6.1f} "
                  f"{np.percentile(x, 90):6.1f}")


if __name__ == "__main__":
    main()
