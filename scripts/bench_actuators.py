#!/usr/bin/env python
"""Step-time cost of actuator noise (benchmark, not a test): a gymnasium env (default Ant-v5,
8 hinge actuators; or a gymnasium-robotics one, e.g. FetchPickAndPlace-v4, whose arm moves by
mocap and whose 2 gripper fingers are slide actuators) wrapped in ``AudioObservation`` with
actuators off against the same with a preset on every actuator
(``sim_kwargs={"actuators": PRESET}``), CPU time per ``env.step`` (``time.process_time``) on
the same seeded random actions, in interleaved rounds (off, on, off, ...) of ``--steps`` steps;
``ratio`` = median over rounds of on / off. Goal (issue 38): <= 1.10.

    python scripts/bench_actuators.py --rounds 6 --steps 100 --preset qdd
    python scripts/bench_actuators.py --env FetchPickAndPlace-v4 --preset servo --sample-rate 48000

(At the wrapper's default 16 kHz, Fetch's gripper links have no audible mode, so its
gripper's drives are silent and cost nothing; at 48 kHz they ring. ``--materials
GEOM=MATERIAL,...`` gives geoms materials, in both envs.)
"""

import argparse
import json
import time

import gymnasium as gym
import numpy as np

from mjsound.wrappers import AudioObservation


def make(name):
    """``gym.make(name)``; a gymnasium-robotics env registers that package first (and its
    mujoco 4 patch: :func:`mjsound.compat.patch_gymnasium_robotics`)."""
    if name not in gym.registry:
        import gymnasium_robotics

        from mjsound.compat import patch_gymnasium_robotics

        patch_gymnasium_robotics()
        gym.register_envs(gymnasium_robotics)
    return gym.make(name)


#: The options :func:`add_arguments` declares, as ``measure``'s arguments (``scripts/
#: bench_actuator_ablation.py`` hands them on to its variants' processes).
OPTIONS = ("env", "preset", "rounds", "steps", "sample_rate", "materials")


def add_arguments(ap, rounds=6):
    """The benchmark's options (:data:`OPTIONS`) on the parser ``ap``."""
    ap.add_argument("--env", default="Ant-v5")
    ap.add_argument("--preset", default="qdd")
    ap.add_argument("--rounds", type=int, default=rounds)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--sample-rate", type=int, default=16000, help="AudioObservation's sample rate [Hz]")
    ap.add_argument("--materials", default="", help="GEOM=MATERIAL,... for both envs (sim_kwargs materials)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(ap)
    args = ap.parse_args()
    print(json.dumps(measure(args.env, args.preset, args.rounds, args.steps, args.sample_rate, args.materials)))


def measure(name, preset, rounds, steps, sr, materials=""):
    """The benchmark's figures for env ``name`` with ``preset`` on every actuator (module
    docstring): a dict of the env, the preset, its actuators, the sample rate, the materials,
    the median CPU times per step off and on [ms] and the median of their ratio."""
    kw = {"materials": dict(kv.split("=", 1) for kv in materials.split(","))} if materials else {}
    envs = {"off": AudioObservation(make(name), sample_rate=sr, sim_kwargs=dict(kw)),
            "on": AudioObservation(make(name), sample_rate=sr, sim_kwargs={**kw, "actuators": preset})}
    rng = np.random.default_rng(0)
    space = envs["off"].action_space
    acts = rng.uniform(space.low, space.high, (steps, space.shape[0]))
    times = {k: [] for k in envs}
    for k, env in envs.items():  # (warm-up: numba, first streams)
        env.reset(seed=0)
        for a in acts[:20]:
            env.step(a)
    for _ in range(rounds):
        for k, env in envs.items():
            env.reset(seed=0)
            t = time.process_time()
            for a in acts:
                _, _, term, trunc, _ = env.step(a)
                if term or trunc:
                    env.reset(seed=0)
            times[k].append((time.process_time() - t) / len(acts))
    off, on = np.array(times["off"]), np.array(times["on"])
    return {"env": name, "preset": preset, "actuators": int(envs["on"].unwrapped.model.nu), "sample_rate": sr,
            "materials": materials, "off_ms": 1e3 * float(np.median(off)), "on_ms": 1e3 * float(np.median(on)),
            "ratio": float(np.median(on / off))}

if __name__ == "__main__":
    main()
