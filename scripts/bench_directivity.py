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

Usage: python scripts/bench_directivity.py [SCENE.xml] [--duration 3] [--rounds 5] [--order 8]
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


def main(argv=None) -> int:
    import mujoco
    import numpy as np

    from mjsound.modal.model import ModalModel
    from mjsound.sim import AudioSimulator, SoundScene
    from mjsound.sim.demo import find_demo_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=None, help="MJCF (default: the demo scene)")
    p.add_argument("--duration", type=float, default=3.0, help="simulated seconds (default 3)")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--order", type=int, default=8, help="spherical-harmonic order of the patterns (default 8)")
    p.add_argument("--sample-rate", type=int, default=48000)
    args = p.parse_args(argv)
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
    had = getattr(ModalModel, "radiation_pattern", None)
    reset()
    sim_as_is = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate)
    ModalModel.radiation_pattern = synthetic_pattern(args.order)
    try:
        reset()
        sim_dir = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate)
    finally:
        if had is None:
            del ModalModel.radiation_pattern
        else:
            ModalModel.radiation_pattern = had
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
