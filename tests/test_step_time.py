"""What ``AudioSimulator.step`` does when ``data.time`` is not one timestep after the last step
it read (issue 40): skipped steps and data that is no longer stepped are refused with an error
naming the call to use; a reset behind its back (``mj_resetData``) restarts it; ``rebind``
follows a new MjModel / MjData of the same scene."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjsound.sim import AudioSimulator, SoundScene
from mjsound.sim.stub import stub_model

FS = 16000

SCENE = """<mujoco><option timestep="0.002"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:box" data="oak"/></custom>
  <worldbody><geom name="floor" type="plane" size="2 2 .1"/>
    <body name="ball" pos="0 0 0.08"><freejoint/><geom name="ball" type="sphere" size="0.02"/></body>
    <body name="box" pos="0.3 0 0.05"><freejoint/><geom name="box" type="box" size="0.04 0.03 0.03"/></body>
  </worldbody></mujoco>"""

MODELS = {"ball": stub_model("sphere:0.02", "steel", 4, 3000.0), "box": stub_model("box:0.08,0.06,0.06", "oak", 4, 700.0)}


def make():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    data.qvel[0] = 0.3
    with pytest.warns(UserWarning):  # (the stub models' masses are not the bodies')
        scene = SoundScene.from_model(model, models=MODELS, progress=False)
    return model, data, AudioSimulator(model, data, scene=scene, sample_rate=FS)


def test_steps_skipped_between_calls_are_refused():
    """The issue's reproduction: 25 mj_steps per step() call gave 640 samples for 1 s, silently."""
    model, data, sim = make()
    mujoco.mj_step(model, data)
    assert sim.step().shape == (1, 32)
    mujoco.mj_step(model, data, 25)
    with pytest.raises(RuntimeError, match=r"advanced by 0\.05 s \(25 timesteps.*sim\.step\(render=False\).*"
                                           r"sim\.flush\(\).*sim\.advance\(n\)"):
        sim.step()
    assert sim.samples == 32  # (nothing counted for the refused call)


def test_data_that_is_not_stepped_any_more_is_refused():
    """step() twice on one mj_step, or on an MjData that an env replaced: no sound from dead data."""
    model, data, sim = make()
    mujoco.mj_step(model, data)
    sim.step()
    with pytest.raises(RuntimeError, match=r"has not advanced.*sim\.rebind\(model, data\)"):
        sim.step()
    other = mujoco.MjData(model)  # (the env steps a new MjData; the simulator still reads the old one)
    for _ in range(3):
        mujoco.mj_step(model, other)
        with pytest.raises(RuntimeError, match="has not advanced"):
            sim.step()


def test_a_reset_behind_its_back_sounds_as_an_explicit_reset():
    """mj_resetData between episodes (time goes back) keeps working: the simulator resets itself,
    the same audio bit for bit as calling reset() after mj_resetData."""
    out = []
    for explicit in (False, True):
        model, data, sim = make()
        blocks = []
        for episode in range(2):
            for _ in range(150):
                mujoco.mj_step(model, data)
                blocks.append(sim.step())
            mujoco.mj_resetData(model, data)
            data.qvel[0] = 0.3
            if explicit:
                sim.reset()
        out.append(np.concatenate(blocks, axis=1))
    assert out[0].shape == (1, 300 * 32) and np.abs(out[0]).max() > 0
    np.testing.assert_array_equal(out[0], out[1])


def test_rebind_follows_a_rebuilt_model_and_data():
    """A new MjModel / MjData of the same scene (robosuite's hard reset) in the middle of a run:
    the same audio, bit for bit, as a simulator that kept the first data, the sample count
    continuous, and run() steps the new data, not the old."""
    model, data, sim = make()
    ref_model, ref_data, ref = make()
    a, b = [], []
    for _ in range(100):
        for m, d, s, out in ((model, data, sim, a), (ref_model, ref_data, ref, b)):
            mujoco.mj_step(m, d)
            out.append(s.step())
    model2 = mujoco.MjModel.from_xml_string(SCENE)
    data2 = mujoco.MjData(model2)
    mujoco.mj_copyData(data2, model2, data)  # (the env's new data starts where the old one was)
    sim.rebind(model2, data2)
    assert sim.model is model2 and sim.data is data2
    for _ in range(200):
        mujoco.mj_step(model2, data2)
        a.append(sim.step())
        mujoco.mj_step(ref_model, ref_data)
        b.append(ref.step())
    np.testing.assert_array_equal(np.concatenate(a, axis=1), np.concatenate(b, axis=1))
    assert np.abs(np.concatenate(a[100:], axis=1)).max() > 0  # (the ball's bounces after the rebind)
    assert sim.samples == ref.samples == 300 * 32
    t_old, t_new = float(data.time), float(data2.time)
    block = sim.run(0.1)
    assert block.shape == (1, 1600) and data.time == t_old and data2.time == pytest.approx(t_new + 0.1)


def test_rebind_refuses_another_scene():
    model, data, sim = make()
    other = mujoco.MjModel.from_xml_string(SCENE.replace('<body name="box"', '<body name="box2" pos="1 0 .1">'
                                                         '<geom type="sphere" size=".01"/></body><body name="box"'))
    with pytest.raises(ValueError, match="rebind: the new model has ngeom=4.*build a new AudioSimulator"):
        sim.rebind(other)


def test_the_deprecated_stepping_calls_warn_and_sound_as_their_replacements():
    """substeps, stepper and replay_step warn (DeprecationWarning naming the replacement) and
    give the same audio as advance(n, render=False) + flush() and driver.replay."""
    out = []
    for old in (True, False):
        model, data, sim = make()
        blocks = []
        for i in range(40):
            if old and i % 2:
                with pytest.warns(DeprecationWarning, match=r"advance\(n, render=False\)"):
                    sim.substeps(5)
            elif old:
                with pytest.warns(DeprecationWarning, match=r"advance\(n, render=False\)"):
                    step = sim.stepper()
                step(5)
            else:
                sim.advance(5, render=False)
            blocks.append(sim.flush())
        t = float(data.time)
        mujoco.mj_forward(model, data)
        n = sim.clock.n
        if old:
            with pytest.warns(DeprecationWarning, match=r"sim\.driver\.replay"):
                blocks.append(sim.replay_step(n, n + 32, t, t + 0.002))
        else:
            blocks.append(sim.driver.replay(n, n + 32, t, t + 0.002))
        out.append(np.concatenate(blocks, axis=1))
    assert out[0].shape == (1, 40 * 5 * 32 + 32) and np.abs(out[0]).max() > 0
    np.testing.assert_array_equal(out[0], out[1])
