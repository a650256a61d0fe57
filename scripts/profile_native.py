#!/usr/bin/env python
"""Where a wrapped env step's CPU time goes, by library and by numba kernel (profiler, not a test).

Samples running processes with Linux ``perf`` (``perf record -p``) and sorts the samples by
shared library (MuJoCo, the Python interpreter, numpy, libc, libm, numba's JIT code) and,
within the JIT code, by numba kernel. numba's code has no symbols that ``perf`` can read, so
the profiled child writes ``/tmp/perf-<pid>.map`` (the address of every function of every
compiled mjsound kernel, sized up to the next one), which ``perf`` reads for such code. Only
code compiled in that process has its functions' names at hand, so the child compiles every
kernel in an empty numba cache first (``MJSOUND_SHIPPED_KERNELS=0``: about a minute and a
half here, not profiled).

Cases:

* ``ant``: a wrapped Ant-v5 (16 kHz waveform, clicks on) and the bare env, each stepped with
  seeded random actions, each in processes of its own sampled one after the other
  (``--rounds``: wrapped, bare, wrapped, bare ..., averaged per variant; the machine's speed
  drifts between processes). Each counts its env steps and its CPU time over the sampled
  window, so every library's and kernel's share becomes microseconds of CPU
  per env step, and the two processes compare directly: the difference per library is what
  mjsound adds, MuJoCo's own line included (its physics is the same work in both, so what it
  gains in the wrapped process is the time it loses to mjsound's use of the caches);
* ``demo``: the demo scene's 3 s, over and over (shares of the whole process).

Usage: python scripts/profile_native.py [--case ant|demo] [--seconds 4] [--top 20] [--rounds 2] [--free-field]
       [--actuators PRESET]
(``--free-field``: the wrapped Ant-v5 with ``reflections=False``, to compare with the default floor;
``--actuators qdd``: the wrapped Ant-v5 with that preset on every actuator against the same
without, per library and per kernel: where the drives' cost goes).
Needs ``perf`` and ``/proc/sys/kernel/perf_event_paranoid`` <= 2 (a process's own samples).
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

#: The child: set up the case, write the perf map of mjsound's kernels, say it is ready, and
#: step until the parent says stop.
CHILD = r"""
import os, sys, time, warnings
warnings.filterwarnings("ignore")
import numpy as np
case, wrapped, ready, stop, marks = sys.argv[1], sys.argv[2] == "1", sys.argv[3], sys.argv[4], sys.argv[5]
if os.environ.get("MJSOUND_PROFILE_ACTUATORS"):  # (both variants wrapped; argv[2]: actuators on)
    sys.argv.append(sys.argv[2])
    wrapped = True
steps = 0
window = []  # (steps, CPU seconds) when the parent's perf window opened and when it closed
def check_marks():
    if len(window) < 2 and os.path.exists(f"{marks}.{len(window)}"):
        window.append((steps, time.process_time()))
        if len(window) == 2:
            with open(f"{marks}.out", "w") as f:
                f.write(f"{window[1][0] - window[0][0]} {window[1][1] - window[0][1]}")
if case == "ant":
    import gymnasium as gym
    from mjsound.wrappers import AudioObservation
    env = gym.make("Ant-v5")
    if wrapped:
        acts = os.environ.get("MJSOUND_PROFILE_ACTUATORS", "")
        env = AudioObservation(env, sample_rate=16000, reflections=os.environ.get("MJSOUND_PROFILE_FREE_FIELD") != "1",
                               sim_kwargs={"actuators": acts} if acts and sys.argv[6] == "1" else {})
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (2000, env.action_space.shape[0]))
    env.reset(seed=0)
    def work():
        global steps
        for a in acts:
            *_, te, tr, _ = env.step(a)
            if te or tr:
                env.reset()
            steps += 1
            if steps % 50 == 0:  # (the window's ends to within 50 steps of thousands)
                check_marks()
else:
    import mujoco
    from mjsound.sim import AudioSimulator
    from mjsound.sim.demo import find_demo_scene
    model = mujoco.MjModel.from_xml_path(find_demo_scene())
    data = mujoco.MjData(model)
    sim = AudioSimulator(model, data, sample_rate=48000, progress=False)
    def work():
        mujoco.mj_resetDataKeyframe(model, data, 0)
        sim.reset()
        sim.run(3.0)
work()  # (compiles everything the case runs)
if wrapped:
    from numba.core.registry import CPUDispatcher
    names, seen = {}, set()
    def walk(lib):
        if id(lib) in seen:
            return
        seen.add(id(lib))
        for fn in lib._final_module.functions:
            if not fn.is_declaration:
                addr = lib.get_pointer_to_function(fn.name)
                if addr:
                    names[addr] = fn.name
        for dep in getattr(lib, "_linking_libraries", ()):
            walk(dep)
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("mjsound"):
            for v in list(vars(mod).values()):
                if isinstance(v, CPUDispatcher):
                    for cres in v.overloads.values():
                        walk(cres.library)
    addrs = sorted(names)
    with open(f"/tmp/perf-{os.getpid()}.map", "w") as f:
        for i, a in enumerate(addrs):
            size = min(addrs[i + 1] - a if i + 1 < len(addrs) else 1 << 12, 1 << 20)
            f.write(f"{a:x} {size:x} {names[a]}\n")
open(ready, "w").write(str(os.getpid()))
while not os.path.exists(stop):
    work()
    check_marks()
"""


def kernel_name(symbol: str) -> str:
    """``mjsound.synth.bank_loops.bank_forced`` from numba's mangled ``_ZN7mjsound5synth...``."""
    s = symbol[3:] if symbol.startswith("_ZN") else symbol
    parts, i = [], 0
    while i < len(s) and s[i].isdigit():
        j = i
        while j < len(s) and s[j].isdigit():
            j += 1
        n = int(s[i:j])
        parts.append(s[j:j + n])
        i = j + n
    return ".".join(parts) if parts and symbol.startswith("_ZN") else symbol[:60]


def profile(case: str, wrapped: bool, seconds: float, cache: str) -> tuple[dict, dict, float | None]:
    """One child process sampled for ``seconds``: percent of its samples per library and per
    numba kernel, and (``ant``) its CPU microseconds per env step over the sampled window
    (None: ``demo``)."""
    with tempfile.TemporaryDirectory(prefix="mjsound-perf-") as d:
        ready, stop, data, marks = (os.path.join(d, n) for n in ("ready", "stop", "perf.data", "marks"))
        env = dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=cache, MJSOUND_SHIPPED_KERNELS="0")
        child = subprocess.Popen([sys.executable, "-c", CHILD, case, "1" if wrapped else "0", ready, stop, marks],
                                 env=env)
        try:
            while not os.path.exists(ready):
                if child.poll() is not None:
                    raise SystemExit(f"profile_native: the {case} child exited ({child.returncode}) before it was ready")
                time.sleep(0.2)
            time.sleep(0.3)  # (the pid is written before the loop starts)
            open(marks + ".0", "w").close()  # (the child notes its steps and CPU time: the window opens)
            rec = subprocess.run(["perf", "record", "-F", "4000", "-p", str(child.pid), "-o", data, "--", "sleep",
                                  str(seconds)], capture_output=True, text=True)
            open(marks + ".1", "w").close()
            if rec.returncode != 0:
                raise SystemExit("profile_native: perf record failed (perf_event_paranoid above 2?):\n" + rec.stderr)
            us_per_step = None
            if case == "ant":
                t0 = time.monotonic()
                while not os.path.exists(marks + ".out"):
                    if time.monotonic() - t0 > 60 or child.poll() is not None:
                        raise SystemExit("profile_native: the ant child never reported its steps over the window")
                    time.sleep(0.05)
                steps, cpu = open(marks + ".out").read().split()
                us_per_step = float(cpu) / int(steps) * 1e6
        finally:
            open(stop, "w").close()
            child.wait(timeout=120)
        try:  # (perf reads the map when it reports)
            libs, kernels = _report(data)
        finally:
            if os.path.exists(f"/tmp/perf-{child.pid}.map"):
                os.remove(f"/tmp/perf-{child.pid}.map")
    return libs, kernels, us_per_step


def _report(data: str) -> tuple[dict, dict]:
    """Percent of the samples in ``data`` per library and per numba kernel."""
    rep = subprocess.run(["perf", "report", "-i", data, "--no-children", "--sort", "dso,sym", "--stdio"],
                         capture_output=True, text=True, check=True).stdout
    libs, kernels = collections.Counter(), collections.Counter()
    for line in rep.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(\S+(?: tid \d+)?)\s+\[\.\]\s+(\S+)", line)
        if m:
            pct, lib, sym = float(m.group(1)), m.group(2).split()[0], m.group(3)
            libs["numba JIT" if lib == "[JIT]" else lib] += pct
            if lib == "[JIT]":
                kernels[kernel_name(sym)] += pct
    return libs, kernels


def per_step(case: str, wrapped: bool, seconds: float, cache: str) -> tuple[dict, dict, float]:
    """CPU microseconds per env step of one process (:func:`profile`), by library and by numba
    kernel, and in all."""
    libs, kernels, us = profile(case, wrapped, seconds, cache)
    scale = us / 100.0
    return ({k: v * scale for k, v in libs.items()}, {k: v * scale for k, v in kernels.items()}, us)


def _mean(runs: list) -> tuple[dict, dict, float]:
    """The mean of :func:`per_step` results. The kernels' figures come from the processes
    that named them: only the first wrapped process compiles the kernels (the others load
    them from numba's cache, without the names its perf map needs)."""
    libs, kernels = collections.Counter(), collections.Counter()
    named = [kn for _, kn, _ in runs if any(k.startswith("mjsound.") for k in kn)]
    for lb, _, _ in runs:
        for k, v in lb.items():
            libs[k] += v / len(runs)
    for kn in named:
        for k, v in kn.items():
            kernels[k] += v / len(named)
    return libs, kernels, sum(r[2] for r in runs) / len(runs)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", choices=["ant", "demo"], default="ant")
    p.add_argument("--seconds", type=float, default=4.0, help="sampling time per process")
    p.add_argument("--top", type=int, default=20, help="numba kernels listed")
    p.add_argument("--rounds", type=int, default=2, help="ant: processes per variant, alternated")
    p.add_argument("--free-field", action="store_true", help="ant: the wrapped env with reflections=False")
    p.add_argument("--actuators", default="", metavar="PRESET",
                   help="ant: the wrapped env with PRESET on every actuator against the same without (issue 38's cost)")
    args = p.parse_args(argv)
    if args.free_field:  # (read by the child)
        os.environ["MJSOUND_PROFILE_FREE_FIELD"] = "1"
    if shutil.which("perf") is None:
        raise SystemExit("profile_native: needs Linux perf on PATH (linux-tools / linux-perf)")
    if args.actuators:  # (read by the child: both variants wrapped, "bare" the one without drives)
        os.environ["MJSOUND_PROFILE_ACTUATORS"] = args.actuators
    with tempfile.TemporaryDirectory(prefix="mjsound-numba-") as cache, \
            tempfile.TemporaryDirectory(prefix="mjsound-numba-") as cache_off:
        if args.case == "ant":
            # (alternated: wrapped, bare, wrapped, bare ..., so that a drift of the machine's
            # speed weighs on both; averaged per variant. With --actuators each variant has a
            # numba cache of its own: its first process compiles and names its kernels)
            runs = {True: [], False: []}
            for _ in range(args.rounds):
                for wrapped in (True, False):
                    c = cache_off if args.actuators and not wrapped else cache
                    runs[wrapped].append(per_step(args.case, wrapped, args.seconds, c))
            (libs, kernels, step_w), (bare, kernels_b, step_b) = (_mean(runs[True]), _mean(runs[False]))
            a, b = ("actuators", "without") if args.actuators else ("wrapped", "bare")
            keys = sorted(set(libs) | set(bare), key=lambda k: -max(libs[k], bare[k]))
            print(f"Ant-v5 env step, CPU: {b} {step_b:.0f} us, {a} {step_w:.0f} us ({step_w / step_b:.2f} x; "
                  f"each process's CPU time over its sampled steps, mean of {args.rounds} process(es) each; "
                  f"{b} per process: {', '.join(f'{r[2]:.0f}' for r in runs[False])} us)")
            print(f"library                          {b:>7s} us  {a:>9s} us   added us  (% of the {b} step)")
            for k in keys[:12]:
                add = libs[k] - bare[k]
                print(f"{k[:32]:32s} {bare[k]:7.1f}  {libs[k]:9.1f}  {add:+9.1f}  ({100 * add / step_b:+.1f})")
            sb, sw = sum(bare.values()), sum(libs.values())
            print(f"{'(all libraries)':32s} {sb:7.1f}  {sw:9.1f}  {sw - sb:+9.1f}  (user-space samples only)")
            what = "CPU us per wrapped env step, from the process that compiled them"
        else:
            libs, kernels, _ = profile(args.case, True, args.seconds, cache)
            print("library                          % of samples")
            for k, v in libs.most_common(10):
                print(f"{k[:32]:32s} {v:6.1f}")
            what = "% of samples"
        if args.case == "ant" and args.actuators:
            print(f"numba kernels ({what}; without the drives, with, added):")
            ks = sorted(set(kernels) | set(kernels_b), key=lambda k: -abs(kernels[k] - kernels_b[k]))
            for k in ks[:args.top]:
                print(f"  {kernels_b[k]:6.2f}  {kernels[k]:6.2f}  {kernels[k] - kernels_b[k]:+6.2f}  {k}")
        else:
            print(f"numba kernels ({what}):")
            for k, v in kernels.most_common(args.top):
                print(f"  {v:6.2f}  {k}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
