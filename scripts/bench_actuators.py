#!/usr/bin/env python
"""Step-time cost of actuator noise (benchmark, not a test): gymnasium's Ant-v5 wrapped in
``AudioObservation`` with actuators off against the same with a preset on all 8 actuators
(``sim_kwargs={"actuators": PRESET}``), CPU time per ``env.step`` (``time.process_time``) on
the same seeded random actions, in interleaved rounds (off, on, off, ...) of ``--steps`` steps;
``ratio`` = median over rounds of on / off. Goal (issue 38): <= 1.10.

    python scripts/bench_actuators.py --rounds 6 --steps 100 --preset qdd
"""

import argparse
import json
import time

import gymnasium as gym
import numpy as np

from mjsound.wrappers import AudioObservation


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="Ant-v5")
    ap.add_argument("--preset", default="qdd")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--steps", type=int, default=100)
    args = ap.parse_args()
    envs = {"off": AudioObservation(gym.make(args.env)),
            "on": AudioObservation(gym.make(args.env), sim_kwargs={"actuators": args.preset})}
    rng = np.random.default_rng(0)
    space = envs["off"].action_space
    acts = rng.uniform(space.low, space.high, (args.steps, space.shape[0]))
    times = {k: [] for k in envs}
    for k, env in envs.items():  # (warm-up: numba, first streams)
        env.reset(seed=0)
        for a in acts[:20]:
            env.step(a)
    for _ in range(args.rounds):
        for k, env in envs.items():
            env.reset(seed=0)
            t = time.process_time()
            for a in acts:
                _, _, term, trunc, _ = env.step(a)
                if term or trunc:
                    env.reset(seed=0)
            times[k].append((time.process_time() - t) / len(acts))
    off, on = np.array(times["off"]), np.array(times["on"])
    print(json.dumps({"env": args.env, "preset": args.preset, "off_ms": 1e3 * float(np.median(off)),
                      "on_ms": 1e3 * float(np.median(on)), "ratio": float(np.median(on / off))}))


if __name__ == "__main__":
    main()
