#!/usr/bin/env python
"""SHA-1 digests of reference audio, to check that a refactoring keeps the sound bit for bit.

Cases (each a fresh simulator, seeded):

* ``demo-run``: the demo scene from its keyframe, ``AudioSimulator.run(3.0)`` at 48 kHz
  (``advance`` in ``render_block_s`` chunks, the kernel stepping MuJoCo);
* ``demo-step``: the same 3 s through ``mj_step`` + ``AudioSimulator.step()`` per physics step
  (the caller-steps path);
* ``Ant-v5`` / ``Walker2d-v5``: ``AudioObservation(gym.make(id), sample_rate=16000)``, reset
  with seed 0, 300 env steps of actions from ``np.random.default_rng(0)`` (reset on
  termination), the audio observation of every step concatenated.

Usage: python scripts/audio_digest.py [--cases demo-run demo-step Ant-v5 Walker2d-v5] [--free-field]
(``--free-field``: ``reflections=False`` everywhere, the audio of before the floor reflected).
Prints one line per case: ``case sha1 samples peak``. Compare two commits' lines (same machine,
same kernels: ``MJSOUND_SHIPPED_KERNELS=0`` for host-compiled ones on both sides).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import warnings

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402


def demo(path: str, reflections: bool = True) -> np.ndarray:
    import mujoco

    from mjsound.sim import AudioSimulator
    from mjsound.sim.demo import find_demo_scene

    model = mujoco.MjModel.from_xml_path(find_demo_scene())
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    sim = AudioSimulator(model, data, sample_rate=48000, progress=False, reflections=reflections)
    if path == "run":
        return sim.run(3.0)
    n = int(round(3.0 / model.opt.timestep))
    blocks = []
    for _ in range(n):
        mujoco.mj_step(model, data)
        blocks.append(sim.step())
    return np.concatenate(blocks, axis=1)


def env(env_id: str, steps: int = 300, reflections: bool = True) -> np.ndarray:
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    e = AudioObservation(gym.make(env_id), sample_rate=16000, reflections=reflections)
    rng = np.random.default_rng(0)
    e.reset(seed=0)
    out = []
    for _ in range(steps):
        obs, _, term, trunc, _ = e.step(rng.uniform(-1, 1, e.action_space.shape).astype(np.float32))
        out.append(np.array(obs["audio"]))
        if term or trunc:
            e.reset()
    e.close()
    return np.concatenate(out, axis=-1)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=["demo-run", "demo-step", "Ant-v5", "Walker2d-v5"])
    p.add_argument("--free-field", action="store_true", help="reflections=False (no image microphones)")
    args = p.parse_args(argv)
    refl = not args.free_field
    warnings.simplefilter("ignore")
    for case in args.cases:
        audio = demo(case.split("-")[1], refl) if case.startswith("demo-") else env(case, reflections=refl)
        audio = np.ascontiguousarray(audio)
        print(f"{case:12s} {hashlib.sha1(audio.tobytes()).hexdigest()} {audio.shape[-1]} "
              f"{float(np.abs(audio).max()):.6g}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
