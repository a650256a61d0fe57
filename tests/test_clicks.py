"""Impact pulses of a MuJoCo scene: a block dropped on a silent floor clicks at the level of the
rigid-sphere closed form, resting and sliding contact add nothing, contact microphones feel
only their own body."""

import math

import mujoco
import numpy as np
import pytest
from scipy.special import spherical_jn, spherical_yn

from mjsound.materials import get_material
from mjsound.sim.clicks import ImpactPulses, contact_mic_sites
from mjsound.sim.contacts import I_G1, I_G2, I_IMPULSE, I_NORMAL, I_POINT, I_SPEED, ContactReader
from mjsound.sim.scene import geom_contact_radius
from mjsound.synth import accel_noise as an
from mjsound.synth.bandlimited import PASS_FRACTION
from mjsound.synth.pulse import contact_time, hertz_coefficient

FS = 48000
XML = """<mujoco><option timestep="0.001"/>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <site name="mic0" pos="0.3 -0.3 0.4"/>
  <body name="block" pos="0 0 {z}"><freejoint/>
    <geom name="block" type="box" size="0.025 0.025 0.025" density="1050"/>
    <site name="contact_mic_block" pos="0 0 0.025"/>
  </body>
  <body name="plate" pos="0.6 0 0.01"><freejoint/>
    <geom name="plate" type="box" size="0.1 0.1 0.01" density="2700"/>
    <site name="contact_mic_plate" pos="0 0 0.01"/>
  </body>
</worldbody></mujoco>"""


IMPACT = np.dtype([("g1", np.int64), ("g2", np.int64), ("point", np.float64, (3,)), ("normal", np.float64, (3,)),
                   ("impulse", np.float64), ("speed", np.float64)])


def _records(rows):
    rec = np.zeros(len(rows), IMPACT)
    rec["g1"], rec["g2"] = rows[:, I_G1], rows[:, I_G2]
    rec["point"], rec["normal"] = rows[:, I_POINT:I_POINT + 3], rows[:, I_NORMAL:I_NORMAL + 3]
    rec["impulse"], rec["speed"] = rows[:, I_IMPULSE], rows[:, I_SPEED]
    return rec


def _run(z=0.125, steps=400, vel=None, friction=None):
    """Drop the 5 cm ABS block (131 g) from ``z`` onto a floor without a material; returns the
    (air, contact block, contact plate) channels, the impact rows and the pulse source."""
    m = mujoco.MjModel.from_xml_string(XML.format(z=z))
    if friction is not None:
        m.geom_friction[:, 0] = friction
    d = mujoco.MjData(m)
    if vel is not None:
        d.qvel[:3] = vel
    mats = [None, get_material("abs"), get_material("aluminium")]
    radius = np.array([geom_contact_radius(m, g) for g in range(m.ngeom)])
    reader = ContactReader(m, restitution=[None, 0.5, 0.5])
    pulses = ImpactPulses(m, mats, radius, 1, contact_mic_sites(m), FS)
    blocks, n, rows = [], 0, []
    for _ in range(steps):
        t0 = d.time
        mujoco.mj_step(m, d)
        imp, _ = reader.events_fast(d, t0, d.time)
        if imp is not None:
            rows.append(imp.copy())
            pulses.add(_records(imp), t0, d, d.site_xpos[[0]])
        n1 = int(math.ceil(d.time * FS - 1e-6))
        b = pulses.take(n1 - n)
        blocks.append(np.zeros((3, n1 - n)) if b is None else b)
        n = n1
    return np.concatenate(blocks, axis=1), rows, m, d


def test_block_on_silent_floor_clicks_at_the_closed_form_level():
    x, rows, m, d = _run()
    assert len(rows) == 1  # one landing (four corner contacts)
    J = float(rows[0][:, I_IMPULSE].sum())
    mass = float(m.body_mass[1])
    v = float(rows[0][0, 9])
    assert J == pytest.approx(mass * 1.5 * v, rel=1e-6)  # restitution 0.5 of ABS on a rigid floor
    dv = J / mass
    tau = contact_time(hertz_coefficient(mass, 0.025, get_material("abs"), None), v)
    assert 3e-4 < tau < 6e-4
    # reference: the rigid sphere of the block's equivalent ellipsoid (a cube: a sphere of
    # radius sqrt(5/3) 2.5 cm), Hankel closed form, band-limited like the output
    a = math.sqrt(5 / 3) * 0.025
    mic = np.array([0.3, -0.3, 0.4])
    com = np.array([0.0, 0.0, 0.025])
    r = float(np.linalg.norm(mic - com))
    cos_t = (mic - com)[2] / r
    w = np.linspace(1e-3, math.pi * FS, 30000)
    k = w / an.SPEED_OF_SOUND
    acc = dv * (math.pi / tau) ** 2 * (1 + np.exp(-1j * w * tau)) / (2 * ((math.pi / tau) ** 2 - w * w))
    h = spherical_jn(1, k * r) - 1j * spherical_yn(1, k * r)
    hd = spherical_jn(1, k * a, derivative=True) - 1j * spherical_yn(1, k * a, derivative=True)
    p = -1j * an.RHO_AIR * an.SPEED_OF_SOUND * acc / (1j * w) * cos_t * h / hd
    g = np.clip((w / (2 * math.pi * FS) - PASS_FRACTION) / (0.5 - PASS_FRACTION), 0, 1)
    p = p * 0.5 * (1 + np.cos(math.pi * g))
    t = np.arange(-200, 600) / FS
    ref = np.trapezoid((p[None, :] * np.exp(1j * np.outer(t, w))).real, w, axis=1) / math.pi
    peak, want = np.abs(x[0]).max(), np.abs(ref).max()
    assert 20 * math.log10(peak / want) == pytest.approx(0.0, abs=1.0)
    # the documented level (README): 2.9 Pa, 103 dB SPL peak at 0.58 m, 43 degrees off the vertical
    assert 100 < 20 * math.log10(peak / 2e-5) < 106
    # the contact microphone on the block reads its rigid-body pulse: area dv, peak dv pi / (2 tau)
    # (less the band limit's pre-ringing before the step's first sample, already handed out)
    assert x[1].sum() / FS == pytest.approx(dv, rel=1e-3)
    assert np.abs(x[1]).max() == pytest.approx(dv * math.pi / (2 * tau), rel=0.05)
    assert not x[2].any()  # the plate was not touched: its sensor reads nothing


def test_resting_and_sliding_contact_add_no_clicks():
    x, rows, _, _ = _run(z=0.0251, steps=300)  # set down at rest
    assert not rows and not x.any()
    x, rows, _, _ = _run(z=0.025, steps=300, vel=[0.8, 0.0, 0.0], friction=0.2)  # slides 16 cm
    assert not rows and not x.any()


def test_contact_mic_sites_by_prefix_or_name():
    m = mujoco.MjModel.from_xml_string(XML.format(z=0.125).replace('pos="0.6 0 0.01"', 'pos="0 0 0.01"'))
    assert contact_mic_sites(m) == [1, 2]
    assert contact_mic_sites(m, ["contact_mic_plate"]) == [2]
    with pytest.raises(ValueError, match="not in the model"):
        contact_mic_sites(m, ["contact_mic_nowhere"])
    assert contact_mic_sites(m, "mic0") == [0]  # any site, by name