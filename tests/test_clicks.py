"""Acceleration noise in a MuJoCo scene: a block dropped on a floor without a material clicks
at the level of the rigid-sphere closed form; its contact microphone feels the rigid-body pulse;
contact microphone sites by prefix or by name."""

import math

import mujoco
import numpy as np
import pytest
from scipy.special import spherical_jn, spherical_yn

from mjsound.materials import get_material
from mjsound.sim import AudioSimulator
from mjsound.sim.channels import contact_mic_sites
from mjsound.synth import accel_noise as an
from mjsound.synth.bandlimited import PASS_FRACTION
from mjsound.synth.pulse import contact_time, hertz_coefficient

FS = 16000
XML = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:block" data="abs"/></custom>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <site name="mic0" pos="0.3 -0.3 0.4"/>
  <body name="block" pos="0 0 0.125"><freejoint/>
    <geom name="block" type="box" size="0.025 0.025 0.025" density="1050"/>
    <site name="contact_mic_block" pos="0 0 0.025"/>
  </body>
  <body name="plate" pos="0.6 0 0.01"><freejoint/>
    <geom name="plate" type="box" size="0.1 0.1 0.01" density="2700"/>
    <site name="contact_mic_plate" pos="0 0 0.01"/>
  </body>
</worldbody></mujoco>"""


def _run(clicks):
    """Drop the 5 cm ABS block (131 g) 10 cm onto a floor without a material (0.3 s)."""
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, sample_rate=FS, quality="draft", progress=False, clicks=clicks)
    return sim, sim.run(0.3)


def _hankel_click(dv, tau, a, r, cos_t, t):
    """Rigid sphere of radius ``a`` stopped by ``dv`` in a half-sine of ``tau``, band-limited like
    the output: p = -j rho c U cos(theta) h1(kr) / h1'(ka) (Morse & Ingard sec. 7.2)."""
    w = np.linspace(1e-3, math.pi * FS, 20000)
    k = w / an.SPEED_OF_SOUND
    acc = dv * (math.pi / tau) ** 2 * (1 + np.exp(-1j * w * tau)) / (2 * ((math.pi / tau) ** 2 - w * w))
    h = spherical_jn(1, k * r) - 1j * spherical_yn(1, k * r)
    hd = spherical_jn(1, k * a, derivative=True) - 1j * spherical_yn(1, k * a, derivative=True)
    p = -1j * an.RHO_AIR * an.SPEED_OF_SOUND * acc / (1j * w) * cos_t * h / hd
    g = np.clip((w / (2 * math.pi * FS) - PASS_FRACTION) / (0.5 - PASS_FRACTION), 0, 1)
    p = p * 0.5 * (1 + np.cos(math.pi * g))
    return np.trapezoid((p[None, :] * np.exp(1j * np.outer(t, w))).real, w, axis=1) / math.pi


def test_block_on_silent_floor_clicks_at_the_closed_form_level():
    sim, on = _run(True)
    _, off = _run(False)
    assert sim.channel_names == ["mic0", "contact_mic_block", "contact_mic_plate"]
    (rec,) = sim.impacts  # one landing (four corner contacts)
    mass = float(sim.model.body_mass[1])
    assert rec.impulse_pred == pytest.approx(mass * (1 + rec.restitution) * rec.speed, rel=1e-6)
    dv = rec.impulse_pred / mass
    tau = contact_time(hertz_coefficient(mass, 0.025, get_material("abs"), None), rec.speed)
    assert 3e-4 < tau < 6e-4
    click = on[0].astype(np.float64) - off[0]  # the block's modes (if any) are the same in both
    # the equivalent ellipsoid of a cube: a sphere of radius sqrt(5/3) 2.5 cm
    a = math.sqrt(5 / 3) * 0.025
    mic, com = np.array([0.3, -0.3, 0.4]), np.array([0.0, 0.0, 0.025])
    r = float(np.linalg.norm(mic - com))
    t = np.arange(click.size) / FS - rec.time
    near = np.abs(t - r / an.SPEED_OF_SOUND) < 0.004
    ref = _hankel_click(dv, tau, a, r, (mic - com)[2] / r, t[near])
    peak, want = np.abs(click).max(), np.abs(ref).max()
    assert 20 * math.log10(peak / want) == pytest.approx(0.0, abs=1.0)
    assert np.abs(click[near] - ref).max() < 0.05 * want
    # the documented level (README): 3.0 Pa, 103.5 dB SPL peak at 0.58 m, 43 degrees off the vertical
    assert 101 < 20 * math.log10(peak / 2e-5) < 106
    # the block's contact microphone reads its rigid-body pulse (the block has no modes below
    # 7.2 kHz; ``clicks`` switches the air's clicks only): area dv (less the band limit's
    # pre-ringing before the step's first sample), peak about dv pi / (2 tau)
    assert np.array_equal(on[1], off[1])
    pulse = on[1].astype(np.float64)
    assert pulse.sum() / FS == pytest.approx(dv, rel=2e-3)
    assert np.abs(pulse).max() == pytest.approx(dv * math.pi / (2 * tau), rel=0.1)
    assert not on[2].any()  # the plate was not touched: its sensor reads nothing
    assert not off[0].any()  # without clicks, this block on this floor is silent (no modes below 7.2 kHz)


def test_contact_mic_sites_by_prefix_or_name():
    m = mujoco.MjModel.from_xml_string(XML)
    assert contact_mic_sites(m) == [1, 2]
    assert contact_mic_sites(m, ["contact_mic_plate"]) == [2]
    assert contact_mic_sites(m, "mic0") == [0]  # any site, by name
    assert contact_mic_sites(m, []) == []
    with pytest.raises(ValueError, match="not in the model"):
        contact_mic_sites(m, ["contact_mic_nowhere"])


def test_audible_bodies_are_the_clicking_and_the_miked_bodies():
    """``ImpactPulses.audible_bodies``: with clicks, every free body (not the world); without,
    only the bodies that carry a contact microphone (the block's site, chosen by name)."""
    m = mujoco.MjModel.from_xml_string(XML)
    world, block, plate = 0, m.body("block").id, m.body("plate").id
    clicking = AudioSimulator(m, sample_rate=FS, quality="draft", progress=False, contact_mics=[])
    aud = clicking.pulses.audible_bodies()
    assert aud.shape == (m.nbody,) and not aud[world] and aud[block] and aud[plate]
    miked = AudioSimulator(m, sample_rate=FS, quality="draft", progress=False, clicks=False,
                           contact_mics=["contact_mic_block"])
    aud = miked.pulses.audible_bodies()
    assert aud[block] and not aud[plate] and not aud[world]
    quiet = AudioSimulator(m, sample_rate=FS, quality="draft", progress=False, clicks=False, contact_mics=[])
    assert not quiet.pulses.audible_bodies().any()
