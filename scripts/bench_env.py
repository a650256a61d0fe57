#!/usr/bin/env python
"""Step-time cost of AudioObservation on gymnasium's Ant-v5 and Humanoid-v5 and gymnasium-robotics'
FetchPickAndPlace-v4, and the cold construction time of the Fetch env (benchmark, not a test).

For each env: the CPU time per ``env.step`` (``time.process_time``: this machine is shared, and
CPU time is what another process cannot inflate) bare, wrapped in waveform mode and wrapped in
spectrogram mode, on the same seeded random actions (reset on termination, resets not timed;
numba warm-up and modal analysis excluded). The three are measured in interleaved rounds
(bare, waveform, spectrogram, bare, ...) so that drifting machine load hits all of them alike;
``step_ratio = median over rounds of wrapped / bare``; a fourth variant, waveform with clicks
off (``clicks=False``, no contact microphones: these envs have no ``contact_mic`` site), in the
same rounds gives ``step_ratio_clicks_off``, and a fifth, waveform with the floor's reflection off
(``reflections=False``: free field, docs/rooms.md), ``step_ratio_reflections_off``. Then the throughput of an
``AsyncVectorEnv`` of 2 wrapped Ant-v5 (waveform): env steps per wall second summed over both
envs. Goal (issue 5): step_ratio <= 1.5 in waveform mode.

gymnasium-robotics envs (``--robotics``, default FetchPickAndPlace-v4; run through
``mjsound.compat.patch_gymnasium_robotics`` on mujoco 4) get actions that drive the gripper down
onto the table for the first half of every 50-step episode and random ones after, so that the
timed steps include contacts. Goal (issue 15): step_ratio <= 1.3.

``--blocks N`` (optional): a second, finer protocol for the waveform mode, in the same
process: the bare and the wrapped env alternate every ``--block-steps`` env steps (default 25;
each block's mean CPU time per step), ``N`` blocks each, on the same seeded actions (the
same trajectories: the audio does not act on the physics); ``block_ratio`` is the median over
blocks of wrapped / bare and ``block_overhead_us`` the median of the difference. Alternating
that often, the machine's drift hits both alike; four runs of it told apart a change of 0.03
that eight runs of the rounds above did not.

Cold construction (``--cold``): ``AudioObservation(gym.make(FETCH), sample_rate=fs)`` timed (wall
and CPU seconds; the analysis uses both cores, so on a loaded machine the CPU time is the steadier
figure) in a fresh process with an empty ``MJSOUND_CACHE_DIR`` (no model cache, no in-process memo; numba's own
on-disk cache of compiled kernels is used as a user's second run would: compile time is not
analysis time), at each ``--cold-rates``. Goal (issue 15): under 10 s.

Other env families (``--families metaworld aloha robosuite composer``, or ``all``): one task of each,
bare against wrapped (waveform, default options), CPU time per env step in interleaved rounds as
above on seeded random actions: Meta-World ``pick-place-v3`` (``AudioObservation``, through
``mjsound.compat.patch_metaworld``), gym-aloha ``AlohaInsertion-v0`` (``AudioObservation`` on its
dm_control physics; its steps render three 640x480 camera images, most of their time), robosuite
``Lift`` / Panda (``GymWrapper`` + ``AudioObservation``, ``patch_robosuite``) and dm_control
composer ``stack_2_bricks_features`` (``mjsound.dmc.AudioEnvironment``; a ``LAST`` step's
automatic reset is timed as dm_env makes it part of ``step``). ``--family-steps`` steps per round
(gym-aloha: a tenth of it).

Usage: python scripts/bench_env.py [--steps 300] [--rounds 5] [--sample-rate 16000] [--envs ...]
       [--robotics ...] [--cold] [--cold-rates 16000 48000] [--blocks 0] [--block-steps 25]
       [--families ...] [--family-steps 100] [--json]
With --json one object: {"envs": [{"id", "mode", "step_ratio", "bare_ms", "wrapped_ms", ("block_ratio", ...) ...}],
"async2_steps_per_s", "cold": [{"id", "sample_rate", "seconds", "modes", ...}], ...}.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from mjsound.wrappers import AudioObservation  # noqa: E402


def warm_up(env, acts, seed=0) -> None:
    """Reset ``env`` with ``seed`` and step it through ``acts[:20]`` (numba, caches)."""
    env.reset(seed=seed)
    for a in acts[:20]:
        _, _, te, tr, _ = env.step(a)
        if te or tr:
            env.reset()


def time_steps(env, acts, seed=0):
    """Mean CPU seconds per ``env.step`` over ``acts`` (after a warm-up)."""
    warm_up(env, acts, seed)
    env.reset(seed=seed)
    total = 0.0
    for a in acts:
        t0 = time.process_time()
        _, _, te, tr, _ = env.step(a)
        total += time.process_time() - t0
        if te or tr:
            env.reset()
    return total / len(acts)


def time_blocks(bare, wrapped, acts, n_blocks, block_steps, seed=0) -> dict:
    """The ``--blocks`` protocol (module docstring): CPU seconds per step of each block of
    ``block_steps`` steps, the two envs alternating block by block (which goes first
    alternates too), resets not timed."""
    envs = (bare, wrapped)
    pos = [0, 0]
    for e in envs:
        warm_up(e, acts, seed)
    per = ([], [])
    for b in range(n_blocks):
        for i in ((0, 1) if b % 2 == 0 else (1, 0)):
            e, total = envs[i], 0.0
            for _ in range(block_steps):
                a = acts[pos[i] % len(acts)]
                pos[i] += 1
                t0 = time.process_time()
                _, _, te, tr, _ = e.step(a)
                total += time.process_time() - t0
                if te or tr:
                    e.reset()
            per[i].append(total / block_steps)
    b, w = np.array(per[0]), np.array(per[1])
    return {"block_ratio": float(np.median(w / b)), "block_overhead_us": float(1e6 * np.median(w - b)),
            "block_bare_ms": float(1e3 * np.median(b)), "blocks": n_blocks, "block_steps": block_steps}


def make_env(env_id):
    """``gym.make(env_id)``; gymnasium-robotics ids are registered (and patched for mujoco 4) first."""
    if env_id not in gym.registry:
        import gymnasium_robotics

        from mjsound.compat import patch_gymnasium_robotics

        patch_gymnasium_robotics()
        gym.register_envs(gymnasium_robotics)
    return gym.make(env_id)


def actions(env_id, space, n):
    """Seeded random actions; for gymnasium-robotics' Fetch: down onto the table for the first
    25 steps of every 50 (an episode), random after."""
    space.seed(0)
    acts = [space.sample() for _ in range(n)]
    if env_id.startswith("Fetch"):
        down = np.zeros(space.shape, space.dtype)
        down[2] = -1.0
        acts = [down if i % 50 < 25 else a for i, a in enumerate(acts)]
    return acts


def make_family(name, wrapped, fs):
    """``(env, reset, action_space)`` of one task of a family (``--families``), bare or wrapped
    (waveform, default options)."""
    if name == "composer":
        from dm_control import manipulation

        from mjsound.dmc import AudioEnvironment

        env = manipulation.load("stack_2_bricks_features", seed=0)
        if wrapped:
            env = AudioEnvironment(env, seed=0, sample_rate=fs, progress=False)
        spec = env.action_spec()
        space = gym.spaces.Box(spec.minimum.astype(np.float32), spec.maximum.astype(np.float32), dtype=np.float32)
        return env, (lambda: env.reset()), space
    if name == "metaworld":
        import metaworld  # noqa: F401

        from mjsound.compat import patch_metaworld

        patch_metaworld()
        env = gym.make("Meta-World/MT1", env_name="pick-place-v3")
    elif name == "aloha":
        os.environ.setdefault("MUJOCO_GL", "egl")
        import gym_aloha  # noqa: F401

        env = gym.make("gym_aloha/AlohaInsertion-v0")
    elif name == "robosuite":
        from mjsound.compat import patch_robosuite

        patch_robosuite()
        import robosuite
        from robosuite.wrappers import GymWrapper

        env = GymWrapper(robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                                        use_camera_obs=False))
    else:
        raise ValueError(f"--families: unknown family {name!r} (metaworld, aloha, robosuite, composer)")
    if wrapped:
        env = AudioObservation(env, sample_rate=fs, progress=False)
    return env, (lambda: env.reset(seed=0)), env.action_space


def time_family(made, acts) -> float:
    """Mean CPU seconds per env step of a ``make_family`` env over ``acts`` (resets not timed
    but composer's automatic one)."""
    env, reset, _ = made
    reset()
    total = 0.0
    for a in acts:
        t0 = time.process_time()
        out = env.step(a)
        total += time.process_time() - t0
        if isinstance(out, tuple) and (out[2] or out[3]):
            reset()
    return total / len(acts)


def family_rows(families, fs, steps, rounds) -> list:
    """The ``--families`` measurements (module docstring)."""
    rows = []
    for name in families:
        made = {"bare": make_family(name, False, fs), "waveform": make_family(name, True, fs)}
        n = max(3, steps // 10) if name == "aloha" else steps
        space = made["bare"][2]
        space.seed(0)
        acts = [space.sample() for _ in range(n)]
        for m in made.values():  # warm-up: numba, caches, robosuite's own numba
            time_family(m, acts[:5])
        times = {k: [] for k in made}
        for _ in range(rounds):
            for k, m in made.items():
                times[k].append(time_family(m, acts))
        bare, wrapped = np.array(times["bare"]), np.array(times["waveform"])
        env = made["waveform"][0]
        rows.append({"id": name, "mode": "waveform", "step_ratio": float(np.median(wrapped / bare)),
                     "bare_ms": 1e3 * float(np.median(bare)), "wrapped_ms": 1e3 * float(np.median(wrapped)),
                     "steps": n, "sounding_objects": len(env.scene.sounding), "modes": env.scene.n_modes})
        for m in made.values():
            m[0].close()
    return rows


COLD = """
import os, sys, time, json
sys.path.insert(0, {root!r})
sys.argv = ["cold"]
from scripts.bench_env import make_env
from mjsound.wrappers import AudioObservation
env = make_env({env_id!r})
t0, c0 = time.perf_counter(), time.process_time()
w = AudioObservation(env, sample_rate={fs}, progress=False)
dt, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({{"seconds": dt, "cpu_seconds": cpu, "modes": w.scene.n_modes, "objects": len(w.scene.sounding),
                  "notes": [n for s in w.scene.sounding for n in s.notes if "large solid" in n]}}))
"""


def cold_construction(env_id, fs) -> dict:
    """Seconds to construct the wrapper in a fresh process with an empty model cache."""
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "MJSOUND_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, "-c", COLD.format(root=root, env_id=env_id, fs=fs)], env=env,
                             capture_output=True, text=True, check=True)
    return {"id": env_id, "sample_rate": fs, **json.loads(out.stdout.strip().splitlines()[-1])}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--blocks", type=int, default=0, help="also the block-alternating protocol, this many blocks")
    p.add_argument("--block-steps", type=int, default=25)
    p.add_argument("--sample-rate", type=int, default=16000)
    p.add_argument("--envs", nargs="*", default=["Ant-v5", "Humanoid-v5"])
    p.add_argument("--robotics", nargs="*", default=["FetchPickAndPlace-v4"])
    p.add_argument("--cold", action="store_true", help="also time cold construction of the first --robotics env")
    p.add_argument("--cold-rates", nargs="+", type=int, default=[16000, 48000])
    p.add_argument("--async-seconds", type=float, default=5.0)
    p.add_argument("--families", nargs="*", default=[], help="metaworld aloha robosuite composer, or all")
    p.add_argument("--family-steps", type=int, default=100)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    if args.families == ["all"]:
        args.families = ["metaworld", "aloha", "robosuite", "composer"]
    rows = []
    cold = []
    if args.cold and args.robotics:
        for fs in args.cold_rates:
            cold.append(cold_construction(args.robotics[0], fs))
            if not args.json:
                c = cold[-1]
                print(f"cold construction {c['id']} at {fs} Hz: {c['seconds']:.1f} s wall, {c['cpu_seconds']:.1f} s CPU "
                      f"(both cores; load {os.getloadavg()[0]:.1f}) ({c['objects']} objects, "
                      f"{c['modes']} modes; {'; '.join(c['notes']) or 'no mode budget'})", flush=True)
    for env_id in list(args.envs) + list(args.robotics):
        envs = {"bare": make_env(env_id)}
        for mode in ("waveform", "spectrogram"):
            envs[mode] = AudioObservation(make_env(env_id), sample_rate=args.sample_rate, mode=mode, progress=False)
        envs["clicks_off"] = AudioObservation(make_env(env_id), sample_rate=args.sample_rate, mode="waveform",
                                              progress=False, clicks=False, contact_mics=[])
        envs["reflections_off"] = AudioObservation(make_env(env_id), sample_rate=args.sample_rate, mode="waveform",
                                                   progress=False, reflections=False)
        acts = actions(env_id, envs["bare"].action_space, args.steps)
        times = {k: [] for k in envs}
        for _ in range(args.rounds):
            for k, env in envs.items():
                times[k].append(time_steps(env, acts))
        t_bare = float(np.median(times["bare"]))
        for mode in ("waveform", "spectrogram"):
            env = envs[mode]
            ratio = float(np.median(np.array(times[mode]) / np.array(times["bare"])))
            off = float(np.median(np.array(times["clicks_off"]) / np.array(times["bare"])))
            free = float(np.median(np.array(times["reflections_off"]) / np.array(times["bare"])))
            rows.append({"id": env_id, "mode": mode, "step_ratio": ratio, "step_ratio_clicks_off": off,
                         "step_ratio_reflections_off": free,
                         "bare_ms": 1e3 * t_bare,
                         "wrapped_ms": 1e3 * float(np.median(times[mode])),
                         "sounding_objects": len(env.scene.sounding), "modes": env.scene.n_modes})
            if not args.json:
                r = rows[-1]
                print(f"{env_id:<14s} {mode:<12s} bare {r['bare_ms']:.3f} ms  wrapped {r['wrapped_ms']:.3f} ms  "
                      f"ratio {r['step_ratio']:.2f} (clicks off {r['step_ratio_clicks_off']:.2f}, reflections off "
                      f"{r['step_ratio_reflections_off']:.2f})  "
                      f"({r['sounding_objects']} objects, {r['modes']} modes; "
                      f"CPU time, median of {args.rounds} interleaved rounds)", flush=True)
        if args.blocks:
            blk = time_blocks(envs["bare"], envs["waveform"], acts, args.blocks, args.block_steps)
            next(r for r in rows if r["id"] == env_id and r["mode"] == "waveform").update(blk)
            if not args.json:
                print(f"{env_id:<14s} waveform     blocks: ratio {blk['block_ratio']:.3f}, mjsound "
                      f"{blk['block_overhead_us']:.1f} us an env step (bare {blk['block_bare_ms']:.3f} ms; median "
                      f"of {args.blocks} alternating blocks of {args.block_steps} steps)", flush=True)
        for env in envs.values():
            env.close()

    for r in family_rows(args.families, args.sample_rate, args.family_steps, args.rounds):
        rows.append(r)
        if not args.json:
            print(f"{r['id']:<14s} waveform     bare {r['bare_ms']:.3f} ms  wrapped {r['wrapped_ms']:.3f} ms  "
                  f"ratio {r['step_ratio']:.2f}  ({r['sounding_objects']} objects, {r['modes']} modes; CPU time, "
                  f"median of {args.rounds} interleaved rounds of {r['steps']} steps)", flush=True)

    fs = args.sample_rate
    venv = gym.vector.AsyncVectorEnv([lambda: AudioObservation(gym.make("Ant-v5"), sample_rate=fs, progress=False)
                                      for _ in range(2)])
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
    out = {"envs": rows, "async2_steps_per_s": rate, "sample_rate": fs, "steps": args.steps, "cold": cold,
           "async2_note": "env steps per wall second summed over the 2 envs (Ant-v5, waveform)"}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"AsyncVectorEnv(2 x Ant-v5 + audio): {rate:.0f} env steps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
