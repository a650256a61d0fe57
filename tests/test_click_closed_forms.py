"""Clicks of MuJoCo scenes against closed forms (docs/clicks.md).

* A prolate ellipsoid (not a sphere) landing on its side: the dipole of a translating
  ellipsoid, its strength ``M`` (displaced plus added air mass across its axis) from Lamb's
  closed form for a prolate spheroid (*Hydrodynamics*, 1932, sec. 115), computed here
  independently of :mod:`mjsound.synth.accel_noise`, radiating with the exact field of the
  rigid sphere of the same volume (Morse and Ingard): the compact ellipsoid's
  ``p = M cos(theta) (a / r^2 + a' / (r c)) / (4 pi)`` where ``ka`` is small.
* Two equal spheres colliding head on (in ABS): the transient dipole model of Koss and Alfredson
  ("Transient sound radiated by spheres undergoing an elastic collision", J. Sound Vib.
  27(1), 59-75, 1973), whose measurements it was checked against: the impactor decelerates and
  the impactee accelerates by ``(1 + e) V0 / 2`` in the same Hertz half-sine, each a rigid
  sphere radiating from its own centre (Morse and Ingard's exact solution), and the two add.
"""

import math

import mujoco
import numpy as np
import pytest
from scipy.special import spherical_jn, spherical_yn

from mjsound.sim import AudioSimulator
from mjsound.sim.click_kernels import pair_contact_time
from mjsound.synth import accel_noise as an
from mjsound.synth.bandlimited import PASS_FRACTION

FS = 16000
RHO, C = an.RHO_AIR, an.SPEED_OF_SOUND


def _band_limit(P, w):
    """The output's band limit (raised cosine from ``PASS_FRACTION`` of the rate to Nyquist)."""
    g = np.clip((w / (2 * math.pi * FS) - PASS_FRACTION) / (0.5 - PASS_FRACTION), 0, 1)
    return P * 0.5 * (1 + np.cos(math.pi * g))


def _half_sine(w, dv, tau):
    """Spectrum of the half-sine acceleration of area ``dv`` over ``tau`` (``e^{jwt}``)."""
    return dv * (math.pi / tau) ** 2 * (1 + np.exp(-1j * w * tau)) / (2 * ((math.pi / tau) ** 2 - w * w))


def _to_time(P, w, t):
    return np.trapezoid((P[None, :] * np.exp(1j * np.outer(t, w))).real, w, axis=1) / math.pi


ELLIPSOID_XML = """<mujoco><option timestep="0.0005"/>
<custom><text name="mjsound:egg" data="abs"/></custom>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <site name="mic" pos="0 0 0.8"/>
  <body name="egg" pos="0 0 0.065"><freejoint/>
    <geom name="egg" type="ellipsoid" size="0.03 0.015 0.015" density="1050"/></body>
</worldbody></mujoco>"""


def _lamb_prolate_transverse(a, b):
    """Dipole mass per unit displaced air mass of a prolate spheroid (semi-axes ``a > b = b``)
    moving across its axis: ``1 + beta0 / (2 - beta0)``, ``beta0 = 1/e^2 - (1 - e^2)/(2 e^3)
    ln((1 + e)/(1 - e))`` (Lamb sec. 115)."""
    e = math.sqrt(1 - (b / a) ** 2)
    beta0 = 1 / e**2 - (1 - e * e) / (2 * e**3) * math.log((1 + e) / (1 - e))
    return 1 + beta0 / (2 - beta0)


def _drop(xml, clicks):
    m = mujoco.MjModel.from_xml_string(xml)
    sim = AudioSimulator(m, sample_rate=FS, quality="draft", progress=False, clicks=clicks,
                         reflections=False)  # (the free field of the closed form; the floor's echo: test_rooms)
    return sim, sim.run(0.2)[0].astype(np.float64)


def test_ellipsoid_click_is_its_compact_dipole_with_lambs_added_mass():
    """A 6 x 3 x 3 cm ABS ellipsoid lands on its side at 0.8 m/s on a floor without a material;
    the microphone 0.77 m above hears the dipole of its velocity change across its long axis."""
    sim, on = _drop(ELLIPSOID_XML, True)
    _, off = _drop(ELLIPSOID_XML, False)
    rec = sim.impacts[0]
    m = sim.model
    egg = m.body("egg").id
    mass = float(m.body_mass[egg])
    dv = rec.impulse_pred / mass
    assert dv == pytest.approx((1 + rec.restitution) * rec.speed, rel=1e-6)  # a free body on the ground
    tau = pair_contact_time(sim.pulses.state.model, m.geom("floor").id, m.geom("egg").id, rec.speed)
    volume = 4 / 3 * math.pi * 0.03 * 0.015 * 0.015
    M = RHO * volume * _lamb_prolate_transverse(0.03, 0.015)
    r = 0.8 - 0.015
    w = np.linspace(1e-3, math.pi * FS, 20000)
    # the sphere of the same volume's exact field, its dipole mass (1.5 rho V) made Lamb's: the
    # compact ellipsoid where ka is small, the sphere's roll-off above
    a_eq = volume ** (1 / 3) / (4 / 3 * math.pi) ** (1 / 3)
    P = M / (1.5 * RHO * volume) * _hankel(w, a_eq, r, 1.0) * _half_sine(w, dv, tau)
    click = on - off
    t = np.arange(click.size) / FS - rec.time
    near = np.abs(t - r / C) < 0.004
    ref = _to_time(_band_limit(P, w), w, t[near])
    peak, want = np.abs(click[near]).max(), np.abs(ref).max()
    assert 20 * math.log10(peak / want) == pytest.approx(0.0, abs=1.0)
    assert np.corrcoef(click[near], ref)[0, 1] > 0.95


SPHERES_XML = """<mujoco><option timestep="0.00005" gravity="0 0 0"/>
<custom><text name="mjsound:impactor" data="abs"/><text name="mjsound:impactee" data="abs"/></custom>
<worldbody>
  <site name="mic" pos="0.5254 0 0"/>
  <body name="impactor" pos="-0.0254 0 0"><freejoint/><geom name="impactor" type="sphere" size="0.0127" density="1050"/></body>
  <body name="impactee" pos="0.0001 0 0"><freejoint/><geom name="impactee" type="sphere" size="0.0127" density="1050"/></body>
</worldbody></mujoco>"""


def _hankel(w, a, r, cos_t):
    """Morse and Ingard's rigid sphere: pressure per unit acceleration spectrum,
    ``-j rho c cos(theta) h1(kr) / (j w h1'(ka))``."""
    k = w / C
    h = spherical_jn(1, k * r) - 1j * spherical_yn(1, k * r)
    hd = spherical_jn(1, k * a, derivative=True) - 1j * spherical_yn(1, k * a, derivative=True)
    return -1j * RHO * C / (1j * w) * cos_t * h / hd


def test_colliding_spheres_are_two_opposite_dipoles():
    """Koss and Alfredson's experiment in small: a 25.4 mm ball (the impactor) strikes an equal
    ball at rest at 1 m/s, head on (ABS, not their steel: a contact of 0.2 ms whose spectrum lies
    inside the 16 kHz output's band; steel's 40 us reach past it); on the line of centres, 0.5 m beyond the impactee,
    the sound is the impactee's dipole (accelerating towards the microphone) and the
    impactor's (decelerating, from 2 radii further back), each of ``(1 + e) V0 / 2`` in the
    same half-sine."""
    m = mujoco.MjModel.from_xml_string(SPHERES_XML)
    d = mujoco.MjData(m)
    d.qvel[0] = 1.0
    sim = AudioSimulator(m, d, sample_rate=FS, quality="draft", progress=False)
    out = sim.run(0.05)[0].astype(np.float64)
    (rec,) = sim.impacts
    mass = float(m.body_mass[1])
    assert rec.effective_mass == pytest.approx(mass / 2, rel=1e-3)
    dv = rec.impulse_pred / mass
    assert dv == pytest.approx((1 + rec.restitution) * rec.speed / 2, rel=1e-3)
    tau = pair_contact_time(sim.pulses.state.model, 0, 1, rec.speed)
    assert 1e-4 < tau < 5e-4  # (Hertz for 25 mm ABS balls at 1 m/s)
    w = np.linspace(1e-3, math.pi * FS, 20000)
    A = _half_sine(w, dv, tau)
    mic = 0.5254
    x_ee, x_or = 0.0001, 0.0001 - 0.0254  # (the centres at the contact: the impactee at rest, two radii apart)
    P = _hankel(w, 0.0127, mic - x_ee, 1.0) * A - _hankel(w, 0.0127, mic - x_or, 1.0) * A
    t = np.arange(out.size) / FS - rec.time
    near = np.abs(t - (mic - x_ee) / C) < 0.003
    # (the two fields nearly cancel, leaving their time derivative: its shape shows an onset
    # error of one physics step, 50 us, which the single dipole's does not; align within two)
    shifts = np.linspace(-2, 2, 17) * m.opt.timestep
    refs = [_to_time(_band_limit(P, w), w, t[near] - dt) for dt in shifts]
    corr = [np.corrcoef(out[near], r)[0, 1] for r in refs]
    ref = refs[int(np.argmax(corr))]
    peak, want = np.abs(out[near]).max(), np.abs(ref).max()
    assert 20 * math.log10(peak / want) == pytest.approx(0.0, abs=1.0)
    assert max(corr) > 0.95
