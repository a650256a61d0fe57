"""The thin-shell contact time of impact clicks (:func:`mjsound.synth.pulse.shell_contact_time`,
:func:`mjsound.sim.clicks.shell_compliances`): a hand computation, a table-tennis ball, solid
bodies unchanged bit for bit, gymnasium's Ant no longer deafening, and bad input finite."""

import math

import mujoco
import numpy as np
import pytest

from mjsound.materials import get_material
from mjsound.sim.click_kernels import hertz_coefficient, pair_contact_time
from mjsound.sim.clicks import SHELL_MAX_WALL_RATIO, ImpactPulses, geom_volume_area, shell_compliances
from mjsound.synth.pulse import TAU_MAX_S, TAU_MIN_S, contact_time, shell_compliance, shell_contact_time

FS = 16000


def _reissner_tau(mass, walls):
    """Plain-Python reference: ``pi sqrt(m (sum R sqrt(3 (1 - nu^2)) / (4 E t^2)))`` [s] for
    ``walls`` a list of ``(E [Pa], nu, t [m], R [m])``, clamped."""
    s = sum(R * math.sqrt(3.0 * (1.0 - nu * nu)) / (4.0 * E * t * t) for E, nu, t, R in walls)
    return min(max(math.pi * math.sqrt(mass * s), TAU_MIN_S), TAU_MAX_S)


def _pulses(xml, mats):
    """``ImpactPulses`` of ``xml`` with materials by geom name (others: none)."""
    from mjsound.sim.scene import geom_contact_radius

    m = mujoco.MjModel.from_xml_string(xml)
    mat = [get_material(mats[m.geom(g).name]) if m.geom(g).name in mats else None for g in range(m.ngeom)]
    radius = np.array([geom_contact_radius(m, g) for g in range(m.ngeom)])
    return ImpactPulses(m, mat, radius, 1, [], FS, active=False)


def test_shell_time_by_hand():
    al = get_material("aluminium")
    s = shell_compliance(al, 1e-4, 0.05)  # 0.1 mm wall, 5 cm radius
    assert s == pytest.approx(0.05 * math.sqrt(3 * (1 - 0.33**2)) / (4 * 70e9 * 1e-8), rel=1e-12)
    assert 1 / s == pytest.approx(3.42e4, rel=1e-2)  # [N/m]
    # 0.2 kg on it against a rigid floor: pi sqrt(0.2 / 34.2e3) = 7.6 ms; two such walls in series: sqrt(2) longer
    assert shell_contact_time(0.2, s, 0.0) == pytest.approx(_reissner_tau(0.2, [(70e9, 0.33, 1e-4, 0.05)]), rel=1e-12)
    assert shell_contact_time(0.2, s, 0.0) == pytest.approx(7.6e-3, rel=1e-2)
    assert shell_contact_time(0.2, s, s) == pytest.approx(math.sqrt(2) * shell_contact_time(0.2, s, 0.0), rel=1e-12)
    # solid (no shell), immovable or massless: 0 (Hertz's alone); clamped at the ends
    assert shell_contact_time(0.2, 0.0, 0.0) == 0.0
    assert shell_contact_time(math.inf, s, 0.0) == 0.0
    assert shell_contact_time(0.0, s, 0.0) == 0.0 and shell_contact_time(math.nan, s, 0.0) == 0.0
    assert shell_contact_time(1e6, 1.0, 0.0) == TAU_MAX_S and shell_contact_time(1e-30, 1e-30, 0.0) == TAU_MIN_S
    assert shell_compliance(al, 0.0, 0.05) == 0.0 and shell_compliance(al, 1e-4, math.inf) == 0.0


PING_PONG = """<mujoco><worldbody>
  <geom name="table" type="plane" size="2 2 0.1"/>
  <body name="ball" pos="0 0 0.3"><freejoint/><geom name="ball" type="sphere" size="0.02" mass="0.0027"/></body>
</worldbody></mujoco>"""


def test_table_tennis_ball_touches_for_about_a_millisecond():
    """A 2.7 g, 40 mm ball of ABS (modern balls are plastic shells; celluloid is alike) on a
    rigid table: its wall by mass is 0.51 mm (a real one: 0.4 to 0.5 mm), Reissner's spring
    74 kN/m, 0.60 ms of contact at any speed; measured balls touch a hard surface for about
    1 ms (the linear spring is the stiff end of a wall that flattens and buckles), while a
    solid ABS ball of that mass and radius would touch for 60 us at 3 m/s."""
    p = _pulses(PING_PONG, {"ball": "abs"})
    cm = p._model
    abs_ = get_material("abs")
    wall = 0.0027 / (abs_.rho * 4 * math.pi * 0.02**2)
    assert wall == pytest.approx(5.12e-4, rel=1e-2) and wall / 0.02 < SHELL_MAX_WALL_RATIO
    assert cm.geoms[1]["shell_compliance"] == pytest.approx(shell_compliance(abs_, wall, 0.02), rel=1e-12)
    ref = _reissner_tau(0.0027, [(abs_.E, abs_.nu, wall, 0.02)])
    for speed in (1.0, 3.0, 8.0):
        tau = pair_contact_time(cm, 0, 1, speed)
        hertz = contact_time(hertz_coefficient(cm, 0, 1), speed)
        assert tau == pytest.approx(ref, rel=1e-12)
        assert 1e-3 / 1.7 < tau < 1.5e-3  # 0.60 ms
        assert tau > 5 * hertz  # solid Hertz: 87 us at 1 m/s, 60 us at 3 m/s
    # the same ball on a second such ball: the walls in series
    assert shell_contact_time(0.0027 / 2, cm.geoms[1]["shell_compliance"], cm.geoms[1]["shell_compliance"]) == \
        pytest.approx(_reissner_tau(0.0027 / 2, [(abs_.E, abs_.nu, wall, 0.02)] * 2), rel=1e-12)


SOLIDS = """<mujoco><worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <body name="ball" pos="0 0 0.3"><freejoint/><geom name="ball" type="sphere" size="0.03" density="7850"/></body>
  <body name="leg" pos="0.5 0 0.3"><freejoint/>
    <geom name="leg" type="capsule" fromto="0 0 0 0 0 0.4" size="0.05" density="1000"/></body>
  <body name="head" pos="-0.5 0 0.3"><freejoint/><geom name="head" type="sphere" size="0.09" density="1000"/></body>
  <body name="disc" pos="1 0 0.3"><freejoint/>
    <geom name="disc" type="cylinder" size="0.1 0.005" density="8500"/></body>
  <body name="plate" pos="0 1 0.3"><freejoint/>
    <geom name="plate" type="box" size="0.1 0.1 0.004" density="2700"/></body>
</worldbody></mujoco>"""


def test_solid_bodies_keep_hertz_bit_for_bit():
    """Bodies of their material's density (a steel ball, a brass disc and an aluminium plate,
    thin beside their curvature but solid) and MuJoCo's default density 1000 in aluminium
    (Walker2d's, Humanoid's: t / R 0.12 to 0.19) are no shells: ``tau`` is Hertz's exactly."""
    mats = {"floor": "concrete", "ball": "steel", "leg": "aluminium", "head": "aluminium", "disc": "brass",
            "plate": "aluminium"}
    p = _pulses(SOLIDS, mats)
    cm = p._model
    assert not cm.geoms["shell_compliance"].any()
    for g1 in range(cm.geoms.shape[0]):
        for g2 in range(cm.geoms.shape[0]):
            for speed in (0.0, 0.01, 0.7, 3.6, 40.0):
                assert pair_contact_time(cm, g1, g2, speed) == contact_time(hertz_coefficient(cm, g1, g2), speed)


ANT_LIKE = """<mujoco><worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <body name="torso" pos="0 0 0.75"><freejoint/><geom name="torso" type="sphere" size="0.25" density="5"/>
    <body name="ankle" pos="0.2 0.2 0"><joint type="hinge" axis="0 0 1"/>
      <geom name="ankle" type="capsule" fromto="0 0 0 0.4 0.4 0" size="0.08" density="5"/></body>
  </body>
</worldbody></mujoco>"""


def test_ant_bodies_are_foil_shells():
    """Ant's density 5 in aluminium: walls of 150 um (torso) and 70 um (ankles), milliseconds
    of contact against the 72 to 163 us of solid Hertz, each geom's compliance as computed by
    hand from its body's mass and surface."""
    p = _pulses(ANT_LIKE, {"floor": "aluminium", "torso": "aluminium", "ankle": "aluminium"})
    m, cm, al = p.model, p._model, get_material("aluminium")
    torso, ankle = m.geom("torso").id, m.geom("ankle").id
    r, h = 0.08, 0.2 * math.sqrt(2)
    walls = {torso: m.body_mass[1] / (al.rho * 4 * math.pi * 0.25**2),
             ankle: m.body_mass[2] / (al.rho * (2 * math.pi * r * (2 * h + 2 * r)))}
    assert walls[torso] == pytest.approx(1.5e-4, rel=0.05) and walls[ankle] == pytest.approx(6.9e-5, rel=0.05)
    for g, R in ((torso, 0.25), (ankle, r)):
        assert cm.geoms[g]["shell_compliance"] == pytest.approx(shell_compliance(al, walls[g], R), rel=1e-12)
        hertz = contact_time(hertz_coefficient(cm, 0, g), 3.6)
        tau = pair_contact_time(cm, 0, g, 3.6)
        mass = m.body_subtreemass[m.geom_bodyid[g]]
        assert tau == pytest.approx(_reissner_tau(mass, [(al.E, al.nu, walls[g], R)]), rel=1e-12)
        assert tau > 2e-3 and hertz < 2e-4
    # torso on ankle (both shells, both bodies moving): the springs in series, the masses combined
    mass = 1 / (1 / m.body_subtreemass[1] + 1 / m.body_subtreemass[2])
    ref = _reissner_tau(mass, [(al.E, al.nu, walls[torso], 0.25), (al.E, al.nu, walls[ankle], r)])
    assert pair_contact_time(cm, torso, ankle, 1.0) == pytest.approx(ref, rel=1e-12)


def test_geom_volume_and_area():
    xml = """<mujoco><asset><mesh name="cube" vertex="-1 -1 -1 1 -1 -1 -1 1 -1 1 1 -1 -1 -1 1 1 -1 1 -1 1 1 1 1 1"
      scale="0.05 0.05 0.05"/></asset><worldbody>
      <geom type="sphere" size="0.1"/><geom type="capsule" size="0.1 0.2"/><geom type="cylinder" size="0.1 0.2"/>
      <geom type="box" size="0.1 0.2 0.3"/><geom type="ellipsoid" size="0.1 0.1 0.1"/><geom type="mesh" mesh="cube"/>
      <geom type="plane" size="1 1 1"/></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    pi = math.pi
    want = [(4 / 3 * pi * 1e-3, 4 * pi * 1e-2),  # sphere r 0.1
            (pi * 1e-2 * 0.4 + 4 / 3 * pi * 1e-3, 2 * pi * 0.1 * 0.4 + 4 * pi * 1e-2),  # capsule r 0.1, 0.4 long
            (pi * 1e-2 * 0.4, 2 * pi * 0.1 * 0.4 + 2 * pi * 1e-2),  # cylinder r 0.1, 0.4 high
            (8 * 0.006, 8 * (0.02 + 0.06 + 0.03)),  # box 0.2 x 0.4 x 0.6
            (4 / 3 * pi * 1e-3, 4 * pi * 1e-2),  # a round ellipsoid (Thomsen's formula exact)
            (1e-3, 6e-2)]  # a 10 cm cube as a mesh
    for g, (v, a) in enumerate(want):
        got = geom_volume_area(m, g)
        rel = 1e-6 if g == 5 else 1e-9  # (the mesh's vertices are float32)
        assert got[0] == pytest.approx(v, rel=rel) and got[1] == pytest.approx(a, rel=rel)
    assert geom_volume_area(m, 6) is None  # a plane has no volume


BAD = """<mujoco><worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <body name="a" pos="0 0 0.3"><freejoint/><geom name="a" type="sphere" size="0.1" density="5"/></body>
  <body name="b" pos="1 0 0.3"><freejoint/><geom name="b" type="sphere" size="0.1" density="5"/></body>
  <body name="c" pos="2 0 0.3"><freejoint/><geom name="c" type="sphere" size="0.1" density="5"/></body>
  <body name="d" pos="3 0 0.3"><freejoint/><geom name="d" type="box" size="0.1 0.1 0.1" density="5"/></body>
  <body name="e" pos="4 0 0.3"><freejoint/><geom name="e" type="sphere" size="0.1" density="5"/>
    <body name="f" pos="0 0 0.3"><geom name="f" type="sphere" size="0.05" mass="0"/></body></body>
</worldbody></mujoco>"""


def test_bad_input_stays_finite():
    """A body of zero mass, one of zero inertia, a geom without material, a massless body
    welded to a moving one (its Hertz mass 0: once a division by zero against any moving
    body), a non-finite mass: every compliance is finite and non-negative, every contact time
    finite and positive, every pulse the kernel makes finite."""
    from mjsound.sim.click_kernels import impact_pulses, pulse_rows_needed
    from mjsound.sim.records import IMPACT
    from mjsound.sim.scene import geom_contact_radius
    from mjsound.synth.bandlimited import PULSE_DTYPE

    m = mujoco.MjModel.from_xml_string(BAD)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    m.body_mass[1] = 0.0  # a: massless (not dynamic)
    m.body_inertia[2] = 0.0  # b: no inertia
    mat = [get_material("aluminium")] * 4 + [None] + [get_material("aluminium")] * 2  # d: no material
    radius = np.array([geom_contact_radius(m, g) for g in range(m.ngeom)])
    p = ImpactPulses(m, mat, radius, 1, [], FS, active=False)
    cm = p._model
    s = cm.geoms["shell_compliance"]
    assert np.all(np.isfinite(s)) and np.all(s >= 0)
    assert s[1] == 0.0 and s[4] == 0.0 and s[6] == 0.0 and s[2] > 0 and s[3] > 0  # b's wall is its mass's
    assert s[5] > 0  # e: its massless child f's surface counts in its own (a thinner wall)
    for g1 in range(m.ngeom):
        for g2 in range(m.ngeom):
            for speed in (0.0, 1e-9, 2.0, 1e9):
                tau = pair_contact_time(cm, g1, g2, speed)
                assert math.isfinite(tau) and TAU_MIN_S <= tau <= TAU_MAX_S
    m.body_mass[3] = np.inf  # c: an infinite mass (after construction: the records keep theirs)
    assert np.all(np.isfinite(shell_compliances(m, mat, radius, p._dynamic)))
    k = 6
    imp = np.zeros(k, IMPACT)
    for i in range(k):
        imp[i]["g1"], imp[i]["g2"] = 0, i % (m.ngeom - 1) + 1  # (the floor and each body)
        imp[i]["normal"] = (0, 0, 1)
        imp[i]["impulse"] = 0.01
        imp[i]["speed"] = 2.0
    rows = np.zeros(pulse_rows_needed(k, 1, 0), PULSE_DTYPE)
    dv = np.zeros(len(rows))
    n = impact_pulses(cm, imp, k, 0.1, d.xpos, d.xmat, np.array([[0.0, 1.0, 0.5]]), rows, dv, 0)
    assert n > 0 and np.all(np.isfinite(dv[:n]))
    for f in ("time_s", "tau_s", "b0", "b1", "d1", "d2"):
        assert np.all(np.isfinite(rows[f][:n])), f


def test_ant_clicks_no_longer_deafen():
    """Gymnasium's Ant-v5 wrapped (aluminium, clicks on), 100 seeded random steps: the loudest
    block peaked at 357 Pa (145 dB, clipping) with solid-Hertz clicks; with its foil-shell
    contact times it peaks at 5.2 Pa (clicks off: 0.82 Pa). The bound leaves 4x."""
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    env = AudioObservation(gym.make("Ant-v5"), sample_rate=FS, progress=False)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    peak = 0.0
    for _ in range(100):
        *_, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        peak = max(peak, info["audio_peak_pa"])
    env.close()
    assert 0.5 < peak < 20.0


def test_light_shell_on_a_heavy_subtree_sinks_no_deeper_than_its_radius():
    """A 1 g aluminium sphere of 10 cm radius (a 3 um wall) carrying a 20 kg child: the wall's
    spring under 20 kg would take seconds (the 1 s clamp: a 65536-point pulse window at
    48 kHz); the mass cannot sink deeper than the radius, ``v tau / pi <= R``: ``pi R / v``."""
    xml = """<mujoco><worldbody><geom name="floor" type="plane" size="2 2 .1"/>
      <body name="shell" pos="0 0 0.5"><freejoint/><geom name="s" type="sphere" size="0.1" mass="0.001"/>
      <body name="heavy"><geom type="box" size="0.05 0.05 0.05" mass="20" contype="0" conaffinity="0"/></body>
      </body></worldbody></mujoco>"""
    p = _pulses(xml, {"s": "aluminium"})
    cm = p._model
    s = cm.geoms[1]["shell_compliance"]
    assert s > 0
    assert shell_contact_time(20.001, s, 0.0) == TAU_MAX_S  # (the spring alone: seconds)
    for v in (0.5, 3.0):
        assert pair_contact_time(cm, 0, 1, v) == pytest.approx(math.pi * 0.1 / v, rel=1e-12)
    # slow enough that the wall's spring ends the contact first: the spring's time (clamped)
    assert pair_contact_time(cm, 0, 1, 1e-3) == TAU_MAX_S
