#!/usr/bin/env python
"""What hearing the direction costs per physics step (benchmark, not a test): the demo scene
(or any MJCF) heard three ways in the same process, interleaved in rounds:

* ``isotropic``: every model's pattern replaced by its RMS in every direction (the synthesis
  before directions: none of :mod:`mjsound.synth.directivity` runs);
* ``as_is``: the models' own ``radiation_pattern`` (what the analysis stores);
* ``synthetic``: every model given a pattern of spherical-harmonic order ``--order`` (each
  mode's factor a seeded random combination of the harmonics up to that order, RMS 1, so every
  mode keeps that order: the synthesis's work for patterns that fine).

CPU time (``time.process_time``: the machine is shared), physics only in the same rounds; the
medians over rounds of each round's ``step_ratio`` (time per step with audio / physics only) and
of the differences to ``isotropic`` [us per step].

``--env Ant-v5``: a gymnasium env instead (``AudioObservation``, waveform mode, 16 kHz), bare
and the three wrapped, the same seeded random actions, ``--steps`` env steps per round; ratios
against the bare env.

Usage: python scripts/bench_directivity.py [SCENE.xml] [--duration 3] [--rounds 5] [--order 16]
       python scripts/bench_directivity.py --env Ant-v5 [--steps 500] [--rounds 5] [--order 16]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

VARIANTS = ("isotropic", "as_is", "synthetic")


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


def isotropic_pattern(self, directions):
    """``radiation`` in every direction."""
    import numpy as np

    return np.broadcast_to(self.radiation.astype(np.complex128), (len(directions), len(self.radiation)))


def made_as(variant: str, order: int, make):
    """``make()`` with every ModalModel's pattern as ``variant`` says (the fit happens when the
    synthesizer adds the objects, inside ``make``)."""
    from mjsound.modal.model import ModalModel

    if variant == "as_is":
        return make()
    had = ModalModel.__dict__["radiation_pattern"]
    ModalModel.radiation_pattern = isotropic_pattern if variant == "isotropic" else synthetic_pattern(order)
    try:
        return make()
    finally:
        ModalModel.radiation_pattern = had


def summary(t: dict, base: str, steps: int) -> dict:
    """Median ratios to ``base`` and differences to ``isotropic`` [us per step] of the rounds' times."""
    import numpy as np

    t = {k: np.array(v) for k, v in t.items()}
    out = {f"step_ratio_{k}": float(np.median(t[k] / t[base])) for k in VARIANTS}
    out.update({f"{k}_us_per_step": 1e6 * float(np.median(t[k] - t["isotropic"])) / steps for k in VARIANTS[1:]})
    out[f"us_per_step_{base}"] = 1e6 * float(np.median(t[base])) / steps
    return out


def bench_env(args) -> dict:
    """The ``--env`` protocol (module docstring)."""
    import gymnasium as gym
    import numpy as np

    from mjsound import AudioObservation

    envs = {"bare": gym.make(args.env)}
    for k in VARIANTS:
        envs[k] = made_as(k, args.order, lambda: AudioObservation(gym.make(args.env), sample_rate=16000,
                                                                  progress=False))
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
    return {"env": args.env, "steps": args.steps, "rounds": args.rounds, "order": args.order,
            **summary(t, "bare", args.steps)}


def main(argv=None) -> int:
    import mujoco
    import numpy as np

    from mjsound.sim import AudioSimulator, SoundScene
    from mjsound.sim.demo import find_demo_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=None, help="MJCF (default: the demo scene)")
    p.add_argument("--duration", type=float, default=3.0, help="simulated seconds (default 3)")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--order", type=int, default=16, help="spherical-harmonic order of the synthetic patterns")
    p.add_argument("--sample-rate", type=int, default=48000)
    p.add_argument("--env", default=None, help="a gymnasium env id (e.g. Ant-v5) instead of a scene")
    p.add_argument("--steps", type=int, default=500, help="env steps per round (--env)")
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
    sims = {}
    for k in VARIANTS:
        reset()
        sims[k] = made_as(k, args.order, lambda: AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate))
    orders = {k: sorted({int(o) for n in s.synth.objects for o in s.synth.object_modes(n).directions.orders})
              for k, s in sims.items()}
    for sim in sims.values():  # warm-up (numba)
        reset()
        sim.reset()
        sim.run(0.05)
    t = {"physics": [], **{k: [] for k in VARIANTS}}
    peaks = {}
    for _ in range(args.rounds):
        reset()
        t0 = time.process_time()
        for _ in range(nsteps):
            mujoco.mj_step(model, data)
        t["physics"].append(time.process_time() - t0)
        for k, sim in sims.items():
            reset()
            sim.reset()
            t0 = time.process_time()
            audio = sim.run(args.duration)
            t[k].append(time.process_time() - t0)
            air = [i for i in range(audio.shape[0]) if i not in sim.synth._contacts]
            peaks[k] = [round(float(np.abs(audio[i]).max()), 4) for i in air]
    out = {"scene": os.path.basename(path), "steps": nsteps, "objects": len(sims["as_is"].synth.objects),
           "mode_orders": orders, **summary(t, "physics", nsteps), "air_peaks_pa": peaks}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
