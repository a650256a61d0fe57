#!/usr/bin/env python
"""Env families built their own way, heard through ``AudioObservation`` for a few hundred steps
(issue 40's check; a script, not a test: their first construction analyses their robots' parts).

For each env: seeded random actions (episodes reset when they end), default options at 16 kHz;
printed: the route found (``mjsound.env_stepping``), the window, the samples delivered against the
simulated time of the steps taken (all of it must be heard), the physics steps heard, impacts
heard, the peak and 95th percentile of the steps' peak pressure [Pa], and every warning raised
(message and the file:line it names).

* MyoSuite 3.0.0 ``myoChallengeDieReorientP1-v0`` (``MyoGymnasiumEnv._step_physics``; installed
  with ``--no-deps``: it pins gymnasium < 1.3; needs ``myo-sim`` and ``colorednoise``);
* lerobot-env-so101 0.4.0 ``gym_so101/PickCube-v0`` (its own ``mj_step`` loop; ``--no-deps``: it
  pins mujoco < 4);
* robosuite 1.5.2 ``Lift`` / Panda through ``GymWrapper`` (``MjSim.step2`` of its own loop, a new
  ``MjSim`` at every hard reset; ``mjsound.compat.patch_robosuite``).

Usage: python scripts/check_env_families.py [--steps 300] [--only myosuite so101 robosuite]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from mjsound.wrappers import AudioObservation  # noqa: E402


def make(name, seed=None):
    """The inner env of family ``name`` (``seed``: robosuite's own generator, which places its
    cube; None: unseeded, as robosuite's default)."""
    if name == "myosuite":
        import myosuite  # noqa: F401

        return gym.make("myoChallengeDieReorientP1-v0")
    if name == "so101":
        import lerobot_env_so101

        return gym.make(lerobot_env_so101.ENV_ID)
    if name == "robosuite":
        from mjsound.compat import patch_robosuite

        patch_robosuite()
        import robosuite
        from robosuite.wrappers import GymWrapper

        return GymWrapper(robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                                         use_camera_obs=False, seed=seed))
    raise ValueError(name)


def check(name, steps, fs=16000) -> dict:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        env = AudioObservation(make(name), sample_rate=fs, progress=False)
        built = time.perf_counter() - t0
        env.reset(seed=0)
        env.action_space.seed(0)
        peaks, samples, simulated, impacts, heard = [], 0, 0.0, 0, 0
        t0 = time.perf_counter()
        for _ in range(steps):
            before, steps_before = float(env.sim.data.time), env.sim.steps
            _, _, term, trunc, info = env.step(env.action_space.sample())
            simulated += float(env.sim.data.time) - before
            heard += env.sim.steps - steps_before
            peaks.append(info["audio_peak_pa"])
            samples += info["audio_samples"]
            impacts += info["audio_impacts"]
            if term or trunc:
                env.reset()
        run = time.perf_counter() - t0
        timestep = float(env.sim.model.opt.timestep)
        out = dict(env=name, route=env._route.route if env._route else "manual", window=env.window,
                   samples=samples, samples_expected=round(simulated * fs), steps_heard=heard,
                   steps_simulated=round(simulated / timestep), impacts=impacts, peak_pa=float(np.max(peaks)),
                   p95_pa=float(np.percentile(peaks, 95)), construct_s=built, ms_per_step=1e3 * run / steps)
        env.close()
    out["warnings"] = [f"{w.category.__name__} at {os.path.basename(w.filename)}:{w.lineno}: {str(w.message)[:160]}"
                       for w in caught if "mjsound" in str(w.message)]
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--only", nargs="*", default=["myosuite", "so101", "robosuite"])
    args = p.parse_args(argv)
    for name in args.only:
        r = check(name, args.steps)
        print(f"{r['env']}: {r['route']}; window {r['window']} samples; {r['samples']} samples for "
              f"{r['samples_expected']} simulated ({r['steps_heard']} of {r['steps_simulated']} physics steps heard); "
              f"{r['impacts']} impacts; peak {r['peak_pa']:.3g} Pa, p95 {r['p95_pa']:.3g} Pa; "
              f"built in {r['construct_s']:.1f} s, {r['ms_per_step']:.1f} ms an env step (wall)")
        for w in r["warnings"]:
            print(f"    {w}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
