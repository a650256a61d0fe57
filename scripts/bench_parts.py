#!/usr/bin/env python
"""Where the per-step time goes: wall time of each stage of the audio pipeline (benchmark).

Wraps the stages in ``time.perf_counter`` timers (each timer adds well under a microsecond
per call, to its own stage and to every stage around it) and prints microseconds per physics
step (demo scene) or per env step (gymnasium):

* ``substeps``: :meth:`~mjsound.sim.driver.StepDriver.substeps`, the one way into the step
  kernel (``mj_step`` included when the kernel steps itself; the kernel's own time is not
  timed apart: the driver enters its compiled entry point directly); within it: ``state``
  (:meth:`~mjsound.sim.driver.StepDriver.state`, the kernel's state record from the owners'
  current records, asked before every call: the simulator's drive, the synthesizer's state and
  render target, the reader's state), ``hand_back`` (what the kernel hands back) and
  ``collect`` (the call's log entries and counts, taken when the kernel's ``run.collect`` says
  there are any);
* ``render``: ``Synthesizer.render`` (``render_streams``: its one-call render kernel: due gains, due events, streams, banks);
* ``flush``, ``end_step``, ``wrapper_step``: the layers above (gymnasium wrapper); within
  ``end_step``: ``push`` (the block into the observation window) and ``audible_impacts`` (the
  info's count, when there were impacts); ``observe`` (the spectrogram mode's observation);
* ``physics``: ``mj_step`` alone on a copy of the same model (demo: the same number of steps;
  env: ``frame_skip`` steps per env step);
* ``nrt_allocs`` (env): numba's heap allocations per env step (arrays made inside kernels;
  resets included), counted by numba (``NUMBA_NRT_STATS``);
* ``call_in_step`` / ``call_back_to_back`` (env): ``StepDriver.substeps(0)``, a step-kernel
  call that steps and renders nothing, made after every env step of a run / in a tight loop:
  the fixed cost of a call (the driver's Python, unboxing its packed state, the pose sync),
  which a run pays with cold caches;
* ``repack`` (env): packing the step kernel's state again with its numba type
  (:func:`mjsound.synth.packing.pack`, what a call pays after an owner replaced a record),
  and ``numba_typeof``: ``numba.typeof`` of that state alone (what packing spent typing it
  before the types were memoised).

The demo is also run with ``sustained=False`` (no sliding / rolling sound), which shows what
the streams cost. Clicks and contact microphones are off (their cost: ``bench_scene.py``).
The machine is shared: the median of ``--rounds`` rounds.

Usage: python scripts/bench_parts.py [--duration 3] [--env Ant-v5] [--steps 500] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
os.environ.setdefault("NUMBA_NRT_STATS", "1")  # (before numba's import: its allocation counters)

import mujoco  # noqa: E402
from numba.core.runtime import rtsys  # noqa: E402
import numpy as np  # noqa: E402

from mjsound import wrappers  # noqa: E402
from mjsound.sim import driver, simulator  # noqa: E402
from mjsound.sim.demo import find_demo_scene  # noqa: E402
from mjsound.synth import stream_table, synthesizer  # noqa: E402

TIMES: dict[str, float] = {}


def timed(cls, name: str, key: str) -> None:
    """Add the wall time of every ``cls.name`` call to ``TIMES[key]``."""
    fn = getattr(cls, name)

    def wrapper(*a, **k):
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            TIMES[key] = TIMES.get(key, 0.0) + time.perf_counter() - t0

    setattr(cls, name, wrapper)


for _cls, _name, _key in ((driver.StepDriver, "substeps", "substeps"), (driver.StepDriver, "state", "state"),
                          (driver.StepDriver, "_hand_back", "hand_back"), (driver.StepDriver, "_collect", "collect"),
                          (driver.StepDriver, "flush", "flush"), (synthesizer.Synthesizer, "render", "render"),
                          (stream_table.StreamMethods, "_render_streams", "render_streams"),
                          (wrappers.EnvAudio, "end_step", "end_step"), (wrappers.AudioWindow, "push", "push"),
                          (wrappers.EnvAudio, "_audible_impacts", "audible_impacts"), (wrappers.AudioWindow, "observe", "observe"),
                          (wrappers.AudioObservation, "step", "wrapper_step")):
    timed(_cls, _name, _key)


def demo(duration: float, sustained: bool) -> dict:
    """Microseconds per physics step of each stage, demo scene, 48 kHz."""
    model = mujoco.MjModel.from_xml_path(find_demo_scene())

    def fresh():
        d = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, d, 0)
        return d

    nst = int(round(duration / model.opt.timestep))
    d = fresh()
    t0 = time.perf_counter()
    mujoco.mj_step(model, d, nstep=nst)
    physics = time.perf_counter() - t0
    sim = simulator.AudioSimulator(model, fresh(), sample_rate=48000, progress=False, clicks=False, contact_mics=[],
                                   sustained=sustained, keep_events=0)
    TIMES.clear()
    t0 = time.perf_counter()
    sim.run(duration)
    total = time.perf_counter() - t0
    out = {k: 1e6 * v / nst for k, v in TIMES.items()}
    out.update(physics=1e6 * physics / nst, total=1e6 * total / nst, ratio=total / physics)
    return out


def env_parts(env_id: str, steps: int) -> dict:
    """Microseconds per env step of each stage, ``AudioObservation`` at 16 kHz."""
    import gymnasium as gym

    env = wrappers.AudioObservation(gym.make(env_id), sample_rate=16000, progress=False, clicks=False, contact_mics=[])
    env.action_space.seed(0)
    acts = [env.action_space.sample() for _ in range(steps)]

    def run():
        env.reset(seed=0)
        for a in acts:
            _, _, te, tr, _ = env.step(a)
            if te or tr:
                env.reset()

    run()  # warm-up
    TIMES.clear()
    a0 = rtsys.get_allocation_stats().alloc
    run()
    allocs = rtsys.get_allocation_stats().alloc - a0
    out = {k: 1e6 * v / steps for k, v in TIMES.items()}
    out["nrt_allocs"] = allocs / steps  # (resets included)
    out["call_in_step"], out["call_back_to_back"] = empty_call_cost(env, acts)
    out["repack"], out["numba_typeof"] = repack_cost(env)
    m, d = env.unwrapped.model, mujoco.MjData(env.unwrapped.model)
    fs = env.unwrapped.frame_skip
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d, nstep=fs)
    out["physics"] = 1e6 * (time.perf_counter() - t0) / steps
    env.close()
    return out


def empty_call_cost(env, acts) -> tuple[float, float]:
    """Microseconds of one step-kernel call that runs no substep and renders nothing (its
    packed state's unboxing and unpacking and the end-of-call pose sync): between env steps, as in a run (the
    caches hold the physics' and gymnasium's data then), and back to back."""
    drv = env.core.sim.driver

    env.reset(seed=0)
    tot = 0.0
    for a in acts:
        _, _, te, tr, _ = env.step(a)
        if te or tr:
            env.reset()
        t0 = time.perf_counter()
        drv.substeps(0, False)
        tot += time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in acts:
        drv.substeps(0, False)
    return 1e6 * tot / len(acts), 1e6 * (time.perf_counter() - t0) / len(acts)


def repack_cost(env, reps: int = 5) -> tuple[float, float]:
    """Microseconds to pack the step kernel's current state again, its numba type memoised
    (:func:`~mjsound.synth.packing.pack`, as the kernel's entry does), and to type that state
    with ``numba.typeof`` alone (what packing paid before the memo); medians of ``reps``."""
    from numba import typeof

    from mjsound.synth import packing

    state = env.core.sim.driver.state()
    packs, typings = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        packing.pack(state)
        t1 = time.perf_counter()
        typeof(state)
        typings.append(time.perf_counter() - t1)
        packs.append(t1 - t0)
    return 1e6 * float(np.median(packs)), 1e6 * float(np.median(typings))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=3.0)
    p.add_argument("--env", default="Ant-v5")
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args(argv)
    demo(0.3, True)  # warm-up (numba, model cache)
    cases = {"demo (us per 1 ms step)": lambda: demo(args.duration, True),
             "demo, sustained=False": lambda: demo(args.duration, False),
             f"{args.env} (us per env step)": lambda: env_parts(args.env, args.steps)}
    for name, fn in cases.items():
        rounds = [fn() for _ in range(args.rounds)]
        med = {k: float(np.median([r.get(k, 0.0) for r in rounds])) for k in rounds[0]}
        print(name + ": " + ", ".join(f"{k} {v:.2f}" if k == "ratio" else f"{k} {v:.1f}" for k, v in med.items()),
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
