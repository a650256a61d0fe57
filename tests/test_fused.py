"""Substeps in one numba call (mjsound.sim.fused): the mjData layout it reads, and the same
sound, events and state as the per-substep Python path, bit for bit."""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np
import pytest

from mjsound.sim import fused
from mjsound.sim.scene import SoundScene
from mjsound.sim.simulator import AudioSimulator
from mjsound.sim.stub import stub_model

FS = 16000

# a ball that bounces then rolls, and a box pushed along the floor: impacts, rolling, sliding
SCENE = """
<mujoco>
  <option timestep="0.002"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:box" data="oak"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1" solref="-1e5 -120"/>
    <site name="mic0" pos="0.3 -0.5 0.3"/>
    <body name="ball" pos="0 0 0.2"><freejoint/><geom name="ball" type="sphere" size="0.02" solref="-1e5 -120"/></body>
    <body name="box" pos="0.5 0 0.03"><freejoint/><geom name="box" type="box" size="0.04 0.03 0.03"/></body>
  </worldbody>
</mujoco>"""

MODELS = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0), "box": stub_model("box:0.08,0.06,0.06", "oak", 6, 700.0)}


def make(fused_on, keep_events=0, **kw):
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    data.qvel[0] = 0.4  # the ball rolls after its bounces
    scene = SoundScene.from_model(model, models=MODELS, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, fused=fused_on, keep_events=keep_events, **kw)
    return model, data, sim


def play(model, data, sim, n_env=150, frame_skip=5, jump_at=None, render=False):
    """``driver.substeps(frame_skip, keep=render)`` + ``flush()`` per env step; the box is pushed for a
    while."""
    blocks = []
    for i in range(n_env):
        data.xfrc_applied[2, 0] = 3.0 if 30 <= i < 90 else 0.0
        if i == jump_at:
            data.time += 0.37  # a state jump: the simulator refuses (the skipped steps' contacts were not read)
        sim.driver.substeps(frame_skip, False, render)
        blocks.append(sim.flush())
    return np.concatenate(blocks, axis=1)


def test_mjdata_layout_reads_what_the_bindings_read():
    L = fused.mjdata_layout()
    assert L is not None, "the mjData layout from mujoco.introspect disagrees with the bindings"
    model, data, _ = make(True)
    seen = 0
    for _ in range(400):
        mujoco.mj_step(model, data)
        raw = np.frombuffer(ctypes.string_at(data._address, int(L[fused.L_EFC_FORCE]) + 8), np.uint8)
        assert raw[L[fused.L_NCON]: L[fused.L_NCON] + 4].view(np.int32)[0] == data.ncon
        assert raw[L[fused.L_NEFC]: L[fused.L_NEFC] + 4].view(np.int32)[0] == data.nefc
        assert raw[L[fused.L_TIME]: L[fused.L_TIME] + 8].view(np.float64)[0] == data.time
        if data.ncon:
            seen += 1
            base = raw[L[fused.L_CONTACT]: L[fused.L_CONTACT] + 8].view(np.uint64)[0]
            assert base == data.contact.dist.__array_interface__["data"][0]
            geom = np.frombuffer(ctypes.string_at(int(base) + int(L[fused.L_CGEOM]), 8), np.int32)
            np.testing.assert_array_equal(geom, data.contact.geom[0])
    assert seen > 100


@pytest.mark.parametrize("variant", ["plain", "event_log", "short_log", "follow", "tiny_buffers"])
def test_fused_substeps_equal_the_python_loop_bit_for_bit(variant, monkeypatch):
    """Audio, events, impact records and the reader's state: identical whether the step kernel
    calls mj_step and reads the mjData struct itself (fused) or Python steps through the
    bindings, copies the contacts in and solves M^-1 J^T (not fused), whatever the kernel hands
    back. Variants: with an event log, with a log that fills up after 40 events, with a
    listener following the box (microphones move at each impact), with buffers too small for
    the impact records and the event queue (the kernel asks Python to grow them)."""
    from mjsound.sim import step as S
    from mjsound.sim.records import RECORD
    from mjsound.synth.bandlimited import PULSE_DTYPE
    from mjsound.sim.driver import StepDriver

    keep_events = {"event_log": 100_000, "short_log": 40}.get(variant, 0)
    reasons = {}
    orig_hand_back, orig_substeps = StepDriver._hand_back, StepDriver.substeps

    def counting_hand_back(self, reason):  # (every hand-back of the step kernel counted by its reason)
        reasons[self.fused, reason] = reasons.get((self.fused, reason), 0) + 1
        return orig_hand_back(self, reason)

    def counting_substeps(self, nstep, render=True, keep=False, stepped=False, times=None):
        if not stepped and self.fused:  # (the kernel calls mj_step itself)
            reasons["stepped", self.fused] = True
        return orig_substeps(self, nstep, render, keep, stepped, times)

    monkeypatch.setattr(StepDriver, "_hand_back", counting_hand_back)
    monkeypatch.setattr(StepDriver, "substeps", counting_substeps)
    runs = []
    for on in (False, True):
        model, data, sim = make(on, keep_events)
        assert sim.driver.fused == on
        if variant == "follow":
            sim.follow(2, [[0.0, -0.4, 0.2]])
        if variant == "tiny_buffers":
            sim.reader.buffers = sim.reader.buffers._replace(records=np.zeros(1, RECORD))
            sim.synth._ev._alloc(1, 1)
            sim.pulses._state = sim.pulses._state._replace(rows=np.zeros(0, PULSE_DTYPE), dv=np.zeros(0))
            track = sim.pulses.track  # (a one-sample ring and scratch: the kernel hands the pulses back to grow them)
            track.state = track.state._replace(acc=np.zeros((track.n_channels, 1)), work=np.zeros(1, np.complex128),
                                               out=np.zeros(1), table=np.zeros(1, np.complex128))
        audio = play(model, data, sim)
        recs = [(r.time, r.geom1, r.geom2, r.impulse_pred, r.impulse_sim, r.steps, r.duration, r.open)
                for r in sim.impacts]
        runs.append((audio, sim.events, recs, sim.event_log, sim.steps, sim.samples, sim.reader.step_count,
                     sim.clock.k))
    (a0, ev0, rec0, log0, *state0), (a1, ev1, rec1, log1, *state1) = runs
    assert reasons.get(("stepped", True)) and not reasons.get(("stepped", False))  # the fused path did run
    assert ev0["impact"] >= 3 and ev0["slide"] > 50 and ev0["roll"] > 50, ev0
    assert np.abs(a0).max() > 0
    np.testing.assert_array_equal(a0, a1)
    assert ev0 == ev1 and rec0 == rec1 and log0 == log1 and state0 == state1
    assert (len(log0) > 0) == (keep_events > 0)
    if variant == "short_log":
        assert len(log0) == 40
    for fused_on in (False, True):  # streams are made in Python, on demand
        assert reasons.get((fused_on, S.STREAMS), 0) > 0
    assert reasons.get((False, S.SOLVE), 0) > 0 and not reasons.get((True, S.SOLVE))
    if variant == "tiny_buffers":  # (the event log's buffer also starts empty and grows once)
        assert reasons.get((True, S.ROOM), 0) > 1
        assert reasons.get((True, S.PULSES), 0) > 0  # (no room for the impacts' pulses: Python grows it)
        grown = sim.pulses.track.state
        assert grown.work.shape[0] >= 64 and grown.acc.shape[1] >= 64  # (Python grew the track for the kernel)
    if variant == "follow":
        assert not np.allclose(sim.synth.microphones, [[0.5, -0.4, 0.23]])  # moved with the box


def test_fused_substeps_refuse_a_time_jump_like_the_python_loop():
    """data.time moved forward behind the simulator's back: both paths refuse, naming the
    calls to use, after counting the same steps."""
    out = []
    for on in (False, True):
        model, data, sim = make(on)
        with pytest.raises(RuntimeError, match=r"advanced by 0\.37.*sim\.advance\(n\).*sim\.reset\(\)"):
            play(model, data, sim, n_env=60, jump_at=20)
        out.append((sim.samples, sim.steps, sim.flush()))
    assert out[0][:2] == out[1][:2] == (20 * 5 * FS // 500, 20 * 5)
    np.testing.assert_array_equal(out[0][2], out[1][2])


@pytest.mark.parametrize("jump", [None, "backward"])
def test_render_in_the_step_call_sounds_as_rendering_in_flush(jump):
    """``driver.substeps(n, keep=True)`` renders the pending samples in the step kernel's call
    (``flush`` returns that block) and mixes the impacts' clicks into it: the same blocks, bit
    for bit, as rendering and mixing in ``flush``, the same ones handed to an observer, also
    around a clock jump backwards (an automatic reset) and with steps taken one by one before it."""
    from mjsound.sim.records import NOT_RENDERED

    out = []
    for render in (False, True):
        model, data, sim = make(True)
        seen = []
        sim.on_block = lambda s, block, n0, seen=seen: seen.append((n0, block.copy()))
        codes, mixed = [], []
        blocks = []
        for i in range(120):
            data.xfrc_applied[2, 0] = 3.0 if 30 <= i < 90 else 0.0
            if i == 20 and jump is not None:
                data.time -= 0.05
            if i % 7 == 3:  # a step taken by hand first: its samples are pending too
                mujoco.mj_step(model, data)
                sim.step(render=False)
            sim.driver.substeps(5, False, render)
            codes.append(int(sim.driver.f["render_code"][0]))
            mixed.append(int(sim.driver.f["pulses_mixed"][0]))
            blocks.append(sim.flush())
        out.append((blocks, seen, sim.samples, sim.clock.n))
        if render:  # (every call rendered, but the one that met the jump)
            assert codes.count(NOT_RENDERED) == (0 if jump is None else 1)
            # (and mixed the clicks of the bounces into its block itself; Python mixed them into the others)
            assert mixed == [int(c != NOT_RENDERED) for c in codes] and sim.pulses.track.dropped == 0
    (b0, seen0, *n0), (b1, seen1, *n1) = out
    assert n0 == n1 and len(b0) == len(b1) and len(seen0) == len(seen1)
    assert np.abs(np.concatenate(b0, axis=1)).max() > 0
    for x, y in zip(b0, b1):
        np.testing.assert_array_equal(x, y)
    for (m0, x), (m1, y) in zip(seen0, seen1):
        assert m0 == m1
        np.testing.assert_array_equal(x, y)


def test_fused_path_can_be_switched_off(monkeypatch):
    monkeypatch.setenv("MJSOUND_FUSED", "0")
    assert make(True)[2].driver.fused is False


def test_struct_layout_follows_c_alignment():
    off, size, align = fused.struct_layout("mjContact")
    assert off["dist"] == 0 and off["pos"] == 8 and align == 8 and size % 8 == 0
    c = mujoco.MjContact()
    addr = lambda a: a.__array_interface__["data"][0]
    assert addr(c.geom) - addr(c.pos) == off["geom"] - off["pos"]
    assert addr(c.frame) - addr(c.pos) == off["frame"] - off["pos"]


def test_streams_rendered_in_one_call_sound_as_stage_by_stage():
    """Synthesizer.fused_streams (gains, stream rows and the render in one numba call) against
    one call per stage: the same sound to float32 rounding (the modal state is float32)."""
    out = []
    for fused_streams in (False, True):
        model, data, sim = make(True)
        sim.synth.fused_streams = fused_streams
        out.append(play(model, data, sim))
    peak = np.abs(out[0]).max()
    assert peak > 0
    np.testing.assert_allclose(out[1], out[0], rtol=0, atol=1e-5 * peak)


def test_a_mujoco_build_without_the_c_functions_falls_back_to_python(monkeypatch):
    """If libmujoco or a signature does not check out, the simulator warns once and steps
    every substep in Python (the sound is unchanged)."""
    def missing(name):
        raise OSError("no libmujoco next to the bindings")

    monkeypatch.setattr(fused, "mj_function_address", missing)
    with pytest.warns(RuntimeWarning, match="substeps run through Python"):
        model, data, sim = make(True)
    assert sim.driver.fused is False
    ref_model, ref_data, ref = make(False)
    np.testing.assert_array_equal(play(model, data, sim, n_env=40), play(ref_model, ref_data, ref, n_env=40))


@pytest.mark.parametrize("fused_streams,render,bad", [(True, False, np.nan), (False, False, np.nan), (True, True, np.nan),
                                                       (True, True, np.inf)])
def test_render_zeroes_non_finite_samples(fused_streams, render, bad):
    """A modal state gone non-finite (what an exploding simulation could leave) never reaches
    the output: those samples are 0, the others are rendered as usual (also when the step
    kernel renders: ``driver.substeps(keep=True)``)."""
    model, data, sim = make(True, clicks=False)  # (the modes' state only: no clicks of the bounces)
    sim.synth.fused_streams = fused_streams
    play(model, data, sim, n_env=40)  # something rolls: streams exist
    assert sim.synth.n_streams > 0
    sim.synth._bank.zr[:] = bad  # (the modal state, as an exploding simulation could leave it)
    sim.driver.substeps(5, False, render)
    block = sim.flush()
    assert block.size and np.isfinite(block).all() and not block.any()
