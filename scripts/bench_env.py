#!/usr/bin/env python
"""Step-time cost of AudioObservation on gymnasium's Ant-v5 and Humanoid-v5 (benchmark, not a test).

For each env: the CPU time per ``env.step`` (``time.process_time``: this machine is shared, and
CPU time is what another process cannot inflate) bare, wrapped in waveform mode and wrapped in
spectrogram mode, on the same seeded random actions (reset on termination, resets not timed;
numba warm-up and modal analysis excluded). The three are measured in interleaved rounds
(bare, waveform, spectrogram, bare, ...) so that drifting machine load hits all of them alike;
``step_ratio = median over rounds of wrapped / bare``. Then the throughput of an
``AsyncVectorEnv`` of 2 wrapped Ant-v5 (waveform): env steps per wall second summed over both
envs. Goal (issue 5): step_ratio <= 1.5 in waveform mode.

Usage: python scripts/bench_env.py [--steps 300] [--rounds 5] [--sample-rate 16000] [--json]
With --json one object: {"envs": [{"id", "mode", "step_ratio", "bare_ms", "wrapped_ms", ...}],
"async2_steps_per_s", ...}.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from mjsound.wrappers import AudioObservation  # noqa: E402


def time_steps(env, acts, seed=0):
    """Mean CPU seconds per ``env.step`` over ``acts`` (after a warm-up)."""
    env.reset(seed=seed)
    for a in acts[:20]:  # warm-up (numba, caches)
        _, _, te, tr, _ = env.step(a)
        if te or tr:
            env.reset()
    env.reset(seed=seed)
    total = 0.0
    for a in acts:
        t0 = time.process_time()
        _, _, te, tr, _ = env.step(a)
        total += time.process_time() - t0
        if te or tr:
            env.reset()
    return total / len(acts)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--sample-rate", type=int, default=16000)
    p.add_argument("--envs", nargs="+", default=["Ant-v5", "Humanoid-v5"])
    p.add_argument("--async-seconds", type=float, default=5.0)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    rows = []
    for env_id in args.envs:
        envs = {"bare": gym.make(env_id)}
        for mode in ("waveform", "spectrogram"):
            envs[mode] = AudioObservation(gym.make(env_id), sample_rate=args.sample_rate, mode=mode)
        space = envs["bare"].action_space
        space.seed(0)
        acts = [space.sample() for _ in range(args.steps)]
        times = {k: [] for k in envs}
        for _ in range(args.rounds):
            for k, env in envs.items():
                times[k].append(time_steps(env, acts))
        t_bare = float(np.median(times["bare"]))
        for mode in ("waveform", "spectrogram"):
            env = envs[mode]
            ratio = float(np.median(np.array(times[mode]) / np.array(times["bare"])))
            st = env.sim.stats()
            rows.append({"id": env_id, "mode": mode, "step_ratio": ratio, "bare_ms": 1e3 * t_bare,
                         "wrapped_ms": 1e3 * float(np.median(times[mode])),
                         "sounding_geoms": len(env.scene.sounding), "modes": env.scene.n_modes,
                         "contact_us_per_substep": st["contact_us_per_step"],
                         "synth_us_per_substep": st["synth_us_per_step"],
                         "fused_us_per_substep": st["fused_us_per_step"]})
            if not args.json:
                r = rows[-1]
                print(f"{env_id:<14s} {mode:<12s} bare {r['bare_ms']:.3f} ms  wrapped {r['wrapped_ms']:.3f} ms  "
                      f"ratio {r['step_ratio']:.2f}  ({r['sounding_geoms']} geoms, {r['modes']} modes; per substep "
                      f"in numba {r['fused_us_per_substep']:.0f} us with mj_step, in Python contacts "
                      f"{r['contact_us_per_substep']:.0f} us, synth {r['synth_us_per_substep']:.0f} us; "
                      f"CPU time, median of {args.rounds} interleaved rounds)", flush=True)
        for env in envs.values():
            env.close()

    fs = args.sample_rate
    venv = gym.vector.AsyncVectorEnv([lambda: AudioObservation(gym.make("Ant-v5"), sample_rate=fs) for _ in range(2)])
    venv.reset(seed=[0, 1])
    venv.action_space.seed(0)
    for _ in range(10):
        venv.step(venv.action_space.sample())
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < args.async_seconds:
        venv.step(venv.action_space.sample())
        n += 1
    rate = 2 * n / (time.perf_counter() - t0)
    venv.close()
    out = {"envs": rows, "async2_steps_per_s": rate, "sample_rate": fs, "steps": args.steps,
           "async2_note": "env steps per wall second summed over the 2 envs (Ant-v5, waveform)"}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"AsyncVectorEnv(2 x Ant-v5 + audio): {rate:.0f} env steps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
