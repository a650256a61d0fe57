"""Compile the per-step and render kernels before timing anything.

numba compiles each kernel the first time a process calls it and keeps the machine code in
its on-disk cache (``cache=True``), so only the first run on a machine pays. :func:`warmup`
runs a tiny scene through every path (advance, single steps, replay-style explicit steps,
rendering with events and streams) so that a caller can separate compile time from
speed figures (:mod:`.first_compile`: whether the cache is cold, and the line said then).
"""

from __future__ import annotations

import time
import warnings

from .first_compile import kernel_cache_dir, kernels_cached, notice_first_compile  # noqa: F401 (re-exported)

__all__ = ["warmup", "kernels_cached", "kernel_cache_dir", "notice_first_compile"]

_WARMED = [False]

_XML = """<mujoco><option timestep="0.002"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:box" data="oak"/>
    <text name="mjsound:arm" data="aluminium"/></custom>
  <worldbody><geom name="floor" type="plane" size="2 2 .1"/>
    <body name="ball" pos="0 0 0.05"><freejoint/><geom name="ball" type="sphere" size="0.02"/></body>
    <body name="box" pos="0.3 0 0.03"><freejoint/><geom name="box" type="box" size="0.04 0.03 0.03"/></body>
    <body name="arm" pos="-0.5 0 0.3"><joint name="hinge" type="hinge" axis="0 0 1" armature="0.01"/>
      <geom name="arm" type="box" size="0.05 0.01 0.01"/></body>
  </worldbody><actuator><velocity name="motor" joint="hinge" kv="0.02"/></actuator></mujoco>"""


def warmup(verbose: bool = True, once: bool = False) -> float:
    """Compile (or load from the cache) every kernel of the per-step and render paths by
    running a tiny two-body scene for 0.1 s: advance (the kernel stepping), single steps, a replayed step,
    impacts, a sliding and rolling stream (rendered in one call and in stages), clicks, a motor's
    drive tones, forcing sources and listeners following a body. Returns the seconds it took; with ``once``, 0.0 when this process has
    warmed up already."""
    if once and _WARMED[0]:
        return 0.0
    import mujoco
    import numpy as np

    from .scene import SoundScene
    from .simulator import AudioSimulator
    from .stub import stub_model

    t0 = time.perf_counter()
    notice_first_compile(quiet=not verbose)
    model = mujoco.MjModel.from_xml_string(_XML)
    data = mujoco.MjData(model)
    data.qvel[0] = 0.5  # the ball rolls, the box slides: impacts, streams, rolling (the ball's
    # modes below 0.45 fs: its stream sounds, so the blocks while it rolls take render_streams)
    data.qvel[8] = 0.8
    data.qvel[2] = -1.0
    data.ctrl[0] = 3.0  # the arm's motor turns it: actuator drive tones (docs/actuators.md)
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 3000.0), "box": stub_model("box:0.08,0.06,0.06", "oak", 4, 700.0),
              "arm": stub_model("box:0.1,0.02,0.02", "aluminium", 4, 2000.0)}
    with warnings.catch_warnings():  # (the stub models' masses are not the bodies')
        warnings.simplefilter("ignore")
        scene = SoundScene.from_model(model, models=models, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=16000, actuators="servo")
    sim.run(0.05)
    for _ in range(10):
        mujoco.mj_step(model, data)
        sim.step()
    sim.synth.fused_streams = False
    sim.advance(5, render=False)
    sim.flush()
    t = float(data.time)
    mujoco.mj_forward(model, data)
    sim.driver.replay(sim.clock.n, sim.clock.n + 32, t, t + 0.002)
    sim.synth.impact("ball", [0, 0, 0], [0, 0, 0.01], time=sim.synth.time)
    sim.synth.slide("box", [0.3, 0, 0], [0, 0, 1], 1.0, 0.1, sim.synth.time, sim.synth.time + 0.01)
    sim.synth.render(256)
    sim.reader.events(data)
    sim.follow(1, np.tile([0.0, 0.0, 0.5], (sim.n_air, 1)))  # listeners riding a body (gymnasium envs)
    sim.reset()  # (moves them there)
    sim.advance(5, render=False)
    assert np.isfinite(sim.flush()).all()
    _WARMED[0] = True
    return time.perf_counter() - t0
