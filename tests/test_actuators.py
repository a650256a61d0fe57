"""Actuator noise (mjsound.sim.actuators): lines at the drive's kinematic frequencies, level
linear in torque, heard through the driven links only, off by default and bit for bit."""

import math

import mujoco
import numpy as np
import pytest

from mjsound.sim.actuators import PRESETS, ActuatorPreset, actuator_config
from mjsound.sim.simulator import AudioSimulator

FS = 16000  # (the lines checked lie under 1 kHz; fewer modes to analyse than at 48 kHz)
#: one clean tone: 10x the rotor rate, 100:1 reduction (the test reads the lines it makes)
ONE_TONE = ActuatorPreset(reduction=100.0, radius=0.01, tones=((10.0, 0.05),), broadband=0.0)


def arm_xml(damping=0.05, texts="", ball=False):
    """A box base fixed in space, an arm on a vertical hinge (velocity-servoed), a far box."""
    ball_xml = ('<body name="ball" pos="2 0 0.8"><freejoint/><geom name="ball" type="sphere" size=".03"/></body>'
                if ball else "")
    ball_text = '<text name="mjsound:ball" data="steel"/>' if ball else ""
    return f"""<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:base" data="steel"/><text name="mjsound:link" data="aluminium"/>
 <text name="mjsound:other" data="steel"/>{ball_text}{texts}</custom>
<worldbody>
 <body name="base" pos="0 0 0.5"><geom name="base" type="box" size=".1 .1 .05"/><site name="s_base" pos="0 0 .05"/>
  <body name="arm" pos="0 0 0.1"><joint name="j" type="hinge" axis="0 0 1" damping="{damping}"/>
   <geom name="link" type="box" size=".2 .02 .02" pos=".2 0 0"/><site name="s_link" pos=".3 0 .02"/></body></body>
 <body name="far" pos="2 0 0.5"><geom name="other" type="box" size=".1 .1 .05"/><site name="s_far" pos="0 0 .05"/></body>
 {ball_xml}
</worldbody>
<actuator><velocity name="m" joint="j" kv="5"/></actuator></mujoco>"""


def run(xml, ctrl, actuators=None, steps=1000):
    """Step the scene with ``ctrl(i)``; returns (audio (3, n): air, link contact, far contact;
    qvel per step; actuator force per step)."""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"], progress=False,
                         sample_rate=FS, quality="draft", actuators=actuators)
    out, qv, fa = [], [], []
    for i in range(steps):
        d.ctrl[0] = ctrl(i)
        mujoco.mj_step(m, d)
        out.append(sim.step())
        qv.append(d.qvel[0])
        fa.append(d.actuator_force[0])
    return np.concatenate(out, axis=1), np.array(qv), np.array(fa)


def test_lines_follow_the_joint_speed_within_one_bin():
    """A speed ramp (chirp): per 50 ms segment the contact microphone's strongest line near the
    expected one is at 10 x N x qdot / (2 pi) within one FFT bin, and it stands out."""
    audio, qv, _ = run(arm_xml(), lambda i: 1.0 + 1.0 * i / 1000, {"m": ONE_TONE})
    x = audio[1]
    L = FS // 20  # 50 ms: 20 Hz bins
    checked = 0
    for s in range(4, len(x) // L):  # (after the servo has caught up)
        seg = x[s * L:(s + 1) * L].astype(float)
        S = np.abs(np.fft.rfft(seg * np.hanning(L)))
        f = np.fft.rfftfreq(L, 1 / FS)
        speed = qv[s * 50:(s + 1) * 50].mean()  # (1 ms steps: 50 per segment)
        expect = 10.0 * 100.0 * speed / (2 * math.pi)
        band = np.abs(f - expect) < 200.0
        peak = f[band][np.argmax(S[band])]
        assert abs(peak - expect) <= FS / L, (s, peak, expect)
        assert S[band].max() > 10 * np.median(S[band]), s  # a line, not noise
        checked += 1
    assert checked >= 15


def test_level_follows_torque_6_db_per_doubling():
    """The same speed held against twice the damping: twice the torque, +6.02 dB."""
    rms, torque, speed = [], [], []
    for damping in (0.05, 0.1):
        audio, qv, fa = run(arm_xml(damping), lambda i: 2.0, {"m": ONE_TONE}, steps=600)
        rms.append(np.sqrt(np.mean(audio[1, -int(0.3 * FS):].astype(float) ** 2)))
        torque.append(abs(fa[-300:].mean()))
        speed.append(qv[-300:].mean())
    assert abs(speed[1] / speed[0] - 1) < 0.02  # (the same lines)
    expect = 20 * math.log10(torque[1] / torque[0])
    assert abs(expect - 6.02) < 0.3  # (the scene does double the torque)
    assert abs(20 * math.log10(rms[1] / rms[0]) - expect) < 0.3


def test_a_contact_mic_on_the_driven_link_hears_it_one_on_an_untouched_body_not():
    audio, _, _ = run(arm_xml(), lambda i: 2.0, "servo", steps=400)
    assert np.abs(audio[1]).max() > 1e-3  # the link's contact microphone
    assert np.abs(audio[0]).max() > 0  # the air microphone hears the links ring
    assert np.abs(audio[2]).max() == 0.0  # the far body: undriven, untouched


def test_a_joint_holding_still_is_silent():
    audio, _, _ = run(arm_xml(), lambda i: 0.0, "qdd", steps=300)
    assert np.abs(audio).max() == 0.0


def test_drives_follow_a_rebound_data():
    """After ``rebind`` to a new ``MjData`` whose joint is still, the drives read that data (the
    arguments kept between blocks are made again): the link falls silent once its last block
    has played, where the old data, no longer stepped, still turns at full speed."""
    m = mujoco.MjModel.from_xml_string(arm_xml())
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"], progress=False,
                         sample_rate=FS, quality="draft", actuators="servo")
    for _ in range(300):
        d.ctrl[0] = 2.0
        mujoco.mj_step(m, d)
        sim.step()
    assert abs(d.qvel[0]) > 1.0
    d2 = mujoco.MjData(m)
    d2.time = d.time
    sim.rebind(m, d2)
    out = []
    for _ in range(300):
        mujoco.mj_step(m, d2)
        out.append(sim.step())
    audio = np.concatenate(out, axis=1)
    before = np.abs(audio[1, : FS // 20]).max()  # (the lines of the old data's last speed, fading)
    assert before > 1e-3
    assert np.abs(audio[1, FS // 5:]).max() < 1e-6 * before  # (the drives of a still joint: nothing)


def test_an_env_steps_drives_end_where_its_speeds_are_read():
    """Stepped 50 at a time in one kernel call (an env's ``frame_skip``), the drives' block is
    rendered after the substeps from the state then: a joint that starts at 500 ms is heard
    from 500 ms as when every step is read on its own, not one call (50 ms) late."""
    onsets = []
    for every in (1, 50):
        m = mujoco.MjModel.from_xml_string(arm_xml())
        d = mujoco.MjData(m)
        sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"],
                             progress=False, sample_rate=FS, quality="draft", actuators="servo")
        out = []
        for i in range(0, 1000, every):
            d.ctrl[0] = 0.0 if i < 500 else 2.0
            if every == 1:
                mujoco.mj_step(m, d)
                out.append(sim.step())
            else:
                out.append(sim.advance(every))
        link = np.concatenate(out, axis=1)[1]
        onsets.append(np.argmax(np.abs(link) > 1e-3 * np.abs(link).max()) / FS)
    assert 0.500 <= onsets[0] < 0.502
    assert 0.500 <= onsets[1] < 0.503  # (a ramp from rest over the call's 50 ms: 1.3 ms to -60 dB)


@pytest.mark.parametrize("how", ["python-none", "python-dict-none", "mjcf-none"])
def test_none_changes_nothing_bit_for_bit(how):
    """With a ball striking the far box (so the scene sounds), ``none`` is the default's audio."""
    ref, _, _ = run(arm_xml(ball=True), lambda i: 2.0, None, steps=500)
    assert np.abs(ref).max() > 0
    if how == "python-none":
        got, _, _ = run(arm_xml(ball=True), lambda i: 2.0, "none", steps=500)
    elif how == "python-dict-none":
        got, _, _ = run(arm_xml(ball=True), lambda i: 2.0, {"m": "none"}, steps=500)
    else:
        got, _, _ = run(arm_xml(ball=True, texts='<text name="mjsound-actuator:m" data="none"/>'), lambda i: 2.0,
                        None, steps=500)
    assert np.array_equal(ref, got)


def test_mjcf_text_and_python_give_the_same_sound():
    a, _, _ = run(arm_xml(texts='<text name="mjsound-actuator:m" data="harmonic"/>'), lambda i: 2.0, None, steps=300)
    b, _, _ = run(arm_xml(), lambda i: 2.0, {"m": "harmonic"}, steps=300)
    assert np.abs(a[1]).max() > 0
    assert np.array_equal(a, b)


def test_configuration_errors_name_the_input():
    m = mujoco.MjModel.from_xml_string(arm_xml())
    with pytest.raises(ValueError, match="unknown actuator preset 'whine'"):
        actuator_config(m, "whine")
    with pytest.raises(ValueError, match="no actuator named 'hip'"):
        actuator_config(m, {"hip": "servo"})
    tendon = """<mujoco><worldbody><body><joint name="a" axis="0 0 1"/><geom size=".1"/></body></worldbody>
    <tendon><fixed name="t"><joint joint="a" coef="1"/></fixed></tendon>
    <actuator><motor name="tm" tendon="t"/></actuator></mujoco>"""
    with pytest.raises(ValueError, match="'tm' does not drive a hinge or slide joint"):
        actuator_config(mujoco.MjModel.from_xml_string(tendon), {"tm": "servo"})
    with pytest.warns(RuntimeWarning, match="none of this model's 1 actuators is a motor on a hinge or slide joint"):
        assert actuator_config(mujoco.MjModel.from_xml_string(tendon), "servo") == {}
    assert actuator_config(mujoco.MjModel.from_xml_string(tendon), "none") == {}
    assert actuator_config(m) == {}  # off unless a preset is named
    assert actuator_config(m, "qdd") == {0: PRESETS["qdd"]}


MIXED = """<mujoco><worldbody><body><joint name="a" axis="0 0 1"/><geom size=".1"/>
  <body pos=".3 0 0"><joint name="b" axis="0 0 1"/><geom size=".1"/></body></body></worldbody>
<custom>{texts}</custom>
<tendon><fixed name="t"><joint joint="a" coef="1"/></fixed></tendon>
<actuator><motor name="m" joint="a"/><motor name="tm" tendon="t"/><muscle name="mus" joint="b" lengthrange="-1 1"/>
 <motor name="mp" jointinparent="b"/></actuator></mujoco>"""


@pytest.mark.parametrize("how", ["python", "mjcf"])
def test_a_preset_for_every_motor_leaves_muscles_and_tendons_silent_unless_named(how):
    """A preset for all (``"servo"``, ``{"*": ...}``, MJCF ``mjsound-actuator:*``) reaches the
    motors on hinge and slide joints only (``joint`` or ``jointinparent``): the tendon's
    actuator and the muscle stay silent without an error; the muscle named sounds as asked."""
    texts = '<text name="mjsound-actuator:*" data="servo"/>' if how == "mjcf" else ""
    m = mujoco.MjModel.from_xml_string(MIXED.format(texts=texts))
    every = None if how == "mjcf" else "servo"
    assert actuator_config(m, every) == {0: PRESETS["servo"], 3: PRESETS["servo"]}
    assert actuator_config(m, {"*": "servo"}) == {0: PRESETS["servo"], 3: PRESETS["servo"]}
    assert actuator_config(m, {"*": "qdd", "mus": "harmonic"}) == {0: PRESETS["qdd"], 2: PRESETS["harmonic"],
                                                                   3: PRESETS["qdd"]}
    with pytest.raises(ValueError, match="'tm' does not drive a hinge or slide joint"):
        actuator_config(m, {"tm": "qdd"})


def test_a_joint_in_parent_drive_sounds_as_its_joint():
    """``jointinparent`` on a hinge is the same transmission as ``joint``: the same sound, bit for bit."""
    a, _, _ = run(arm_xml(), lambda i: 2.0, "servo", steps=300)
    b, _, _ = run(arm_xml().replace('<velocity name="m" joint="j"', '<velocity name="m" jointinparent="j"'),
                  lambda i: 2.0, "servo", steps=300)
    assert np.abs(a[1]).max() > 0
    assert np.array_equal(a, b)


def test_drives_without_a_sounding_body_are_named_even_unnamed():
    """An unnamed actuator whose bodies have no sounding geom is named by its index in the warning."""
    xml = """<mujoco><worldbody><body pos="0 0 1"><joint axis="0 0 1"/>
      <geom size=".1" contype="0" conaffinity="0"/></body></worldbody>
    <actuator><motor joint="0"/></actuator></mujoco>"""
    xml = xml.replace('joint="0"', 'joint="j"').replace("<joint axis", '<joint name="j" axis')
    m = mujoco.MjModel.from_xml_string(xml)
    with pytest.warns(RuntimeWarning, match=r"actuators \['#0'\] drive no sounding geom"):
        AudioSimulator(m, mujoco.MjData(m), progress=False, sample_rate=FS, quality="draft", actuators="servo")


def test_the_parent_of_a_driven_joint_hears_its_reaction_and_a_link_sums_its_drives():
    """A chain base -> upper (hinge j1) -> fore (hinge j2), fixed base: driving j2 alone, the
    upper link (j2's parent) hears the reaction and the base (parent of the undriven j1) hears
    nothing; driving both (other speeds: other lines), the upper link's one stream carries both
    drives: louder than j1's alone."""
    xml = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:base" data="steel"/><text name="mjsound:upper" data="aluminium"/>
 <text name="mjsound:fore" data="aluminium"/></custom>
<worldbody>
 <body name="base" pos="0 0 0.5"><geom name="base" type="box" size=".1 .1 .05"/><site name="s_base" pos="0 0 .05"/>
  <body name="upper" pos="0 0 0.1"><joint name="j1" type="hinge" axis="0 0 1" damping="0.05"/>
   <geom name="upper" type="box" size=".2 .02 .02" pos=".2 0 0"/><site name="s_upper" pos=".2 0 .02"/>
   <body name="fore" pos=".4 0 0.05"><joint name="j2" type="hinge" axis="0 0 1" damping="0.05"/>
    <geom name="fore" type="box" size=".15 .015 .015" pos=".15 0 0"/></body></body></body>
</worldbody>
<actuator><velocity name="m1" joint="j1" kv="5"/><velocity name="m2" joint="j2" kv="5"/></actuator></mujoco>"""

    def hear(actuators, ctrl, bodies):
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_upper", "s_base"],
                             progress=False, sample_rate=FS, quality="draft", actuators=actuators)
        out = []
        for _ in range(400):
            d.ctrl[:] = ctrl
            mujoco.mj_step(m, d)
            out.append(sim.step())
        assert sim.actuators.bodies.tolist() == [m.body(b).id for b in bodies]  # (one stream per driven body)
        return np.concatenate(out, axis=1)[:, -int(0.2 * FS):].astype(float)

    only2 = hear({"m2": ONE_TONE}, [0.0, 2.0], ["upper", "fore"])
    assert np.abs(only2[1]).max() > 1e-4  # upper: j2's reaction
    assert np.abs(only2[2]).max() == 0.0  # base: j1 not driven
    both = hear({"m1": ONE_TONE, "m2": ONE_TONE}, [2.0, 3.0], ["base", "upper", "fore"])
    assert np.abs(both[2]).max() > 0  # base: j1's reaction now
    only1 = hear({"m1": ONE_TONE}, [2.0, 0.0], ["base", "upper"])
    rms = [np.sqrt(np.mean(x[1] ** 2)) for x in (only1, both)]
    assert rms[1] > 1.2 * rms[0]
