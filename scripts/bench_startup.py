#!/usr/bin/env python
"""Time to first audio of a fresh process, with a cold and a warm numba cache (benchmark).

Each case runs in a child process (``python -c``), timed from before ``import mjsound`` to
the first audio block: the demo scene (``AudioSimulator`` on ``assets/demo_scene.xml``, its
modal models from the on-disk model cache, 10 ms simulated) and a wrapped Ant-v5 (reset and
one ``env.step``). "cold": ``NUMBA_CACHE_DIR`` is a new empty directory, so every kernel is
compiled; "warm": the same directory again, so every kernel is loaded. Wall seconds of the
child (the machine is shared: the median of ``--rounds`` rounds). Goals (issue 18): cold
<= 8 s, warm <= 1 s (the time of importing mujoco and gymnasium included).

Usage: python scripts/bench_startup.py [--rounds 1] [--json]
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
print(t1 - t0, t2 - t1, t3 - t2)
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
print(t1 - t0, t2 - t1, t3 - t2)
""",
}


def run_case(code: str, cache_dir: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir, PYTHONPATH=ROOT)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    imports, setup, first = (float(x) for x in out.stdout.split())
    return {"wall_s": wall, "import_s": imports, "setup_s": setup, "first_audio_s": first,
            "compile_notice": "compiling numba kernels" in out.stderr}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--cases", nargs="+", default=list(CASES))
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    res = {}
    for name in args.cases:
        rows = {"cold": [], "warm": []}
        for _ in range(args.rounds):
            with tempfile.TemporaryDirectory(prefix="mjsound-numba-") as d:
                rows["cold"].append(run_case(CASES[name], d))
                rows["warm"].append(run_case(CASES[name], d))
        res[name] = {k: sorted(v, key=lambda r: r["wall_s"])[len(v) // 2] for k, v in rows.items()}
    if args.json:
        print(json.dumps(res))
    else:
        for name, r in res.items():
            for k, v in r.items():
                print(f"{name:5s} {k}: {v['wall_s']:.2f} s to first audio (imports {v['import_s']:.2f} s, "
                      f"setup {v['setup_s']:.2f} s, first block {v['first_audio_s']:.2f} s)"
                      + ("; said it compiles" if v["compile_notice"] else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
