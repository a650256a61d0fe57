"""The struck object's modes coupled to the contact (mjsound.synth.contact_coupling): against a
converged integration of the same equations, energy within the collision's, the closed form
kept where the modes do not push back, and the per-step path giving the modes what the coupled
contact gives (not the whole energy the collision loses)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mjsound.synth.contact_coupling import coupled_response
from mjsound.synth.pulse import half_sine_spectrum


def reference(g, lam, tau, mass, periods=40.0):
    """Converged integration (DOP853, rtol 1e-10) of the module docstring's equations at unit
    approach speed up to ``periods`` contact times: each mode's complex amplitude referenced to
    the impact's start per unit impulse (the closed form's ``g S / w`` plus the coupling's
    ``delta``), the modes' energy and the rigid bodies' kinetic energy at the end."""
    n = len(g)
    hertz = 1.25 * mass / (tau / 2.9432) ** 2.5  # (Hertz's contact time tau at unit speed)
    d, w, w0sq = -lam.real, lam.imag, np.abs(lam) ** 2

    def rhs(t, s):
        y, yd, q, qd = s[0], s[1], s[2:2 + n], s[2 + n:]
        gap = y - g @ q
        f = hertz * gap**1.5 if gap > 0 else 0.0
        return np.concatenate([[yd, -f / mass], qd, g * f - 2 * d * qd - w0sq * q])

    T = periods * tau
    sol = solve_ivp(rhs, (0, T), np.r_[0.0, 1.0, np.zeros(2 * n)], method="DOP853", rtol=1e-10, atol=1e-14,
                    max_step=tau / 400)
    s = sol.y[:, -1]
    q, qd = s[2:2 + n], s[2 + n:]
    amp = ((qd + d * q) / w + 1j * q) * np.exp(-lam * T) / (2 * mass)
    return amp, 0.5 * np.sum(qd**2 + w0sq * q**2), 0.5 * mass * s[1] ** 2


def modes(n, f_lo, f_hi, coupling, seed=0):
    rng = np.random.default_rng(seed)
    f = np.geomspace(f_lo, f_hi, n)
    lam = -(2.0 + 1e-8 * (2 * np.pi * f) ** 2) + 2j * np.pi * f  # (aluminium-like Rayleigh damping)
    return rng.normal(size=n) * coupling, lam


def coupled(g, lam, tau, mass, resolution=1.0):
    """:func:`coupled_response`'s amplitudes referred to the contact's start (as
    :func:`reference` gives them) and its steps."""
    out = np.zeros(len(g), np.complex128)
    steps, end = coupled_response(g, lam, tau, mass, out, resolution)
    return out * np.exp(-lam * end), steps


def energy(amp, lam, impulse):
    """The modes' energy [J] of amplitudes ``amp`` per unit impulse, for the impulse [N s]."""
    return 0.5 * float(np.sum(np.abs(amp * impulse * lam.imag) ** 2))


def test_nothing_is_integrated_without_coupling_contact_time_or_mass():
    """(The caller then keeps the half sine's closed form.)"""
    out = np.full(3, 1.0 + 1.0j)
    assert coupled_response(np.zeros(3), np.array([-1 + 1e3j, -1 + 2e3j, -1 + 5e3j]), 3e-4, 2.0, out) == (0, 0.0)
    assert np.all(out == 0)
    g, lam = modes(3, 500.0, 5000.0, 0.3)
    for tau, mass in ((0.0, 2.0), (3e-4, 0.0), (3e-4, np.inf), (np.nan, 2.0)):  # no contact time or mass: none
        assert coupled_response(g, lam, tau, mass, out) == (0, 0.0) and np.all(out == 0)
    with pytest.raises(ValueError, match="one entry per mode"):
        coupled_response(g, lam, 3e-4, 2.0, np.zeros(2, np.complex128))


@pytest.mark.parametrize("n, coupling, mass", [(1, 0.3, 4.0), (10, 0.5, 4.0), (27, 0.25, 6.6), (3, 1.5, 0.08)])
def test_coupled_contact_matches_a_converged_integration(n, coupling, mass):
    """Walker- and HalfCheetah-like limbs (m* sum g^2 from 0.4 to 14: modes 0.5 to 7 kHz, a
    0.5 ms contact), and a light gripper struck hard (SO-101's: 0.08 kg): every mode's complex
    amplitude within 2 % of the largest, the modes' energy within 3 %."""
    g, lam = modes(n, 230.0 if n > 20 else 800.0, 7000.0, coupling, seed=n)
    tau = 5e-4
    amp, steps = coupled(g, lam, tau, mass)
    ref, e_ref, _ = reference(g, lam, tau, mass)
    assert 0 < steps <= 4096
    assert np.abs(amp - ref).max() < 0.02 * np.abs(ref).max()
    assert energy(amp, lam, 1.0) == pytest.approx(energy(ref, lam, 1.0), rel=0.03)
    finer, _ = coupled(g, lam, tau, mass, resolution=4.0)  # (the step is converged)
    assert np.abs(finer - amp).max() < 0.01 * np.abs(ref).max()


def test_the_modes_never_take_more_than_the_collision_has():
    """A point whose modes are light against the collision's mass (m* sum g^2 = 12): the
    prescribed half sine asks for 9 times the collision's kinetic energy; coupled, the modes and
    the rebound share it (energy conserved to 2 % with the modes' damping), the modes a fraction."""
    g, lam = modes(30, 800.0, 7000.0, 0.4, seed=3)
    tau, mass = 5e-4, 4.0
    kinetic = 0.5 * mass  # (unit approach speed; the elastic impulse is 2 m*)
    one_way = energy(g * half_sine_spectrum(lam.imag, tau) / lam.imag, lam, 2 * mass)
    amp, _ = coupled(g, lam, tau, mass)
    e_modes = energy(amp, lam, 2 * mass)
    _, e_ref, rebound = reference(g, lam, tau, mass)
    assert one_way > 5 * kinetic
    assert e_modes < 0.5 * kinetic
    assert e_ref + rebound == pytest.approx(kinetic, rel=0.02)


def test_weakly_coupled_modes_hear_hertz_s_pulse():
    """m* sum g^2 = 1e-6: each mode hears the rigid bodies' Hertz force, the half sine's
    impulse below w tau = 1 (within 0.3 %), and its own shape above (Hertz's pulse, of the same
    length, is more peaked: 1.1 to 1.9 times the half sine's spectrum at w tau = 4 to 15)."""
    f = np.array([50.0, 200.0, 400.0, 1600.0, 3000.0, 6000.0])
    lam = -2.0 + 2j * np.pi * f
    g = np.full(len(f), 1e-3)
    tau = 4e-4
    amp, _ = coupled(g, lam, tau, 1.0)
    ref, _, _ = reference(g, lam, tau, 1.0)
    closed = g * half_sine_spectrum(lam.imag, tau) / lam.imag
    ratio = np.abs(amp) / np.abs(closed)
    assert np.all(np.abs(ratio[lam.imag * tau < 1] - 1) < 3e-3)
    assert np.all((ratio[3:] > 1.05) & (ratio[3:] < 2.0))
    assert np.abs(amp - ref).max() < 0.01 * np.abs(ref).max()


def test_synthesizer_impact_with_an_effective_mass_is_coupled():
    """``Synthesizer.impact(effective_mass_kg=...)`` renders the coupled amplitudes; a mass
    that is not positive is refused, naming the argument."""
    from mjsound import ModalModel, get_material
    from mjsound.synth.synthesizer import Synthesizer

    f, d = np.array([600.0, 1500.0, 3300.0]), np.array([2.0, 3.0, 4.0])
    shapes = np.zeros((1, 3, 3))  # (point, xyz, mode): one point, every mode along z
    shapes[0, 2] = [0.5, -0.7, 0.4]
    model = ModalModel(f, d, [[0, 0, 0]], [[0, 0, 1]], shapes, [1.0, 1.0, 1.0], get_material("aluminium"), mass_kg=2.0)
    fs, tau, J, mass = 48000, 5e-4, 3.0, 5.0

    def render(**kw):
        syn = Synthesizer(fs, microphones=[[0, 0, 1.0]], dtype="float64", cull_db=None)
        syn.add_object("o", model)
        syn.impact("o", [0, 0, 0], [0, 0, J], 0.0, pulse_s=tau, **kw)
        return syn.render(fs // 10)[0]

    lam = -d + 1j * np.sqrt((2 * np.pi * f) ** 2 - d**2)
    ring = np.zeros(3, np.complex128)
    _, end = coupled_response(shapes[0, 2], lam, tau, mass, ring)
    t = np.arange(fs // 10) / fs - 1.0 / 343.0 - end  # (the modes ring from the contact's end)
    want = np.where(t >= 0, np.imag((J * ring)[:, None] * np.exp(lam[:, None] * t)).sum(0), 0.0)
    got = render(effective_mass_kg=mass)
    assert np.abs(got - want).max() < 1e-6 * np.abs(want).max()
    assert np.abs(got).max() < 0.8 * np.abs(render()).max()  # (the half sine alone: louder)
    with pytest.raises(ValueError, match="effective_mass_kg"):
        render(effective_mass_kg=0.0)


XML = """
<mujoco>
  <option timestep="0.0005"/>
  <custom><text name="mjsound:bar" data="aluminium"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <body name="bar" pos="0 0 0.52">
      <freejoint/>
      <geom name="bar" type="box" size="0.2 0.03 0.02" density="2700"/>
    </body>
  </worldbody>
</mujoco>"""


def test_a_heavy_bar_dropped_flat_rings_with_what_the_coupled_contact_gives():
    """A 3 kg bar dropped flat from 0.5 m (3.1 m/s) whose struck points are light in its low
    modes (a stub model: m* sum g^2 of several): the prescribed half sine would ask for more
    than the collision loses, and the energy bound then gave the modes all of it. Coupled, the
    modes queued for the impact hold the coupled contact's energy, a small part of the loss."""
    from mjsound.jit import call_inner
    from mjsound.sim.contacts import ContactReader
    from mjsound.sim.drive import impact_sides
    from mjsound.sim.scene import SoundScene
    from mjsound.sim.simulator import AudioSimulator
    from mjsound.sim.stub import stub_model

    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    models = {"bar": stub_model("box:0.4,0.06,0.04", "aluminium", 24, 300.0, ratio=1.15)}
    scene = SoundScene.from_model(model, models=models, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=16000, clicks=False, reflections=False)
    restitution = [m.restitution if m is not None else None for m in scene.geom_material]
    rows = ContactReader(model, restitution=restitution)  # (the same contacts, read beside the simulator)
    impacts = None
    while impacts is None and data.time < 0.6:
        mujoco.mj_step(model, data)
        sim.step(render=False)  # (queues the impact's modes; nothing rendered yet)
        impacts, _ = rows.events_fast(data)
    assert impacts is not None
    drive = sim._drive_state(sim.reader.state())
    obj, P, J, tau, budget, mass, n = call_inner(impact_sides, drive, impacts, len(impacts))
    e = impacts["restitution"][0]
    assert np.all(mass == pytest.approx(np.abs(impacts["impulse"]) / ((1 + e) * impacts["speed"]), rel=1e-12))
    # the modes each impact row asks for with the half sine alone, against its budget
    st = sim.synth.kernel_state()
    ob = st.objects
    o = int(obj[0])
    m0, m1 = ob.mode_off[o], ob.mode_off[o + 1]
    wd, lam = ob.wd[m0:m1], ob.lam[m0:m1]
    from mjsound.synth.streams import nearest_sorted

    one_way, want = 0.0, 0.0
    ring = np.zeros(m1 - m0, np.complex128)
    for i in range(n):
        pl = (P[i] - st.pos[o]) @ st.R[o]
        jl = J[i] @ st.R[o]
        p0, p1 = ob.pts_off[o], ob.pts_off[o + 1]
        b = call_inner(nearest_sorted, ob.pts[p0:p1], ob.pts_index[p0:p1], ob.pts_axis[o], *pl)
        sh = ob.shk[ob.shk_off[o] + 3 * b * (m1 - m0):][:3 * (m1 - m0)].reshape(3, m1 - m0)
        G = jl @ sh
        one_way += energy(G * half_sine_spectrum(wd, tau[i]) / wd, lam, 1.0)
        coupled_response(G / np.linalg.norm(jl), lam, tau[i], mass[i], ring)
        want += energy(ring, lam, np.linalg.norm(jl))  # (at the contact's end)
    assert one_way > budget[:n].sum()  # (before: the bound gave the modes the whole loss)
    q = sim.synth.kernel_state().queue
    queued = 0.0
    for e_row in q.events[: q.counts[0]["count"]]:
        if e_row["obj"] != o or e_row["mic"] != 0:
            continue
        rows_of = slice(e_row["offset"], e_row["offset"] + e_row["width"])
        a = q.re[rows_of] + 1j * q.im[rows_of]
        r = np.linalg.norm(sim.synth.kernel_state().mics[0] - st.pos[o])
        queued += energy(a * r / ob.w[m0:m1], lam, 1.0)
    assert queued == pytest.approx(want, rel=0.02)
    assert queued < 0.8 * budget[:n].sum()  # (before: exactly the budget)
