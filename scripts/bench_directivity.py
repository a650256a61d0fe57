#!/usr/bin/env python
"""What hearing the direction costs per physics step: the demo scene (or any MJCF) with its
models as they are, against the same scene with every model given a radiation pattern of
spherical-harmonic order ``--order`` (benchmark, not a test).

The patterns are synthetic (each mode's D a seeded random combination of the real spherical
harmonics up to the order, scaled to RMS 1, so every object is directional and the fit keeps
that order): what is measured is the synthesis's work, the same for any pattern of that order.
Three passes per round, interleaved (physics only, audio as is, audio with patterns), CPU time
(``time.process_time``: the machine is shared); the medians over rounds of each round's
``step_ratio`` (time per step with audio / physics only) and of the difference [us per step].
Both audio runs render the same scene in the same process, so their difference is what the
direction factors cost (evaluations, ramps, event and forcing scaling).

``--env Ant-v5``: a gymnasium env instead, bare / wrapped as is / wrapped with patterns
(``AudioObservation``, waveform mode), the same seeded random actions, interleaved in rounds
of ``--steps`` env steps; ratios against the bare env.

Usage: python scripts/bench_directivity.py [SCENE.xml] [--duration 3] [--rounds 5] [--order 8]
       python scripts/bench_directivity.py --env Ant-v5 [--steps 1000] [--rounds 7] [--order 8]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def synthetic_pattern(order: int, seed: int = 0):
    """A ``radiation_pattern`` method: mode i's pattern is ``radiation[i] * D_i(u)`` with D_i a
    seeded random real combination of the harmonics up to ``order`` of RMS 1."""
    import numpy as np

    from mjsound.synth.directivity import _basis, sh_count

    def radiation_pattern(self, directions):
        n = len(self.frequencies_hz)
        c = np.random.default_rng(seed).normal(size=(n, sh_count(order)))
        c /= np.linalg.norm(c, axis=1, keepdims=True) / np.sqrt(4 * np.pi)  # RMS 1 over the sphere
        return (_basis(order, np.asarray(directions, np.float64)) @ c.T) * self.radiation[None, :]

    return radiation_pattern


def with_patterns(order, make):
    """``make()`` with every ModalModel given :func:`synthetic_pattern` (the fit happens when
    the synthesizer adds the objects, inside ``make``)."""
    from mjsound.modal.model import ModalModel

    had = ModalModel.__dict__.get("radiation_pattern")
    ModalModel.radiation_pattern = synthetic_pattern(order)
    try:
        return make()
    finally:
        if had is None:
            del ModalModel.radiation_pattern
        else:
            ModalModel.radiation_pattern = had


def bench_env(args) -> dict:
    """The ``--env`` protocol (module docstring)."""
    import gymnasium as gym
    import numpy as np

    from mjsound import AudioObservation

    envs = {"bare": gym.make(args.env),
            "as_is": AudioObservation(gym.make(args.env), sample_rate=16000, progress=False),
            "directional": with_patterns(args.order, lambda: AudioObservation(gym.make(args.env), sample_rate=16000,
                                                                              progress=False))}
    acts = np.random.default_rng(0).uniform(-1, 1, (args.steps,) + envs["bare"].action_space.shape)
    t = {k: [] for k in envs}
    for r in range(args.rounds + 1):
        for k, e in envs.items():
            e.reset(seed=r)
            t0 = time.process_time()
            for a in acts:
                _, _, te, tr, _ = e.step(a)
                if te or tr:
                    e.reset()
            if r:  # (round 0: warm-up)
                t[k].append(time.process_time() - t0)
    t = {k: np.array(v) for k, v in t.items()}
    return {"env": args.env, "steps": args.steps, "rounds": args.rounds, "order": args.order,
            "step_ratio_as_is": float(np.median(t["as_is"] / t["bare"])),
            "step_ratio_directional": float(np.median(t["directional"] / t["bare"])),
            "directional_us_per_step": 1e6 * float(np.median(t["directional"] - t["as_is"])) / args.steps,
            "us_per_step_bare": 1e6 * float(np.median(t["bare"])) / args.steps}


def main(argv=None) -> int:
    import mujoco
    import numpy as np

    from mjsound.sim import AudioSimulator, SoundScene
    from mjsound.sim.demo import find_demo_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=None, help="MJCF (default: the demo scene)")
    p.add_argument("--duration", type=float, default=3.0, help="simulated seconds (default 3)")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--order", type=int, default=8, help="spherical-harmonic order of the patterns (default 8)")
    p.add_argument("--sample-rate", type=int, default=48000)
    p.add_argument("--env", default=None, help="a gymnasium env id (e.g. Ant-v5) instead of a scene")
    p.add_argument("--steps", type=int, default=1000, help="env steps per round (--env)")
    args = p.parse_args(argv)
    if args.env:
        print(json.dumps(bench_env(args), indent=1))
        return 0
    path = args.scene or find_demo_scene()
    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)

    def reset():
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        else:
            mujoco.mj_resetData(model, data)

    scene = SoundScene.from_model(model, sample_rate=args.sample_rate, progress=False)
    nsteps = int(round(args.duration / model.opt.timestep))
    reset()
    sim_as_is = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate)
    reset()
    sim_dir = with_patterns(args.order, lambda: AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate))
    orders = sorted({sim_dir.synth.object_modes(n).directions.order for n in sim_dir.synth.objects})
    for sim in (sim_as_is, sim_dir):  # warm-up (numba)
        reset()
        sim.reset()
        sim.run(0.05)
    t = {"physics": [], "as_is": [], "directional": []}
    peaks = {}
    for _ in range(args.rounds):
        reset()
        t0 = time.process_time()
        for _ in range(nsteps):
            mujoco.mj_step(model, data)
        t["physics"].append(time.process_time() - t0)
        for key, sim in (("as_is", sim_as_is), ("directional", sim_dir)):
            reset()
            sim.reset()
            t0 = time.process_time()
            audio = sim.run(args.duration)
            t[key].append(time.process_time() - t0)
            air = [i for i, n in enumerate(sim.channel_names) if i not in sim.synth._contacts]
            peaks[key] = [float(np.abs(audio[i]).max()) for i in air]
    t = {k: np.array(v) for k, v in t.items()}
    out = {
        "scene": os.path.basename(path),
        "steps": nsteps,
        "objects": len(sim_dir.synth.objects),
        "fitted_orders": orders,
        "step_ratio_as_is": float(np.median(t["as_is"] / t["physics"])),
        "step_ratio_directional": float(np.median(t["directional"] / t["physics"])),
        "directional_us_per_step": 1e6 * float(np.median(t["directional"] - t["as_is"])) / nsteps,
        "us_per_step_physics": 1e6 * float(np.median(t["physics"])) / nsteps,
        "air_peaks_pa": peaks,
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
