"""Clicks and impulses true to the impact (docs/clicks.md): what welds a body to the world adds
nothing to the mass an impact pushes against; a velocity change is at most what the approach
allows, ``(1 + e) v``, whatever presses on through the contact; a click radiates from the
body's own shape, not from an inertia the MJCF file rounded up.

The scenes reproduce, in small, what was measured on robot-learning envs: robosuite's
Lift/Panda (a fixed-base arm on a 274.6 kg mount welded to the world), Meta-World's
button press (a mocap-welded gripper pressing at 5 cm/s), gym-aloha's insertion (a 50 g peg
with an inertia of 0.002 kg m^2 settling on the table at 0.9 m/s), MyoSuite's phalanges and
robosuite's finger pads (grams, with inertias of 1e-4 to 1e-2 kg m^2).
"""

import math

import mujoco
import numpy as np
import pytest

from mjsound.sim import AudioSimulator
from mjsound.sim.bodies import geom_shape_axes, moving_tree_mass
from mjsound.synth import accel_noise as an

FS = 16000

ARM_XML = """<mujoco><option timestep="0.0005" gravity="0 0 0"/>
<worldbody>
  <geom name="table" type="box" size="0.4 0.3 0.02" pos="0.3 0 -0.02"/>
  <body name="target" mocap="true" pos="0 0.5 0"/>
  <body name="mount" pos="0 0 0">
    <geom name="pedestal" type="box" size="0.1 0.1 0.1" pos="-0.3 0 -0.3" mass="274.6"/>
    <body name="base" pos="0 0 0.0151"><geom name="base" type="cylinder" size="0.03 0.01" mass="2"/>
      <body name="link" pos="0 0 0"><joint name="hinge" type="hinge" axis="0 1 0" armature="{armature}"/>
        <geom name="rod" type="capsule" fromto="0.03 0 0 0.3 0 0" size="0.01" mass="0.5"/>
        <geom name="tip" type="sphere" pos="0.3 0 0" size="0.015" mass="0.1"/>
      </body>
    </body>
  </body>
  <body name="cube" pos="0 0.5 0.1"><freejoint/><geom type="box" size="0.02 0.02 0.02" mass="0.2"/></body>
</worldbody></mujoco>"""


def _arm(armature):
    return mujoco.MjModel.from_xml_string(ARM_XML.format(armature=armature))


def test_moving_tree_mass_excludes_what_is_welded_to_the_world():
    """The arm's link moves with 0.6 kg; the mount (274.6 kg), the base welded to it and the
    mocap body do not move at all; a free body moves with its own mass. MuJoCo's
    ``body_subtreemass`` of the link's root (the mount) counts all 277.2 kg."""
    m = _arm(0)
    mt = moving_tree_mass(m)
    link, mount = m.body("link").id, m.body("mount").id
    assert m.body_subtreemass[m.body_rootid[link]] == pytest.approx(277.2)
    assert mt[link] == pytest.approx(0.6)
    assert np.isinf(mt[mount]) and np.isinf(mt[m.body("base").id]) and np.isinf(mt[m.body("target").id])
    assert np.isinf(mt[0])
    assert mt[m.body("cube").id] == pytest.approx(0.2)


def _touch(armature):
    """The arm's tip swung down onto the table at 0.08 m/s; (record, mass matrix entry)."""
    m = _arm(armature)
    d = mujoco.MjData(m)
    d.qvel[m.jnt_dofadr[m.joint("hinge").id]] = 0.08 / 0.3
    sim = AudioSimulator(m, d, sample_rate=FS, quality="draft", progress=False)
    sim.run(0.1)
    recs = [r for r in sim.impacts if {m.geom(r.geom1).name, m.geom(r.geom2).name} == {"tip", "table"}]
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)  # (a hinge's entry: its inertia about the axis, armature included)
    i = m.jnt_dofadr[m.joint("hinge").id]
    return recs[0], M[i, i]


def test_fixed_base_arm_touch_has_the_arm_effective_mass_and_no_mount():
    """A fixed-base arm touching lightly (robosuite Lift/Panda's
    ``ImpactRecord(speed=0.080, impulse_pred=35.97, effective_mass=293.6)``, 293.6 kg the
    subtree of ``robot0_base`` with its welded mount): the impulse is MuJoCo's own inverse
    inertia along the normal, ``1 / (J M^-1 J^T)``, here the hinge's ``I / L^2`` (the tip
    0.3 m from the hinge, moving along the normal); where that exceeds the mass that moves
    (a rotor's armature of 100 kg m^2 on the hinge: 1100 kg at the tip), the cap is the
    arm's 0.6 kg, never the mount's."""
    rec, inertia = _touch(0)
    assert rec.speed == pytest.approx(0.08, rel=0.1)
    assert rec.effective_mass == pytest.approx(inertia / 0.3**2, rel=0.01)
    assert rec.impulse_pred == pytest.approx(rec.effective_mass * (1 + rec.restitution) * rec.speed, rel=1e-9)
    heavy, inertia = _touch(100)
    assert inertia / 0.3**2 > 1000
    assert heavy.effective_mass == pytest.approx(0.6, rel=1e-9)


PUSH_XML = """<mujoco><option timestep="0.0025"/>
<custom><text name="mjsound:hand" data="abs"/><text name="mjsound:button" data="abs"/></custom>
<worldbody>
  <site name="mic" pos="0.2 0 0.4"/>
  <body name="table" pos="0 0 0"><geom name="top" type="box" size="0.5 0.5 0.02" pos="0 0 0.1" mass="1000"/>
    <body name="box" pos="0 0 0.14"><geom name="box" type="box" size="0.04 0.04 0.02" mass="1"/>
      <body name="button" pos="0 0 0.03">
        <joint name="press" type="slide" axis="0 0 1" stiffness="50" damping="1" limited="true" range="-0.02 0"/>
        <geom name="button" type="box" size=".03 .03 .01" mass="0.05"/></body></body></body>
  <body name="target" mocap="true" pos="0 0 0.2"/>
  <body name="hand" pos="0 0 0.2"><freejoint/>
    <inertial pos="0 0 0" mass="0.33" diaginertia="{inertia} {inertia} {inertia}"/>
    <geom name="hand" type="box" size="0.03 0.03 0.01"/></body>
</worldbody>
<equality><weld body1="target" body2="hand"/></equality>
</mujoco>"""


def _press(inertia, clicks=True):
    """The mocap target carries the welded hand down at 6 cm/s onto the button and on, pressing
    (0.6 s: the hand meets the button after 0.2 s and pushes 0.4 s more)."""
    m = mujoco.MjModel.from_xml_string(PUSH_XML.format(inertia=inertia))
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, sample_rate=FS, quality="draft", progress=False, clicks=clicks)
    out = []
    while d.time < 0.6:
        d.mocap_pos[0, 2] = 0.2 - 0.06 * d.time
        mujoco.mj_step(m, d)
        out.append(sim.step())
    return sim, np.concatenate(out, axis=1)[0].astype(np.float64)


def _dipole_bound(axes, dv, tau, r):
    """Largest pressure [Pa] at distance ``r`` of a compact ellipsoid (semi-axes ``axes``,
    moving along its largest dipole mass ``M``) whose velocity changes by ``dv`` in a
    half-sine of ``tau``: ``p = M (a / r^2 + a' / (r c)) / (4 pi)`` with the half-sine's peaks
    ``a = pi dv / (2 tau)``, ``a' = pi^2 dv / (2 tau^2)``."""
    M = float(np.max(an.dipole_masses(np.asarray(axes))))
    acc, jerk = math.pi * dv / (2 * tau), math.pi**2 * dv / (2 * tau * tau)
    return M * (acc / r**2 + jerk / (r * an.SPEED_OF_SOUND)) / (4 * math.pi)


def test_mocap_push_clicks_from_the_approach_not_the_push():
    """Meta-World's expert pressing a button (a mocap-welded gripper at 5 cm/s) made an impact
    of 45.5 N s on a 0.33 kg effective mass (137 m/s from 0.05 m/s) and a 91.6 Pa click. Here
    the hand (0.33 kg, a 6 x 6 x 2 cm box with an inertia rounded up to 0.01 kg m^2, a 27 cm
    ellipsoid) meets the button (50 g on a spring): the predicted impulse is the two free
    masses' ``m* (1 + e) v``; MuJoCo's sum of F dt over the pressing (the weld pushing on) is a
    hundred times more and enters nothing; the click is no louder than the hand's own shape
    changing its velocity by ``(1 + e) v`` in the contact time allows."""
    sim, on = _press(0.01)
    _, off = _press(0.01, clicks=False)
    (rec,) = [r for r in sim.impacts if {sim.model.geom(r.geom1).name, sim.model.geom(r.geom2).name}
              == {"hand", "button"}]
    m_star = 1 / (1 / 0.33 + 1 / 0.05)
    assert rec.speed == pytest.approx(0.06, rel=0.05)
    assert rec.effective_mass == pytest.approx(m_star, rel=0.02)
    assert rec.impulse_sim > 50 * rec.impulse_pred  # the push, over the event's 0.1 s
    hand = sim.model.body("hand").id
    shape = geom_shape_axes(sim.model, hand)
    np.testing.assert_allclose(sim.pulses._axes[hand], shape, rtol=1e-12)  # not the 27 cm ellipsoid
    np.testing.assert_allclose(shape, math.sqrt(5 / 3) * np.array([0.03, 0.03, 0.01]), rtol=1e-9)
    from mjsound.sim.click_kernels import pair_contact_time

    g1, g2 = sim.model.geom("hand").id, sim.model.geom("button").id
    tau = pair_contact_time(sim.pulses.state.model, g1, g2, rec.speed)
    r = float(np.linalg.norm(np.array([0.2, 0, 0.4]) - np.array([0, 0, 0.16])))
    bound = _dipole_bound(shape, (1 + rec.restitution) * rec.speed, tau, r - 0.05)
    click = np.abs(on - off).max()
    assert 0 < click <= bound
    assert click < 0.5  # (91.6 Pa before)


PEG_XML = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:table" data="oak"/><text name="mjsound:peg" data="abs"/></custom>
<worldbody>
  <site name="mic" pos="0 -0.4 0.5"/>
  <geom name="table" type="box" size="0.4 0.3 0.015" pos="0 0 0.015"/>
  <body name="peg" pos="0 0 {z}"><freejoint/>{inertial}
    <geom name="peg" type="box" size="0.06 0.01 0.01" {mass}/></body>
</worldbody></mujoco>"""


def _peg(inertial, clicks=True):
    """gym-aloha's peg (12 x 2 x 2 cm, 50 g) dropped to meet the table at 0.9 m/s."""
    h = 0.9**2 / (2 * 9.81)
    if inertial:
        xml = PEG_XML.format(z=0.04 + h, inertial='<inertial pos="0 0 0" mass="0.05" diaginertia="0.002 0.002 0.002"/>',
                             mass="")
    else:
        xml = PEG_XML.format(z=0.04 + h, inertial="", mass='mass="0.05"')
    m = mujoco.MjModel.from_xml_string(xml)
    sim = AudioSimulator(m, sample_rate=FS, quality="draft", progress=False, clicks=clicks)
    return sim, sim.run(0.25)[0].astype(np.float64)


def test_settling_peg_clicks_as_its_shape_whatever_its_inertia():
    """gym-aloha's 50 g peg settling at 0.9 m/s peaked at 85 Pa, 64x the table's own ring: its
    inertia of 0.002 kg m^2 made a 32 cm ellipsoid of a 12 x 2 x 2 cm box. Its click now is
    the one of the same peg with the inertia MuJoCo computes from its geom (within 1 dB), and
    its ellipsoid is the box's own."""
    sim, on = _peg(True)
    _, off = _peg(True, clicks=False)
    ref_sim, ref_on = _peg(False)
    peg = sim.model.body("peg").id
    np.testing.assert_allclose(sim.pulses._axes[peg], ref_sim.pulses._axes[peg], rtol=1e-9)
    assert sim.pulses._axes[peg].max() < 0.08  # (0.32 m from the inertia)
    rec = sim.impacts[0]
    assert rec.speed == pytest.approx(0.9, rel=0.05)
    click, ref_click = np.abs(on - off).max(), np.abs(ref_on - off).max()
    assert 20 * math.log10(click / ref_click) == pytest.approx(0.0, abs=1.0)
    assert click < 5.0  # (85 Pa before, the click dominating)


FINGER_XML = """<mujoco><worldbody>
  <body name="phalanx" pos="0 0 0.1"><freejoint/>
    <inertial pos="0 0 0" mass="0.005" diaginertia="1e-4 1e-4 1e-4"/>
    <geom name="bone" type="capsule" fromto="0 0 0 0 0 0.03" size="0.006"/>
    <geom name="skin" type="sphere" pos="0 0 0.03" size="0.007" contype="0" conaffinity="0" group="1"/></body>
  <body name="pad" pos="0.2 0 0.1"><freejoint/>
    <inertial pos="0 0 0" mass="0.01" diaginertia="0.01 0.01 0.01"/>
    <geom name="pad" type="box" size="0.01 0.004 0.01"/></body>
  <body name="ball" pos="0.4 0 0.1"><freejoint/><geom name="ball" type="sphere" size="0.02"/></body>
</worldbody></mujoco>"""


def test_click_ellipsoids_stay_within_the_bodies_geoms():
    """MyoSuite's phalanges (5 g, inertia 1e-4: 0.16-0.35 m ellipsoids around 5-9 mm capsules)
    and robosuite's finger pads (10 g, inertia 0.01: 1.58 m) click from ellipsoids no larger
    than their geoms' (the phalanx's visual skin sphere counts); a ball whose inertia is its
    own keeps its radius."""
    from mjsound.sim.clicks import ImpactPulses

    m = mujoco.MjModel.from_xml_string(FINGER_XML)
    p = ImpactPulses(m, [None] * m.ngeom, np.full(m.ngeom, np.inf), 1, [], FS)
    phalanx, pad, ball = (m.body(n).id for n in ("phalanx", "pad", "ball"))
    assert an.ellipsoid_from_inertia(0.01, [0.01] * 3).max() > 1.5  # robosuite's 1.58 m
    a = p._axes[phalanx]
    assert a.max() < 0.04 and a.min() < 0.012  # a 6 mm capsule 3 cm long with its 7 mm tip
    assert np.all(a >= 0.006)
    np.testing.assert_allclose(np.sort(p._axes[pad]), np.sort(math.sqrt(5 / 3) * np.array([0.004, 0.01, 0.01])),
                               rtol=1e-9)
    np.testing.assert_allclose(p._axes[ball], 0.02, rtol=1e-9)
    assert geom_shape_axes(m, 0) is None  # the world has no geom here
