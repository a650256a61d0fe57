#!/usr/bin/env python
"""Where a wrapped env step's CPU time goes, by library and by numba kernel (profiler, not a test).

Samples a running process with Linux ``perf`` (``perf record -p``) and sorts the samples by
shared library (MuJoCo, the Python interpreter, numpy, libc, libm, numba's JIT code) and,
within the JIT code, by numba kernel. numba's code has no symbols that ``perf`` can read, so
the profiled child writes ``/tmp/perf-<pid>.map`` (the address of every function of every
compiled mjsound kernel, sized up to the next one), which ``perf`` reads for such code. Only
code compiled in that process has its functions' names at hand, so the child compiles every
kernel in an empty numba cache first (``MJSOUND_SHIPPED_KERNELS=0``: about a minute and a
half here, not profiled).

Cases:

* ``ant``: a wrapped Ant-v5 (16 kHz waveform, clicks on) and the bare env, each stepped with
  seeded random actions; both profiles are scaled so that MuJoCo's share is the same work
  (``libmujoco`` = the same physics in both), and the difference per library is what
  mjsound adds, in percent of the bare env step;
* ``demo``: the demo scene's 3 s, over and over (shares of the whole process).

Usage: python scripts/profile_native.py [--case ant|demo] [--seconds 4] [--top 20]
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
case, wrapped, ready, stop = sys.argv[1], sys.argv[2] == "1", sys.argv[3], sys.argv[4]
if case == "ant":
    import gymnasium as gym
    from mjsound.wrappers import AudioObservation
    env = gym.make("Ant-v5")
    if wrapped:
        env = AudioObservation(env, sample_rate=16000)
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (2000, env.action_space.shape[0]))
    env.reset(seed=0)
    def work():
        for a in acts:
            *_, te, tr, _ = env.step(a)
            if te or tr:
                env.reset()
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


def profile(case: str, wrapped: bool, seconds: float, cache: str) -> tuple[dict, dict]:
    """Percent of samples per library and per numba kernel of one child process."""
    with tempfile.TemporaryDirectory(prefix="mjsound-perf-") as d:
        ready, stop, data = (os.path.join(d, n) for n in ("ready", "stop", "perf.data"))
        env = dict(os.environ, PYTHONPATH=ROOT, NUMBA_CACHE_DIR=cache, MJSOUND_SHIPPED_KERNELS="0")
        child = subprocess.Popen([sys.executable, "-c", CHILD, case, "1" if wrapped else "0", ready, stop], env=env)
        try:
            while not os.path.exists(ready):
                if child.poll() is not None:
                    raise SystemExit(f"profile_native: the {case} child exited ({child.returncode}) before it was ready")
                time.sleep(0.2)
            time.sleep(0.3)  # (the pid is written before the loop starts)
            rec = subprocess.run(["perf", "record", "-F", "4000", "-p", str(child.pid), "-o", data, "--", "sleep",
                                  str(seconds)], capture_output=True, text=True)
            if rec.returncode != 0:
                raise SystemExit("profile_native: perf record failed (perf_event_paranoid above 2?):\n" + rec.stderr)
        finally:
            open(stop, "w").close()
            child.wait(timeout=120)
        try:  # (perf reads the map when it reports)
            rep = subprocess.run(["perf", "report", "-i", data, "--no-children", "--sort", "dso,sym", "--stdio"],
                                 capture_output=True, text=True, check=True).stdout
        finally:
            if os.path.exists(f"/tmp/perf-{child.pid}.map"):
                os.remove(f"/tmp/perf-{child.pid}.map")
    libs, kernels = collections.Counter(), collections.Counter()
    for line in rep.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(\S+(?: tid \d+)?)\s+\[\.\]\s+(\S+)", line)
        if m:
            pct, lib, sym = float(m.group(1)), m.group(2).split()[0], m.group(3)
            libs["numba JIT" if lib == "[JIT]" else lib] += pct
            if lib == "[JIT]":
                kernels[kernel_name(sym)] += pct
    return libs, kernels


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", choices=["ant", "demo"], default="ant")
    p.add_argument("--seconds", type=float, default=4.0, help="sampling time per process")
    p.add_argument("--top", type=int, default=20, help="numba kernels listed")
    args = p.parse_args(argv)
    if shutil.which("perf") is None:
        raise SystemExit("profile_native: needs Linux perf on PATH (linux-tools / linux-perf)")
    with tempfile.TemporaryDirectory(prefix="mjsound-numba-") as cache:
        libs, kernels = profile(args.case, True, args.seconds, cache)
        if args.case == "ant":
            bare, _ = profile(args.case, False, args.seconds, cache)
            # the wrapped process ran MuJoCo's same physics: its step is `scale` bare steps
            mj = next((k for k in bare if k.startswith("libmujoco")), None)
            if mj is None or not libs[mj]:
                raise SystemExit("profile_native: no samples in MuJoCo's library: nothing to scale by")
            scale = bare[mj] / libs[mj]
            keys = sorted(set(libs) | set(bare), key=lambda k: -(libs[k] * scale - bare[k]))
            print(f"wrapped Ant-v5 step = {scale:.2f} x the bare step (MuJoCo's samples as the yardstick)")
            print("library                          bare %   wrapped % of the bare step   added")
            for k in keys[:10]:
                print(f"{k[:32]:32s} {bare[k]:6.1f}   {libs[k] * scale:6.1f}                     "
                      f"{libs[k] * scale - bare[k]:+6.1f}")
            unit = scale
        else:
            print("library                          % of samples")
            for k, v in libs.most_common(10):
                print(f"{k[:32]:32s} {v:6.1f}")
            unit = 1.0
        what = "% of the bare step" if args.case == "ant" else "% of samples"
        print(f"numba kernels ({what}):")
        for k, v in kernels.most_common(args.top):
            print(f"  {v * unit:6.2f}  {k}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
