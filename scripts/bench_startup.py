#!/usr/bin/env python
"""Time to first audio of a fresh process, with a cold and a warm numba cache (benchmark).

Each case runs in a child process (``python -c``), timed from before ``import mjsound`` to
the first audio block: the demo scene (``AudioSimulator`` on ``assets/demo_scene.xml``, its
modal models from the on-disk model cache, 10 ms simulated) and a wrapped Ant-v5 (reset and
one ``env.step``). "cold": ``NUMBA_CACHE_DIR`` is a new empty directory, so every kernel is
compiled, or, with mjsound's shipped kernels (``mjsound/kernel_bundle/``, used unless
``--no-shipped``), copied from them into the cache and loaded; "warm": the same directory
again, so every kernel is loaded. Wall seconds of the
child from its start to the first audio (interpreter start-up included, exit not; the machine
is shared: the median of ``--rounds`` rounds), and the CPU seconds the child spent until then
(``time.process_time``, less sensitive to other load). Goals (issue 18): cold <= 8 s, warm <= 1 s (the
time of importing mujoco and gymnasium included). The modal models come from the user's model
cache (run once first to fill it); ``--warm-only`` skips the cold runs. The children run with
Python's bytecode cache on (``PYTHONDONTWRITEBYTECODE`` removed, as users have it): compiling
mjsound's and its dependencies' sources at every start would add about 0.1 s.

With ``--compile-profile`` each cold child also records where its compilation went (numba's
``numba:compile`` and ``numba:llvm_lock`` events): the seconds inside LLVM, the number of
functions compiled, and the functions with the most compile time of their own (their callees'
compilation excluded).

Each case also runs its floor in the same rounds (``FLOORS``; ``--no-floor`` skips them): the same
process without mjsound, which imports mujoco (and gymnasium), makes the same model or env and
calls one cached numba function of its own. The floor is what the machine charges any such
program (numba's import and first kernel load dominate it), so ``case - floor`` is mjsound's own
start-up; the 1 s goal cannot be met where the floor alone exceeds it.

Usage: python scripts/bench_startup.py [--rounds 1] [--json] [--compile-profile] [--no-shipped] [--no-floor]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

CASES = {
    "demo": """
import time; t0 = time.perf_counter()
import mujoco
from mjsound.sim import AudioSimulator
from mjsound.sim.demo import find_demo_scene
model = mujoco.MjModel.from_xml_path(find_demo_scene())
data = mujoco.MjData(model)
mujoco.mj_resetDataKeyframe(model, data, 0)
t1 = time.perf_counter()
sim = AudioSimulator(model, data, sample_rate=48000, progress=False)
t2 = time.perf_counter()
audio = sim.run(0.01)
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, time.time(), time.process_time())
""",
    "ant": """
import time; t0 = time.perf_counter()
import gymnasium as gym
import numpy as np
from mjsound.wrappers import AudioObservation
env = gym.make("Ant-v5")
t1 = time.perf_counter()
env = AudioObservation(env, sample_rate=16000)
env.reset(seed=0)
t2 = time.perf_counter()
obs, *_ = env.step(np.zeros(env.action_space.shape))
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, time.time(), time.process_time())
""",
}

#: Each case's floor: the same process without mjsound. It imports what the case imports apart from
#: mjsound (mujoco, gymnasium), makes the same model or env and calls one numba function of its own
#: that is cached on disk (``floor_kernel``, cached in the same numba cache directory). That first
#: call loads numba and sets up its compilation target, which any program with one cached numba
#: kernel pays. ``case - floor`` is what mjsound itself adds.
FLOORS = {
    "demo": """
import time; t0 = time.perf_counter()
import mujoco
import numpy as np
import floor_kernel
model = mujoco.MjModel.from_xml_path(floor_kernel.DEMO)
data = mujoco.MjData(model)
mujoco.mj_resetDataKeyframe(model, data, 0)
t1 = time.perf_counter()
t2 = time.perf_counter()
floor_kernel.first(np.ones(3))
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, time.time(), time.process_time())
""",
    "ant": """
import time; t0 = time.perf_counter()
import gymnasium as gym
import numpy as np
import floor_kernel
env = gym.make("Ant-v5")
t1 = time.perf_counter()
env.reset(seed=0)
t2 = time.perf_counter()
obs, *_ = env.step(np.zeros(env.action_space.shape))
floor_kernel.first(np.ones(3))
t3 = time.perf_counter()
print(t1 - t0, t2 - t1, t3 - t2, time.time(), time.process_time())
""",
}

#: The floors' one numba function (a module of its own: numba caches only functions defined in files).
FLOOR_KERNEL = """
import numba

DEMO = {demo!r}


@numba.njit(cache=True)
def first(x):
    return x.sum()
"""


#: Prepended to a child's code with --compile-profile: numba's compile events, summed per function
#: (self time) and inside LLVM, written to stderr at exit as one JSON line.
PROFILE = """
import atexit, collections, json, sys, time
from numba.core import event as _ev
_open, _self, _llvm = [], collections.Counter(), [0.0]
class _Listen(_ev.Listener):
    def on_start(self, e):
        _open.append((e.kind, time.perf_counter(), [0.0]))
    def on_end(self, e):
        kind, t, child = _open.pop()
        dt = time.perf_counter() - t
        if kind == "numba:llvm_lock":
            _llvm[0] += dt
            return
        f = getattr(e.data.get("dispatcher"), "py_func", None)
        _self[f"{f.__module__}.{f.__qualname__}" if f else "?"] += dt - child[0]
        for k, _, c in reversed(_open):
            if k == "numba:compile":
                c[0] += dt
                break
_ev.register("numba:compile", _Listen()); _ev.register("numba:llvm_lock", _Listen())
atexit.register(lambda: print("COMPILE_PROFILE " + json.dumps({"llvm_s": _llvm[0], "functions": len(_self),
    "compile_s": sum(_self.values()), "top": _self.most_common(12)}), file=sys.stderr))
"""


def run_case(code: str, cache_dir: str, profile: bool = False, shipped: bool = True, path: str = ROOT) -> dict:
    env = dict(os.environ, PYTHONPATH=path)
    env.pop("MJSOUND_SHIPPED_KERNELS", None)
    if not shipped:
        env["MJSOUND_SHIPPED_KERNELS"] = "0"
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # (as a user has it: Python keeps compiled modules)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    t0, start = time.perf_counter(), time.time()
    if profile:  # (after the case's first line, which starts its clock)
        first_line, rest = code.lstrip("\n").split("\n", 1)
        code = first_line + "\n" + PROFILE + rest
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    imports, setup, first, heard_at, cpu = (float(x) for x in out.stdout.split())
    res = {"to_audio_s": heard_at - start, "cpu_s": cpu, "wall_s": wall, "import_s": imports, "setup_s": setup,
           "first_audio_s": first, "compile_notice": "compiling numba kernels" in out.stderr}
    for line in out.stderr.splitlines():
        if line.startswith("COMPILE_PROFILE "):
            res["compile_profile"] = json.loads(line.split(" ", 1)[1])
    return res


def _rounds(args, name: str, floor_dir: str) -> dict:
    """The median cold and warm rows of case ``name`` (and of its floor, in the same rounds)."""
    kinds = ["warm"] if args.warm_only else ["cold", "warm"]
    rows = {k: [] for k in kinds}
    floor = not args.no_floor and name in FLOORS
    if floor:
        rows.update({f"{k} floor": [] for k in kinds})
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory(prefix="mjsound-numba-") as d:
            cache = None if args.warm_only else d
            if floor and args.warm_only:
                run_case(FLOORS[name], d, path=floor_dir)  # (caches the floor's kernel)
            for k in kinds:
                rows[k].append(run_case(CASES[name], cache, profile=args.compile_profile and k == "cold",
                                        shipped=not args.no_shipped))
                if floor:
                    rows[f"{k} floor"].append(run_case(FLOORS[name], d, path=floor_dir))
    return {k: sorted(v, key=lambda r: r["to_audio_s"])[len(v) // 2] for k, v in rows.items()}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--cases", nargs="+", default=list(CASES))
    p.add_argument("--json", action="store_true")
    p.add_argument("--warm-only", action="store_true", help="use numba's usual cache; no cold runs")
    p.add_argument("--no-shipped", action="store_true",
                   help="without mjsound's shipped kernels (MJSOUND_SHIPPED_KERNELS=0): a cold run compiles them")
    p.add_argument("--no-floor", action="store_true", help="skip the floors (each case without mjsound)")
    p.add_argument("--compile-profile", action="store_true",
                   help="cold runs: where the compilation went (LLVM seconds, functions, the largest self times)")
    args = p.parse_args(argv)
    res = {}
    with tempfile.TemporaryDirectory(prefix="mjsound-floor-") as floor_dir:
        sys.path.insert(0, ROOT)
        from mjsound.sim.demo import find_demo_scene

        with open(os.path.join(floor_dir, "floor_kernel.py"), "w") as f:
            f.write(FLOOR_KERNEL.format(demo=find_demo_scene()))
        for name in args.cases:
            res[name] = _rounds(args, name, floor_dir)
    if args.json:
        print(json.dumps(res))
    else:
        for name, r in res.items():
            for k, v in r.items():
                if k.endswith("floor"):
                    continue
                print(f"{name:5s} {k}: {v['to_audio_s']:.2f} s to first audio (imports {v['import_s']:.2f} s, "
                      f"setup {v['setup_s']:.2f} s, first block {v['first_audio_s']:.2f} s; process exit at "
                      f"{v['wall_s']:.2f} s; {v['cpu_s']:.2f} s of CPU to the first audio)"
                      + ("; said it compiles" if v["compile_notice"] else ""))
                fl = r.get(f"{k} floor")
                if fl:
                    print(f"      floor (the same without mjsound): {fl['to_audio_s']:.2f} s; mjsound adds "
                          f"{v['to_audio_s'] - fl['to_audio_s']:.2f} s ({v['cpu_s'] - fl['cpu_s']:.2f} s of CPU)")
                cp = v.get("compile_profile")
                if cp:
                    print(f"      compiled {cp['functions']} functions in {cp['compile_s']:.1f} s, "
                          f"{cp['llvm_s']:.1f} s of it inside LLVM; largest self times: "
                          + ", ".join(f"{n.rsplit('.', 1)[-1]} {t:.2f}" for n, t in cp["top"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
