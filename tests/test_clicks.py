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
from mjsound.synth.pulse import TAU_MAX_S, TAU_MIN_S, contact_time, effective, hertz_coefficient

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
    sim = AudioSimulator(m, d, sample_rate=FS, quality="draft", progress=False, clicks=clicks,
                         reflections=False)  # (the free-field closed form; the floor's echo: test_rooms)
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
    # the documented level (docs/clicks.md): 3.0 Pa, 103.5 dB SPL peak at 0.58 m, 43 degrees off the vertical
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


def _reference_pulses(p, impacts, time_s, data, mics):
    """The pulses of ``ImpactPulses.add`` in plain numpy (rows, dv): the per-impact code that
    :func:`mjsound.sim.click_kernels.impact_pulses` replaced."""
    from mjsound.synth.contact_mic import site_pulse

    model = p.model
    g12 = np.stack([impacts["g1"], impacts["g2"]], axis=1).astype(np.int64)
    imp, nrm, pts, spd = impacts["impulse"], impacts["normal"], impacts["point"], impacts["speed"]
    ok = np.isfinite(imp) & (imp > 0) & np.isfinite(spd) & np.all(np.isfinite(nrm), axis=1) \
        & np.all(np.isfinite(pts), axis=1)
    groups = {}
    for i in np.flatnonzero(ok).tolist():
        groups.setdefault((int(g12[i, 0]), int(g12[i, 1])), []).append(i)
    recs, dvs = [], []
    for (g1, g2), sel in groups.items():
        w = imp[sel]
        J2 = (w[:, None] * nrm[sel]).sum(axis=0)
        point = (w[:, None] * pts[sel]).sum(axis=0) / w.sum()
        speed = float(spd[sel].max())
        mat1, mat2 = p._mat[g1], p._mat[g2]
        if mat1 is None and mat2 is None:
            mat1 = mat2 = get_material("abs")
        known = [m.restitution for m in (p._mat[g1], p._mat[g2]) if m is not None]
        e = math.sqrt(known[0] * known[1]) if len(known) == 2 else (known[0] if known else 0.5)
        b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
        coef = hertz_coefficient(effective(p._hertz_mass[b1], p._hertz_mass[b2]),
                                 effective(p._radius[g1], p._radius[g2]), mat1, mat2)
        tau = float(contact_time(coef, speed))
        shell = p._model.geoms["shell_compliance"][g1] + p._model.geoms["shell_compliance"][g2]
        if shell > 0:  # a thin hollow shell: the mass on the walls' springs, when longer
            mass = effective(p._hertz_mass[b1], p._hertz_mass[b2])
            # (no deeper than the smaller shell's radius: v tau / pi <= R)
            gm = p._model.geoms
            r = min(gm["radius"][g] for g in (g1, g2) if gm["shell_compliance"][g] > 0)
            crush = math.pi * r / speed if speed > 0 and math.isfinite(r) else math.inf
            tau = max(tau, min(min(max(math.pi * math.sqrt(mass * shell), TAU_MIN_S), TAU_MAX_S), crush))
        for g, J in ((g2, J2), (g1, -J2)):
            b = int(model.geom_bodyid[g])
            if not p._dynamic[b]:
                continue
            R = np.asarray(data.xmat[b]).reshape(3, 3)
            com = np.asarray(data.xpos[b]) + R @ model.body_ipos[b]
            Ri = R @ p._iframe[b]
            cap = (1.0 + e) * speed  # (no velocity change beyond what the approach allows)
            dv = J / p._mass[b]
            dv_norm = float(np.linalg.norm(dv))
            if dv_norm > cap > 0:
                dv *= cap / dv_norm
                dv_norm = cap
            if p.clicks and p.n_air and dv_norm > 0:
                recs.append(an.dipole_pulses(com, Ri, p._masses[b], p._a_eq[b], dv / dv_norm, mics, time_s, tau, p.c))
                dvs.append(np.full(len(mics), dv_norm))
            sites = np.flatnonzero(p._site_body == b)
            if not len(sites):
                continue
            inertia = np.asarray(model.body_inertia[b], dtype=np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                dw = Ri @ np.where(inertia > 0, (Ri.T @ np.cross(point - com, J)) / inertia, 0.0)
            for k in sites.tolist():
                s = p.contact_sites[k]
                site = np.asarray(data.xpos[b]) + R @ model.site_pos[s]
                axis = R @ p._site_frame[k][:, 2]
                spin = np.cross(dw, site - com)
                spin_norm = float(np.linalg.norm(spin))
                if spin_norm > cap > 0:
                    spin *= cap / spin_norm
                dv_site = float((dv + spin) @ axis)
                if dv_site != 0.0:
                    recs.append(site_pulse(time_s, tau, p.n_air + k))
                    dvs.append(np.array([dv_site]))
    return np.concatenate(recs), np.concatenate(dvs)


@pytest.mark.parametrize("clicks,hollow", [(True, False), (False, False), (True, True)])
def test_impact_pulses_kernel_equals_the_numpy_reference(clicks, hollow):
    """Grouping by pair (order of first appearance), impulse-weighted point, capped dv and
    spin, clicks at two air microphones and both contact microphones: the numba kernel's pulse
    rows against the numpy code it replaced, on tilted, spinning bodies (``hollow``: the
    aluminium plate a hundredth of its solid mass, a thin shell whose contact time is its
    wall's)."""
    from mjsound.sim.click_kernels import impact_pulses, pulse_rows_needed
    from mjsound.sim.clicks import ImpactPulses
    from mjsound.sim.records import IMPACT
    from mjsound.synth.bandlimited import PULSE_DTYPE

    m = mujoco.MjModel.from_xml_string(XML)
    if hollow:
        plate = m.body("plate").id
        m.body_mass[plate] *= 0.01
        m.body_subtreemass[plate] *= 0.01
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    for j in range(2):  # tilted free bodies
        q = rng.normal(size=4)
        d.qpos[7 * j + 3: 7 * j + 7] = q / np.linalg.norm(q)
    mujoco.mj_kinematics(m, d)
    sites = contact_mic_sites(m, None)
    mat = [None, None, get_material("aluminium")]  # (floor-block: neither has a material)
    p = ImpactPulses(m, mat, np.array([np.inf, 0.03, 0.1]), 2, sites, FS, clicks=clicks)
    assert (p._model.geoms["shell_compliance"] > 0).tolist() == [False, False, hollow]
    k = 12
    imp = np.zeros(k, IMPACT)
    pairs = [(0, 1), (1, 2), (0, 2), (0, 1)]
    for i in range(k):
        imp[i]["g1"], imp[i]["g2"] = pairs[rng.integers(0, len(pairs))]
        n = rng.normal(size=3)
        imp[i]["normal"] = n / np.linalg.norm(n)
        imp[i]["point"] = rng.normal(size=3) * 0.05
        imp[i]["impulse"] = rng.uniform(0.0, 0.5) * (1 if i % 5 else 40)  # some capped
        imp[i]["speed"] = rng.uniform(0.05, 2.0)
    imp[3]["impulse"] = -0.1  # left out: not a push
    imp[7]["normal"][0] = np.nan  # left out: not finite
    mics = np.array([[0.3, -0.3, 0.4], [-1.0, 0.5, 0.2]])
    rows = np.zeros(pulse_rows_needed(k, 2, len(sites)), PULSE_DTYPE)
    dv = np.zeros(len(rows))
    n = impact_pulses(p._model, imp, k, 0.125, d.xpos, d.xmat, mics, rows, dv, 0)
    ref_rows, ref_dv = _reference_pulses(p, imp, 0.125, d, mics)
    assert n == len(ref_rows) >= (12 if clicks else 4)  # (3 pairs; two bodies with contact microphones)
    np.testing.assert_array_equal(rows["channel"][:n], ref_rows["channel"])
    for f in ("time_s", "tau_s", "b0", "b1", "d1", "d2"):
        np.testing.assert_allclose(rows[f][:n], ref_rows[f], rtol=1e-12, atol=1e-300, err_msg=f)
    np.testing.assert_allclose(dv[:n], ref_dv, rtol=1e-12, atol=1e-15)
