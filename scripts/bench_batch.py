"""Benchmark of batch sonification (mjsound.batch.sonify_batch).

Measures, on a generated dataset of rollouts (three objects dropping, sliding and rolling on
a floor; re-simulated from their controls):

* throughput (seconds of audio per wall second, everything included: pool start, worker
  warm-up, I/O, sidecars) of the local process pool with 1 and 2 workers, and the speed-up;
* the same batch on a local Ray instance (2 CPUs), cold (first batch after ``ray.init``) and warm
  (worker processes already started and JIT-compiled), and warm with 1 task in flight: the
  parallel speed-up without process start-up in the timing;
* the ceiling on this machine *now*: the same ``sonify`` work split over 1 and 2 independent,
  already warm processes, with no batch code at all (on a shared machine it can be far below 2);
* the per-rollout overhead of each backend: the slope of wall time over the number of (tiny)
  rollouts, ``(wall(2M) - wall(M)) / M``, with 2 workers; the intercept is the fixed cost
  (pool start / Ray scheduling warm-up).

Modal models are analysed (and disk-cached) before any timing. The machine's other load is
printed: a shared machine makes the numbers noisy.

    python scripts/bench_batch.py [--rollouts 24] [--seconds 2] [--tiny 12] [--no-ray] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time

import numpy as np

XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom>
    <text name="mjsound:floor" data="oak"/>
    <text name="mjsound:plate" data="steel"/>
    <text name="mjsound:block" data="aluminium"/>
    <text name="mjsound:rod" data="glass"/>
  </custom>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    <body name="plate" pos="0 0 0.05"><freejoint/>
      <geom name="plate" type="box" size="0.08 0.05 0.004" solref="-1e5 -120"/></body>
    <body name="block" pos="0.15 0 0.08"><freejoint/>
      <geom name="block" type="box" size="0.025 0.02 0.015" solref="-1e5 -120"/></body>
    <body name="rod" pos="-0.15 0 0.1"><freejoint/>
      <geom name="rod" type="cylinder" size="0.008 0.06" euler="0 90 0" solref="-1e5 -120"/></body>
  </worldbody>
</mujoco>"""


def make_dataset(d, n, seconds, seed=0):
    import mujoco

    os.makedirs(d, exist_ok=True)
    scene = os.path.join(d, "scene.xml")
    with open(scene, "w") as fh:
        fh.write(XML)
    model = mujoco.MjModel.from_xml_string(XML)
    rng = np.random.default_rng(seed)
    steps = int(round(seconds / model.opt.timestep)) + 1
    paths = []
    for k in range(n):
        data = mujoco.MjData(model)
        data.qpos[[2, 9, 16]] += rng.uniform(0.0, 0.1, 3)
        data.qvel[:] = rng.normal(0.0, 0.6, model.nv)
        t, q, v = np.empty(steps), np.empty((steps, model.nq)), np.empty((steps, model.nv))
        for i in range(steps):
            t[i], q[i], v[i] = data.time, data.qpos, data.qvel
            mujoco.mj_step(model, data)
        p = os.path.join(d, f"r{k:04d}.npz")
        np.savez(p, time=t, qpos=q, qvel=v, ctrl=np.zeros((steps, 0)))
        paths.append(p)
    return scene, paths


_RAW = """
import sys, time
from mjsound.sim.rollout import sonify
scene, paths = sys.argv[1], sys.argv[2:]
sonify(scene, rollout=paths[0], progress=False)  # process warm-up (imports, JIT) not timed
t = time.perf_counter()
for p in paths:
    sonify(scene, rollout=p, progress=False)
print(time.perf_counter() - t)
"""


def raw_parallel(scene, paths, k):
    """Ceiling: ``k`` independent processes (no batch machinery) sonify ``paths`` split k ways.

    Returns the wall time of the slowest one's timed loop (warm-up excluded).
    """
    import subprocess

    procs = [subprocess.Popen([sys.executable, "-c", _RAW, scene, *paths[j::k]], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True) for j in range(k)]
    times = [float(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
    return max(times)


def run(paths, scene, out, **kw):
    from mjsound.batch import sonify_batch

    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    s = sonify_batch(paths, scene, out, resume=False, progress=False, **kw)
    wall = time.perf_counter() - t0
    assert not s["failed"], s["failed"]
    return {"wall_s": wall, "audio_s": s["audio_seconds"], "throughput": s["audio_seconds"] / wall,
            "task_s": s["task_seconds"], "analysis_s": s["analysis_seconds"], "n": len(s["done"])}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rollouts", type=int, default=24, help="rollouts in the throughput batch (default 24)")
    ap.add_argument("--seconds", type=float, default=2.0, help="seconds per rollout (default 2)")
    ap.add_argument("--tiny", type=int, default=12, help="M for the overhead slope (M and 2M rollouts of 10 ms)")
    ap.add_argument("--no-ray", action="store_true", help="local pool only")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)

    from mjsound.sim.rollout import sonify

    tmp = tempfile.mkdtemp(prefix="mjsound-bench-batch-")
    res = {"cpus": os.cpu_count(), "load_avg_before": os.getloadavg(), "rollouts": args.rollouts,
           "seconds_per_rollout": args.seconds}
    try:
        scene, paths = make_dataset(os.path.join(tmp, "big"), args.rollouts, args.seconds)
        _, tiny = make_dataset(os.path.join(tmp, "tiny"), 2 * args.tiny, 0.01, seed=1)
        t0 = time.perf_counter()
        sonify(scene, rollout=paths[0], progress=False)  # modal analysis into the disk cache; JIT cache
        res["warmup_s"] = time.perf_counter() - t0
        out = os.path.join(tmp, "out")

        sub = paths[: max(2, min(8, len(paths)))]
        r1, r2 = raw_parallel(scene, sub, 1), raw_parallel(scene, sub, 2)
        res["raw_1proc_s"], res["raw_2proc_s"], res["raw_speedup_2_vs_1"] = r1, r2, r1 / r2

        res["local_w1"] = run(paths, scene, out, workers=1)
        res["local_w2"] = run(paths, scene, out, workers=2)
        res["speedup_local_2_vs_1"] = res["local_w2"]["throughput"] / res["local_w1"]["throughput"]
        # overhead slope, local pool
        a = run(tiny[: args.tiny], scene, out, workers=2)
        b = run(tiny, scene, out, workers=2)
        res["local_overhead_per_rollout_s"] = (b["wall_s"] - a["wall_s"]) / args.tiny
        res["local_fixed_s"] = a["wall_s"] - args.tiny * res["local_overhead_per_rollout_s"]

        if not args.no_ray:
            import logging

            import ray

            t0 = time.perf_counter()
            ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING, log_to_driver=False)
            res["ray_init_s"] = time.perf_counter() - t0
            try:
                res["ray_w2_cold"] = run(paths, scene, out, workers=2, address="auto")
                res["ray_w2_warm"] = run(paths, scene, out, workers=2, address="auto")
                res["ray_w1_warm"] = run(paths, scene, out, workers=1, address="auto")
                res["speedup_ray_warm_2_vs_1"] = res["ray_w2_warm"]["throughput"] / res["ray_w1_warm"]["throughput"]
                a = run(tiny[: args.tiny], scene, out, workers=2, address="auto")
                b = run(tiny, scene, out, workers=2, address="auto")
                res["ray_overhead_per_rollout_s"] = (b["wall_s"] - a["wall_s"]) / args.tiny
                res["ray_fixed_s"] = a["wall_s"] - args.tiny * res["ray_overhead_per_rollout_s"]
                res["ray_minus_local_overhead_per_rollout_s"] = (res["ray_overhead_per_rollout_s"]
                                                                 - res["local_overhead_per_rollout_s"])
            finally:
                ray.shutdown()
        res["load_avg_after"] = os.getloadavg()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    if args.json:
        print(json.dumps(res))
        return 0
    print(f"machine    {res['cpus']} CPUs, load average {res['load_avg_before'][0]:.1f} before, "
          f"{res['load_avg_after'][0]:.1f} after (other processes share the CPUs)")
    print(f"dataset    {args.rollouts} rollouts x {args.seconds:g} s, 3 sounding objects (re-simulated)")
    for key, label in (("local_w1", "local, 1 worker"), ("local_w2", "local, 2 workers"),
                       ("ray_w2_cold", "ray, 2 CPUs (cold)"), ("ray_w2_warm", "ray, 2 CPUs (warm)"),
                       ("ray_w1_warm", "ray, 1 task in flight")):
        if key in res:
            r = res[key]
            print(f"{label:<20s} {r['audio_s']:.1f} s audio in {r['wall_s']:.1f} s wall = "
                  f"{r['throughput']:.2f} audio-s/s (tasks {r['task_s']:.1f} s)")
    print(f"ceiling    2 vs 1 independent processes (no batch code, warm): {res['raw_speedup_2_vs_1']:.2f}x "
          "= what this machine gives right now")
    print(f"speed-up   2 vs 1 local workers: {res['speedup_local_2_vs_1']:.2f}x (goal >= 1.7x on 2 idle cores)")
    if "speedup_ray_warm_2_vs_1" in res:
        print(f"           2 vs 1 tasks in flight on warm Ray workers: {res['speedup_ray_warm_2_vs_1']:.2f}x "
              "(no process start / JIT in the timing)")
    print(f"overhead   local pool {1e3 * res['local_overhead_per_rollout_s']:.0f} ms/rollout "
          f"(fixed {res['local_fixed_s']:.1f} s)")
    if "ray_overhead_per_rollout_s" in res:
        print(f"           ray        {1e3 * res['ray_overhead_per_rollout_s']:.0f} ms/rollout "
              f"(fixed {res['ray_fixed_s']:.1f} s; ray.init {res['ray_init_s']:.1f} s); "
              f"ray - local = {1e3 * res['ray_minus_local_overhead_per_rollout_s']:+.0f} ms/rollout")
    return 0


if __name__ == "__main__":
    sys.exit(main())
