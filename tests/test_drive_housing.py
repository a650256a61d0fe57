"""The motor housing's direct airborne part (mjsound.synth.drive_housing): a monopole at the
joint's anchor whose pressure is the drive's force times ``housing / r``, delayed ``r / c``;
air and image microphones (times the reflection), not contact ones."""

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from mjsound.sim.actuators import (HOUSING_POINTS, PRESETS, ActuatorPreset, a_weighting_db, housing_coefficient,
                                   housing_level_dba)
from mjsound.sim.simulator import AudioSimulator
from mjsound.synth.accel_noise import SPEED_OF_SOUND
from test_actuators import FS, arm_xml

ANCHOR = np.array([0.0, 0.0, 0.6])  # (the arm's hinge in arm_xml: base at 0.5, arm 0.1 above it)
#: two air microphones straight above the anchor, 0.5 m and 1 m from it (clear of the link's sweep)
MICS = [ANCHOR + [0.0, 0.0, 0.5], ANCHOR + [0.0, 0.0, 1.0]]
K = 0.01  # [Pa m / N]
ONE_TONE = ActuatorPreset(reduction=100.0, radius=0.01, tones=((10.0, 0.05),), broadband=0.0, housing=K)
STEPS = 1000


def render(preset, ctrl=2.0, damping=0.05):
    """The arm at a steady speed; (audio (4, n) float64: the two air microphones, the link's
    and the far body's contact microphones; joint speed [rad/s] and actuator force [N m] over
    the last 0.5 s)."""
    m = mujoco.MjModel.from_xml_string(arm_xml(damping))
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=MICS, contact_mics=["s_link", "s_far"], progress=False, sample_rate=FS,
                         quality="draft", actuators={"m": preset})
    out, qv, fa = [], [], []
    for _ in range(STEPS):
        d.ctrl[0] = ctrl
        mujoco.mj_step(m, d)
        out.append(sim.step())
        qv.append(d.qvel[0])
        fa.append(d.actuator_force[0])
    assert np.allclose(d.xanchor[0], ANCHOR)
    return np.concatenate(out, axis=1).astype(np.float64), float(np.mean(qv[-500:])), float(np.mean(fa[-500:]))


def projection(x, f):
    """Complex amplitude of the tone ``f`` [Hz] in ``x``'s last 0.5 s: ``2 / n sum x e^{-j 2 pi f t}``."""
    n = FS // 2
    t = np.arange(n) / FS
    return 2.0 / n * np.sum(x[-n:] * np.exp(-2j * math.pi * f * t))


def test_the_housing_tone_is_a_monopole_at_the_anchor():
    """One tone, the housing on against off (the links' part cancels): at each microphone the
    tone's amplitude is ``K a A / r`` within 1 % (``a = |force| / radius``; measured within
    0.1 %), and between the two the ratio is ``r1 / r2 e^{-j w (r2 - r1) / c}`` (1 / r and the
    delay: phase within 0.02 rad)."""
    on, qd, force = render(ONE_TONE)
    off, _, _ = render(replace(ONE_TONE, housing=0.0))
    f = 10.0 * 100.0 * qd / (2 * math.pi)
    a = abs(force) / 0.01
    P = [projection(on[i] - off[i], f) for i in range(2)]
    for i, r in enumerate((0.5, 1.0)):
        assert abs(abs(P[i]) / (K * a * 0.05 / r) - 1.0) < 0.01, (r, abs(P[i]), K * a * 0.05 / r)
    ratio = P[1] / P[0]
    assert abs(abs(ratio) - 0.5) < 0.005
    c = SPEED_OF_SOUND  # (the synthesizer's)
    expect = -2 * math.pi * f * 0.5 / c
    assert abs(np.angle(ratio * np.exp(-1j * expect))) < 0.02, (np.angle(ratio), expect)


def test_contact_microphones_do_not_hear_the_housing():
    """The contact microphones' channels are the same bit for bit with the housing on or off
    (and the air ones are not)."""
    on, _, _ = render(ONE_TONE)
    off, _, _ = render(replace(ONE_TONE, housing=0.0))
    assert np.array_equal(on[2:], off[2:])
    assert np.abs(on[1]).max() > 0 and not np.array_equal(on[:2], off[:2])


def test_the_servo_housing_level_at_its_operating_point():
    """The ``servo`` preset (tones only) near its calibration point (0.1 N m at 5 rad/s, 45
    dB(A) at 1 m): the housing part's A-weighted level at the microphone 1 m away is the
    model's (:func:`housing_level_dba` at the measured torque and speed, its lines under 0.45
    fs) within 0.2 dB, and within 1 dB of 45 dB(A)."""
    servo = replace(PRESETS["servo"], broadband=0.0)
    torque, speed, level = HOUSING_POINTS["servo"]
    damping = torque / speed  # (the velocity servo holds speed against the joint's damping)
    ctrl = speed * (1.0 + damping / 5.0)  # (kv = 5: force = kv (ctrl - qdot) = damping qdot)
    on, qd, force = render(servo, ctrl, damping)
    off, _, _ = render(replace(servo, housing=0.0), ctrl, damping)
    x = (on[1] - off[1])[-FS // 2:]
    X = np.fft.rfft(x * np.hanning(len(x)))
    fr = np.fft.rfftfreq(len(x), 1.0 / FS)
    wA = 10.0 ** (a_weighting_db(np.maximum(fr, 1.0)) / 20.0)
    # (Parseval through the window: mean power = 2 sum |X|^2 / (n sum w^2), one-sided bins, A-weighted per bin)
    power = 2.0 * np.sum(np.abs(X * wA) ** 2) / (len(x) * np.sum(np.hanning(len(x)) ** 2))
    measured = 10.0 * math.log10(power / (20e-6) ** 2)
    audible = replace(servo, tones=tuple((o, A) for o, A in servo.tones if o * servo.reduction * qd / (2 * math.pi)
                                         < 0.45 * FS))
    model = housing_level_dba(audible, force, qd)
    assert abs(measured - model) < 0.2, (measured, model)
    assert abs(measured - level) < 1.0, (measured, level)


def test_housing_coefficients_and_bad_input():
    """Each motor preset's coefficient gives its stated level at its operating point (the
    closed form, :func:`housing_level_dba`), the level rises 6.02 dB per doubling of torque,
    ``none`` and a custom preset have none, and a negative coefficient is an error."""
    for name, (torque, speed, level) in HOUSING_POINTS.items():
        p = PRESETS[name]
        assert p.housing > 0
        assert abs(housing_level_dba(p, torque, speed) - level) < 1e-9
        assert abs(housing_level_dba(p, 2 * torque, speed) - level - 20 * math.log10(2)) < 1e-9
        assert housing_coefficient(replace(p, housing=0.0), torque, speed, level) == pytest.approx(p.housing)
    assert PRESETS["none"] is None
    assert ActuatorPreset(10.0, 0.01).housing == 0.0
    with pytest.raises(ValueError, match="housing"):
        ActuatorPreset(10.0, 0.01, housing=-1.0)
    assert abs(float(a_weighting_db(1000.0))) < 0.01 and abs(float(a_weighting_db(100.0)) + 19.1) < 0.05


def test_housing_weights_match_the_plain_formula():
    """The kernel against the plain float64 formula, ``W_cm += K A_c R_m(f_c) e^{-j t_c (r fs /
    c - D_m)} / r``, ``t_c = o_c w / fs``, ``f_c = |t_c| fs / 2 pi``, ``B_jm += K R_m(f_n /
    sqrt 2) / r`` (``R_m`` an image microphone's reflection, log-linear between its points,
    constant outside; 1 at a plain one; ``f_n`` the noise's corner), on a made-up state:
    gear-mesh harmonics (2x, 3x of earlier orders, made as powers of their base's phasor), an
    order of no base, one above 0.45 fs (left out), a silent housing, an image, a contact and a
    too-near microphone, delays longer than a sample beyond the microphone's: within 1e-13 of
    each term."""
    from collections import namedtuple

    from mjsound.synth.drive_housing import housing_weights
    from mjsound.synth.drive_lines import Actuators, LineWeights
    from mjsound.synth.drive_tones import DRIVE, NOISE, TONE
    from mjsound.synth.records import AIR, CHANNEL, SYNTH_CONSTS

    fs, c, rmin = 16000.0, 343.0, 0.05
    orders = [[10.0, 20.0, 30.0, 126.0, 252.0], [7.0, 10.5, 21.0, 14.0], [3.0, 6.0], [5.0, 900.0, 1800.0]]
    comp_off = np.cumsum([0] + [len(o) for o in orders])
    tones = np.zeros(comp_off[-1], TONE)
    tones["order"] = np.concatenate(orders)
    tones["amp"] = np.linspace(0.01, 0.05, len(tones))
    J = len(orders)
    drives = np.zeros(J, DRIVE)
    drives["joint"] = [0, 1, 2, 3]
    housing = np.array([0.01, 0.02, 0.0, 0.015])
    w1 = np.array([120.0, -80.0, 50.0, 30.0])  # (rotor rad/s: order 1800 at 30 rad/s is above 0.45 fs)
    anchor = np.array([[0.0, 0.0, 0.5], [0.3, 0.1, 0.4], [0.0, 0.2, 0.3], [1.0, 1.0, 1.02]])
    mics = np.array([[0.0, 0.0, 1.5], [1.0, 1.0, 1.0], [2.0, -1.0, 1.0], [0.5, 0.5, 0.5]])
    channels = np.zeros(4, CHANNEL)
    channels["owner"] = [AIR, AIR, AIR, 3]  # (an air, an air, an image, a contact microphone)
    channels["w_off"] = [-1, -1, 0, 0]
    consts = np.zeros(1, SYNTH_CONSTS)
    consts[0]["c"], consts[0]["fs"], consts[0]["rmin"] = c, fs, rmin
    KS = namedtuple("KS", "consts mics channels")
    z = np.zeros
    act = Actuators(comp_off, tones, z(J, NOISE), drives, z(1, np.int64), z(0, np.int64), z(0, np.int64), z(0),
                    z(J, np.bool_), z(J), w1, z(J), z(J), housing)
    M = len(mics)
    Dm = np.array([1, 3, 7, 0])
    band_f, band_g = np.array([125.0, 500.0, 2000.0]), np.array([0.9, 0.6, 0.3])
    response = np.zeros((M, 2, 3))
    response[:, 0] = np.inf  # (rows 0, 1, 3: no points)
    response[2] = np.log(band_f), band_g
    lw = LineWeights(z((len(tones), M), complex), z((len(tones), M), complex) + 0.5j, z((J, M)), z((J, M)) + 0.25,
                     Dm, z(J, np.bool_), z((J, 2)), response=response)
    housing_weights(KS(consts, mics, channels), act, lw, anchor, fs)
    W, B = 0.5j + np.zeros((len(tones), M), complex), 0.25 + np.zeros((J, M))

    def R(m, f):  # (the image's reflection; 1 elsewhere)
        return float(np.interp(np.log(f), np.log(band_f), band_g)) if m == 2 else 1.0

    for j in range(J):
        for m in range(3):  # (the air microphones and the image; not the contact one)
            if housing[j] == 0.0:
                continue
            r = max(np.linalg.norm(mics[m] - anchor[j]), rmin)
            fn = min(abs(w1[j]) * tones["order"][comp_off[j]] / (2 * np.pi), 0.45 * fs)
            B[j, m] += housing[j] / r * R(m, fn / np.sqrt(2))
            for q in range(comp_off[j], comp_off[j + 1]):
                t = tones["order"][q] * w1[j] / fs
                if abs(t) < 2 * np.pi * 0.45:
                    W[q, m] += housing[j] / r * R(m, abs(t) * fs / (2 * np.pi)) * tones["amp"][q] * np.exp(
                        -1j * t * (r * fs / c - Dm[m]))
    assert np.abs(lw.W1 - W).max() < 1e-13 * np.abs(W - 0.5j).max()
    assert np.array_equal(lw.W1[:, 3:], W[:, 3:]) and np.array_equal(lw.B1[:, 3:], B[:, 3:])
    assert np.abs(lw.B1 - B).max() < 1e-15
    assert np.count_nonzero(lw.W1[:, :3] - 0.5j) == 3 * (len(tones) - 1 - 2)  # (one above 0.45 fs, a silent pair)
    # (the image's factors span the table's inside and both ends)
    fq = np.abs(tones["order"] * np.repeat(w1, np.diff(comp_off))) / (2 * np.pi)
    assert fq.min() < band_f[0] and fq[fq < 0.45 * fs].max() > band_f[-1]


def test_reflection_at_reads_the_channel_response():
    """``reflection_at`` (its table in log frequencies) against the synthesizer's own
    ``response_at`` (log-linear, constant outside), padding ``inf`` ignored, and 1 without
    points."""
    from mjsound.synth.drive_housing import reflection_at
    from mjsound.synth.synthesizer import Synthesizer

    f, g = np.array([125.0, 250.0, 1000.0, 4000.0]), np.array([0.99, 0.8, 0.5, 0.45])
    resp = np.full((2, 6), np.inf)
    resp[:, :4] = np.log(f), g
    for x in (10.0, 125.0, 180.0, 250.0, 700.0, 3999.0, 4000.0, 9000.0):
        assert abs(reflection_at(resp, x) - float(Synthesizer.response_at(f, g, x))) < 1e-14, x
    assert reflection_at(np.full((2, 3), np.inf), 300.0) == 1.0


def test_the_floor_reflects_the_housing():
    """Above a floor, the housing's tone at the microphone's output (on minus off: the links'
    part cancels) is the direct monopole plus its image, ``K a A (e^{-jk r1} / r1 + R(f)
    e^{-jk r2} / r2)``, ``r2`` the distance to the microphone's mirror image and ``R`` the
    floor's reflection at the tone's frequency: within 1 % in magnitude."""
    xml = arm_xml().replace("<worldbody>", '<worldbody><geom name="floor" type="plane" size="5 5 .1"/>')

    def run(preset):
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        sim = AudioSimulator(m, d, microphones=MICS[:1], progress=False, sample_rate=FS, quality="draft",
                             actuators={"m": preset})
        out, qv, fa = [], [], []
        for _ in range(STEPS):
            d.ctrl[0] = 2.0
            mujoco.mj_step(m, d)
            out.append(sim.step())
            qv.append(d.qvel[0])
            fa.append(d.actuator_force[0])
        return sim, np.concatenate(out, axis=1).astype(np.float64)[0], float(np.mean(qv[-500:])), float(
            np.mean(fa[-500:]))

    sim, on, qd, force = run(ONE_TONE)
    _, off, _, _ = run(replace(ONE_TONE, housing=0.0))
    assert sim.synth.n_channels == 2  # (the microphone and its floor image)
    f = 10.0 * 100.0 * qd / (2 * math.pi)
    a = abs(force) / 0.01
    Rf = float(sim.synth.response_at(*sim.synth.channel_response(1), f))
    assert 0.0 < Rf < 1.0
    r1, r2 = 0.5, 1.1 + 0.6  # (the microphone 1.1 m above the floor, the anchor 0.6 m)
    k = 2 * math.pi * f / SPEED_OF_SOUND
    expect = K * a * 0.05 * abs(1.0 / r1 + Rf * np.exp(-1j * k * (r2 - r1)) / r2)
    got = abs(projection(on - off, f))
    assert abs(got / expect - 1.0) < 0.01, (got, expect)
    # (without the image the level would be K a A / r1: the two differ by more than the bound)
    assert abs(K * a * 0.05 / r1 / expect - 1.0) > 0.05
