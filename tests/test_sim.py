"""MuJoCo side: SoundScene, ContactReader, AudioSimulator (issue 4 correctness list).

Scenes are small MJCF strings; modal models are seeded stubs (mjsound.sim.stub) wherever the
analysis itself is not the point, so the whole file runs in seconds.
"""

from __future__ import annotations

import warnings
from fractions import Fraction

import mujoco
import numpy as np
import pytest

from mjsound.materials import get_material
from mjsound.sim.contacts import ContactReader
from mjsound.sim.scene import SoundScene
from mjsound.sim.simulator import AudioSimulator, SampleClock
from mjsound.sim.stub import stub_model

FS = 48000
G = 9.81
# A contact stiffness/damping whose restitution is about 0.6 (steel) at 0.5-2 ms steps.
SOLREF_E06 = "-1e5 -120"


def drop_xml(dt=0.001, h=0.5, plate=False, r=0.02):
    plate_geom = (
        '<geom name="plate" type="box" size="0.15 0.15 0.005" pos="0 0 0.005" solref="%s"/>' % SOLREF_E06
        if plate
        else ""
    )
    z0 = h + r + (0.01 if plate else 0.0)
    return f"""
<mujoco>
  <option timestep="{dt}"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:plate" data="aluminium"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1" solref="{SOLREF_E06}"/>
    {plate_geom}
    <site name="mic0" pos="0.3 -0.5 0.3"/>
    <body name="ball" pos="0 0 {z0}">
      <freejoint/>
      <geom name="ball" type="sphere" size="{r}" solref="{SOLREF_E06}"/>
    </body>
  </worldbody>
</mujoco>"""


def make_sim(xml, models, **kw):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(model, models=models, progress=False, **kw)
    return model, data, AudioSimulator(model, data, scene=scene, sample_rate=FS)


@pytest.fixture(autouse=True)
def no_analysis(monkeypatch):
    """Fail loudly if a test meant to use stubs calls the real modal analysis."""
    import mjsound.modal.analyze as an

    def boom(*a, **k):
        raise AssertionError("analyze() called")

    monkeypatch.setattr(an, "analyze", boom)


# ---------------------------------------------------------------------- impulse
def test_drop_ball_impulse_matches_theory_and_mujoco():
    h = 0.5
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=h), models)
    audio = sim.run(0.45)
    first = sim.impacts[0]
    mass = model.body_mass[1]
    e = get_material("steel").restitution
    theory = mass * (1 + e) * np.sqrt(2 * G * h)
    assert first.geom1 == 0 and first.geom2 == 1
    assert abs(first.impulse_pred - theory) < 0.10 * theory
    assert abs(first.impulse_sim - theory) < 0.10 * theory, (first.impulse_sim, theory)
    assert abs(first.effective_mass - mass) < 0.02 * mass  # ball on ground: m* = m
    assert not first.open
    # one impact event for this contact, not a train
    onsets = [ev for ev in sim.event_log if ev[1] == "impact" and abs(ev[0] - first.time) < 0.02]
    assert len(onsets) == 1
    assert np.isfinite(audio).all() and np.abs(audio).max() > 0


# ---------------------------------------------------------------------- timestep invariance
def third_octave_levels(x, fs, f_lo=100.0, f_hi=16000.0):
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x)))) ** 2
    f = np.fft.rfftfreq(len(x), 1 / fs)
    centres = 1000.0 * 2.0 ** (np.arange(-10, 13) / 3.0)
    centres = centres[(centres >= f_lo) & (centres <= f_hi)]
    out = []
    for fc in centres:
        band = (f >= fc * 2 ** (-1 / 6)) & (f < fc * 2 ** (1 / 6))
        out.append(10 * np.log10(spec[band].sum() + 1e-30))
    return centres, np.array(out)


def plate_impact_sound(dt):
    models = {"plate": stub_model("box:0.3,0.3,0.01", "aluminium", 12, 430.0)}
    model, data, sim = make_sim(drop_xml(dt=dt, h=0.3, plate=True), models, materials={"ball": "silent"})
    audio = sim.run(0.6)[0]
    first = [ev for ev in sim.event_log if ev[1] == "impact"][0]
    n0 = int(first[0] * FS)
    bounce2 = [ev for ev in sim.event_log if ev[1] == "impact" and ev[0] > first[0] + 0.01]
    n1 = int(bounce2[0][0] * FS) if bounce2 else n0 + int(0.25 * FS)
    seg = audio[max(n0 - 48, 0) : n0 - 48 + min(n1 - n0, int(0.2 * FS))]
    return seg, sim


def test_timestep_invariance_third_octaves_and_no_physics_rate_peaks():
    segs = {}
    for dt in (0.0005, 0.001, 0.002):
        seg, sim = plate_impact_sound(dt)
        segs[dt] = seg
    n = min(len(s) for s in segs.values())
    levels = {}
    for dt, seg in segs.items():
        c, L = third_octave_levels(seg[:n], FS)
        levels[dt] = L
    ref = levels[0.001]
    loud = ref > ref.max() - 40.0
    for dt in (0.0005, 0.002):
        diff = np.abs(levels[dt] - ref)[loud]
        assert diff.max() < 3.0, (dt, np.round(levels[dt] - ref, 2))
    # no spectral peaks at multiples of the physics rate (a per-step impulse train would comb)
    modes = stub_model("box:0.3,0.3,0.01", "aluminium", 12, 430.0).frequencies_hz
    for dt, seg in segs.items():
        spec = 20 * np.log10(np.abs(np.fft.rfft(seg[:n] * np.hanning(n))) + 1e-30)
        f = np.fft.rfftfreq(n, 1 / FS)
        rate = 1.0 / dt
        for k in range(1, int(8000 / rate) + 1):
            fk = k * rate
            if np.min(np.abs(modes - fk)) < 150:
                continue
            at = spec[np.abs(f - fk) < 10].max()
            around = np.median(spec[(np.abs(f - fk) < 150)])
            assert at < around + 6.0, (dt, fk)


# ---------------------------------------------------------------------- resting / pushed box
BOX_XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom><text name="mjsound:box" data="oak"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1" friction="0.5"/>
    <body name="box" pos="0 0 0.0305">
      <freejoint/>
      <geom name="box" type="box" size="0.04 0.03 0.03" friction="0.5"/>
    </body>
  </worldbody>
</mujoco>"""


def box_sim():
    return make_sim(BOX_XML, {"box": stub_model("box:0.08,0.06,0.06", "oak", 6, 700.0)})


def test_resting_box_is_silent_after_settling():
    model, data, sim = box_sim()
    audio = sim.run(1.5)[0]
    late = [ev for ev in sim.event_log if ev[0] > 0.3]
    assert late == []
    tail = audio[int(1.0 * FS) :]
    assert np.sqrt(np.mean(tail**2)) < 1e-6 * max(np.abs(audio).max(), 1e-12) or not tail.any()


def test_pushed_box_sounds_only_while_moving():
    model, data, sim = box_sim()
    mass = model.body_mass[1]
    t_push = (0.5, 1.0)

    def push(m, d):
        d.xfrc_applied[1, 0] = 2.0 * 0.5 * mass * G if t_push[0] <= d.time < t_push[1] else 0.0

    speeds = []

    def push_and_log(m, d):
        push(m, d)
        speeds.append((d.time, abs(d.qvel[0])))

    audio = sim.run(2.5, callback=push_and_log)[0]
    speeds = np.array(speeds)
    moving = speeds[speeds[:, 1] > 0.01, 0]
    assert moving.min() >= t_push[0] - 1e-9
    t_stop = moving.max()
    slides = [ev for ev in sim.event_log if ev[1] == "slide"]
    assert slides, "a sliding box must sound"
    ts = np.array([ev[0] for ev in slides])
    assert ts.min() >= t_push[0] - 0.002 and ts.max() <= t_stop + 0.01
    assert not [ev for ev in sim.event_log if 0.3 < ev[0] < t_push[0] - 0.002]
    seg = lambda a, b: audio[int(a * FS) : int(b * FS)]  # noqa: E731
    loud = np.sqrt(np.mean(seg(t_push[0] + 0.1, t_stop - 0.05) ** 2))
    quiet_before = np.sqrt(np.mean(seg(0.35, t_push[0]) ** 2))
    quiet_after = np.sqrt(np.mean(seg(t_stop + 0.6, 2.5) ** 2))
    assert loud > 0
    assert quiet_before < 1e-4 * loud and quiet_after < 1e-4 * loud


# ---------------------------------------------------------------------- scene rules
SCENE_XML = """
<mujoco>
  <asset><material name="Steel"/><material name="paint"/></asset>
  <custom>
    <text name="mjsound:b" data="glass"/>
    <text name="mjsound:c" data="glass"/>
  </custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1" material="Steel"/>
    <body name="A" pos="0 0 1"><freejoint/><geom name="a" type="box" size=".02 .02 .02" material="Steel"/></body>
    <body name="B" pos="0 0 2"><freejoint/><geom name="b" type="sphere" size=".2" material="Steel"/></body>
    <body name="F" pos="0 0 6"><freejoint/><geom name="f" type="sphere" size=".01" material="Steel"/></body>
    <body name="C" pos="0 0 3"><freejoint/><geom name="c" type="capsule" size=".02 .05"/></body>
    <body name="D" pos="0 0 4"><freejoint/><geom name="d" type="cylinder" size=".02 .05" material="paint"/></body>
    <body name="E" pos="0 0 5"><freejoint/><geom name="e" type="box" size=".02 .02 .02" contype="0" conaffinity="0" material="Steel"/></body>
  </worldbody>
</mujoco>"""


def test_scene_materials_precedence_and_silent_geoms(monkeypatch):
    import mjsound.modal.analyze as an

    calls = []

    def fake(mesh, material, **kw):
        calls.append((mesh, material.name))
        return stub_model(mesh if isinstance(mesh, str) else mesh, material, 3, 1000.0)

    monkeypatch.setattr(an, "analyze", fake)
    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    scene = SoundScene.from_model(model, materials={"C": "brass"}, progress=False)
    mats = {s.name: (s.material.name, s.source) for s in scene.sounding}
    assert mats == {
        "a": ("steel", "mjcf-material"),  # MJCF material name, case-insensitive
        "b": ("glass", "custom"),  # custom text beats the MJCF material
        "c": ("brass", "mapping"),  # body-name mapping beats the custom text
    }
    assert sorted(calls) == sorted([("box:0.04,0.04,0.04", "steel"), ("sphere:0.2", "glass"), ("capsule:0.02,0.1", "brass")])
    assert "d" in scene.silent and "no acoustic material" in scene.silent["d"]
    assert "e" in scene.silent and "collide" in scene.silent["e"]
    assert "no audible modes" in scene.silent["f"]  # 1 cm steel ball: rings above 20 kHz
    assert "plane" in scene.silent["floor"]
    assert scene.geom_material[0].name == "steel"  # the floor's material is used for contacts
    # default listener, 1 m from the centre of the sounding geoms
    assert scene.mic_names == ["listener"]
    centre = np.mean([[0, 0, 1], [0, 0, 2], [0, 0, 3]], axis=0)
    assert abs(np.linalg.norm(scene.mic_positions[0] - centre) - 1.0) < 1e-9


def test_budget_is_shared_and_reported(monkeypatch):
    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    models = {
        "a": stub_model("box:0.04,0.04,0.04", "steel", 40, 500.0, ratio=1.05),
        "b": stub_model("sphere:0.02", "glass", 40, 500.0, ratio=1.05),
        "c": stub_model("capsule:0.02,0.1", "glass", 10, 500.0, ratio=1.05),
    }
    scene = SoundScene.from_model(model, models=models, budget_modes=30, progress=False)
    counts = {s.name: s.model.n_modes for s in scene.sounding}
    assert sum(counts.values()) == 30
    assert all(n >= 1 for n in counts.values())
    assert len(scene.budget_notes) >= 2 and "budget" in scene.report()
    for s in scene.sounding:  # the lowest modes are kept
        assert np.allclose(s.model.frequencies_hz, models[s.name].frequencies_hz[: s.model.n_modes])


def test_no_sounding_geoms_runs_silent_without_analysis():
    xml = drop_xml().replace('<custom><text name="mjsound:ball" data="steel"/><text name="mjsound:plate" data="aluminium"/></custom>', "")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    sim = AudioSimulator(model, data, sample_rate=FS, progress=False, clicks=False)  # analyze() would raise
    assert sim.synth is None and sim.scene.sounding == []
    audio = sim.run(0.5)
    assert audio.shape == (1, 24000) and not audio.any()
    # with clicks (the default) the falling ball is heard, still without any analysis
    data = mujoco.MjData(model)
    sim = AudioSimulator(model, data, sample_rate=FS, progress=False)
    assert sim.scene.sounding == [] and sim.synth.objects == []
    assert np.abs(sim.run(0.5)).max() > 0


# ---------------------------------------------------------------------- time alignment
def test_sample_count_exact_over_10000_steps_non_integer_dt_fs():
    dt = 0.0007  # dt * fs = 33.6 samples
    xml = drop_xml(dt=dt)
    model, data, sim = make_sim(xml, {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)})
    total = 0
    fdt, ffs = Fraction(7, 10000), FS
    for k in range(10000):
        mujoco.mj_step(model, data)
        n = sim.step().shape[1]
        # exactly the samples with t_k <= n/fs < t_{k+1}
        lo = -((-k * fdt * ffs).numerator // (k * fdt * ffs).denominator)
        hi = -((-(k + 1) * fdt * ffs).numerator // ((k + 1) * fdt * ffs).denominator)
        assert n == hi - lo
        total += n
    assert total == round(10000 * dt * FS) == 336000


def test_sample_clock_no_drift_over_hours():
    clock = SampleClock(44100, 0.002 / 3)  # dt * fs = 29.4
    k = int(round(3 * 3600 / (0.002 / 3)))  # three hours
    assert clock.sample_at(k) == round(3 * 3600 * 44100)
    c = SampleClock(48000, 0.001)
    total = 0
    for k in range(5000):
        a, b = c.advance()
        assert b - a == 48 and a == 48 * k
        total += b - a
    assert total == 240000
    # a non-integer dt * fs: the blocks alternate so that their sum never drifts
    c = SampleClock(44100, 0.001)
    blocks = [np.subtract(*c.advance()[::-1]) for _ in range(10000)]
    assert set(blocks) == {44, 45} and sum(blocks) == 441000
    # span: the samples of the next steps without counting them, as sample_at gives them
    c = SampleClock(44100, 0.002 / 3, t_start=1.25)
    for steps in (0, 1, 6, 12338):
        c.advance(steps)
        k = c.k
        assert c.span(5) == (k, c.sample_at(k), c.sample_at(k + 5)) and c.k == k


# ---------------------------------------------------------------------- bad input / reader
def test_nan_and_huge_forces_give_finite_audio_and_one_warning():
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.05), models)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        blocks = []
        for k in range(300):
            mujoco.mj_step(model, data)
            if data.ncon:
                data.efc_force[:] = np.nan if k % 2 else 1e30
            blocks.append(sim.step())
    audio = np.concatenate(blocks, axis=1)
    assert np.isfinite(audio).all()
    msgs = [str(w.message) for w in rec if "clamped" in str(w.message)]
    assert len([m for m in msgs if "contact forces" in m]) == 1
    assert sim.reader.n_clamped > 0


def test_massless_welded_striker_sounds_finite():
    """A massless pad welded to a falling stick (subtree mass 0: common on gripper fingers)
    strikes a sounding plate: its Hertz time is the shortest (the combined mass's limit 0), not
    a division by zero; the sound is finite and close to a 1 g pad's."""
    xml = """<mujoco><option timestep="0.001"/>
      <custom><text name="mjsound:plate" data="aluminium"/><text name="mjsound:pad" data="steel"/></custom>
      <worldbody><site name="mic0" pos="0.3 -0.3 0.3"/>
      <body name="plate" pos="0 0 0.02"><geom name="plate" type="box" size="0.2 0.02 0.01" mass="0.5"/></body>
      <body name="stick" pos="0 0 0.3"><freejoint/><geom name="handle" type="capsule" size="0.01 0.05" mass="0.2"/>
      <body name="pad" pos="0 0 -0.07"><geom name="pad" type="sphere" size="0.012" mass="PAD"/></body></body>
      </worldbody></mujoco>"""
    models = {"plate": stub_model("box:0.4,0.04,0.02", "aluminium", 6, 900.0)}
    peaks = []
    for pad in ("0", "0.001"):
        model, data, sim = make_sim(xml.replace("PAD", pad), models)
        assert (model.body_subtreemass[3] == 0.0) == (pad == "0")
        audio = sim.run(0.4)
        assert np.isfinite(audio).all() and sim.reader.n_impacts >= 1
        peaks.append(float(np.abs(audio[0]).max()))
    assert peaks[1] > 0 and 0.5 < peaks[0] / peaks[1] < 2.0


@pytest.mark.parametrize("cone", ["pyramidal", "elliptic"])
def test_reader_normal_force_matches_mj_contactForce(cone):
    xml = BOX_XML.replace('<option timestep="0.001"/>', f'<option timestep="0.001" cone="{cone}"/>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    cf = ContactReader(model).read(data)
    f6 = np.zeros(6)
    ref = []
    for i in range(data.ncon):
        mujoco.mj_contactForce(model, data, i, f6)
        ref.append(f6[0])
    assert cf.n == data.ncon == 4
    assert np.allclose(cf.force_n, ref, rtol=1e-9, atol=1e-12)
    assert abs(cf.force_n.sum() - model.body_mass[1] * G) < 0.01 * model.body_mass[1] * G
    loc = ContactReader.local_points(data, cf)
    assert np.allclose(np.abs(loc[:, 1, 2]), 0.03, atol=1e-3)  # on the box's bottom face


# ---------------------------------------------------------------------- deferred rendering
def _drop_audio(render_block_s, manual=False):
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0),
              "plate": stub_model("box:0.3,0.3,0.01", "aluminium", 8, 800.0)}
    model = mujoco.MjModel.from_xml_string(drop_xml(h=0.3, plate=True))
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(model, models=models, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, sustained=False, render_block_s=render_block_s)
    if not manual:
        return sim.run(0.6), sim
    blocks = []
    for k in range(600):
        mujoco.mj_step(model, data)
        b = sim.step(render=k % 7 == 6)  # a render every 7 steps, then the rest by flush()
        if b is not None:
            blocks.append(b)
    blocks.append(sim.flush())
    return np.concatenate(blocks, axis=1), sim


def test_deferred_rendering_is_bit_identical_for_impacts():
    every_step, sim0 = _drop_audio(0.0)
    batched, sim1 = _drop_audio(0.01)
    manual, sim2 = _drop_audio(0.0, manual=True)
    assert sim0.events["impact"] >= 2 and np.abs(every_step).max() > 0
    assert every_step.shape == batched.shape == manual.shape == (1, round(0.6 * FS))
    np.testing.assert_array_equal(batched, every_step)
    np.testing.assert_array_equal(manual, every_step)
    assert sim2.flush().shape == (1, 0)  # nothing pending after a flush


def test_deferred_rendering_of_sliding_stays_close():
    """Sliding noise is generated at each step either way; only the gains follow the contact
    point once per render instead of every ``sustained_block_s``."""
    def run(block):
        model, data, sim = box_sim()
        sim.render_block_s = block
        mass = model.body_mass[1]

        def push(m, d):
            d.xfrc_applied[1, 0] = 2.0 * 0.5 * mass * G if 0.5 <= d.time < 1.0 else 0.0

        return sim.run(1.5, callback=push)[0]

    a, b = run(0.0), run(0.01)
    assert np.abs(a).max() > 0
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.15 * np.sqrt(np.mean(a**2))


def test_reader_pair_table_grows_and_keeps_every_pair():
    """The reader's pair -> slot table (open addressing, rehashed on growth) maps thousands
    of pairs to distinct, stable slots."""
    from mjsound.sim.pairs import rehash as _rehash
    from mjsound.sim.pairs import slot_of as _slot_of

    rng = np.random.default_rng(0)
    keys = rng.choice(10**9, size=3000, replace=False).astype(np.int64)
    hk, hv = _rehash(np.full(0, -1, np.int64), np.zeros(0, np.int64), 128)
    slots = {}
    n = 0
    for key in keys.tolist():
        if 2 * (n + 1) > len(hk):
            hk, hv = _rehash(hk, hv, 2 * len(hk))
        s, new = _slot_of(hk, hv, key, n)
        assert new and s == n
        slots[key] = s
        n += 1
    for key in keys[::7].tolist():
        s, new = _slot_of(hk, hv, key, n)
        assert not new and s == slots[key]
    assert sorted(slots.values()) == list(range(len(keys)))


def test_follow_moves_the_microphones_with_the_body_at_each_event():
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.3), models)
    offset = np.array([[0.4, -0.2, 0.1]])
    sim.follow(1, offset)
    fixed = sim.synth.microphones
    for _ in range(600):
        mujoco.mj_step(model, data)
        n = sim.events["impact"]
        sim.step()
        if sim.events["impact"] > n:
            break
    assert sim.events["impact"] == 1
    # moved for the impact: where the ball is (plus the offset), not where the site was
    np.testing.assert_allclose(sim.synth.microphones[:1], data.xpos[1] + offset)
    assert np.abs(sim.synth.microphones - fixed).max() > 0.05
    # and its image in the floor (z = 0) with it (mjsound.sim.images)
    np.testing.assert_allclose(sim.synth.microphones[1:], (data.xpos[1] + offset) * [1, 1, -1])


def test_microphone_site_on_a_moving_body_moves_with_it():
    xml = drop_xml(h=0.3).replace('<geom name="ball"', '<site name="mic_ball" pos="0 0.2 0"/><geom name="ball"')
    xml = xml.replace('<site name="mic0" pos="0.3 -0.5 0.3"/>', "")
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(xml, models)
    start = sim.synth.microphones
    for _ in range(600):
        mujoco.mj_step(model, data)
        n = sim.n_impacts
        sim.step()
        if sim.n_impacts > n:
            break
    assert sim.n_impacts == 1
    np.testing.assert_allclose(sim.synth.microphones[:1], data.site_xpos[[0]])  # where the site is at the impact
    np.testing.assert_allclose(sim.synth.microphones[1:], data.site_xpos[[0]] * [1, 1, -1])  # its image in the floor
    assert start[0, 2] - sim.synth.microphones[0, 2] > 0.25


def test_follow_rejects_bad_arguments():
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.3), models)
    with pytest.raises(ValueError, match="one per microphone"):
        sim.follow(1, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="does not exist"):
        sim.follow(99, np.zeros((1, 3)))
    sim.follow(None, None)
    assert sim._follow is None


def test_impact_record_closed_by_a_new_onset_keeps_its_own_sums():
    """A pair struck again while its impact record is still open: the state machine banks the
    old record's sum F dt, steps and end so the reader can close it with its own values."""
    from mjsound.sim.contacts import ImpactRecord
    from mjsound.jit import call_inner
    from mjsound.sim.impulses import write_records
    from mjsound.sim.pairs import update_pairs
    from mjsound.sim.records import pair_scratch

    model = mujoco.MjModel.from_xml_string(drop_xml())
    reader = ContactReader(model)
    key = np.array([1], np.int64)
    zeros = np.zeros(1)

    def step(k, vmax, f):
        reader.counts[0]["step"] = k
        slot, onset, kind, speed = call_inner(update_pairs, reader.state(), key, np.array([vmax]), np.array([f]), zeros, zeros,
                                                0.01 * (k - 1), 0.01 * k, pair_scratch(1)[1])
        return bool(onset[0]), int(slot[0])

    onset, j = step(1, 1.0, 100.0)  # impact
    assert onset
    assert not step(2, 0.5, 50.0)[0]  # still moving: the record stays open
    onset, _ = step(3, 5.0, 300.0)  # sharp rise after the refractory time: a new impact
    pair = reader.state().pairs[j]
    assert onset and pair["open"] == 1
    assert pair["prev_impulse"] == pytest.approx((100.0 + 50.0) * 0.01)
    assert pair["prev_steps"] == 2
    assert pair["prev_end"] == pytest.approx(0.02)
    assert pair["rec_impulse"] == pytest.approx(300.0 * 0.01)  # the new record's own sum
    old = ImpactRecord(time=0.0, geom1=0, geom2=1, speed=1.0, impulse_pred=1.5, impulse_sim=0.0,
                       restitution=0.5, effective_mass=1.0)
    reader._open[j] = old
    buf = reader.buffers
    buf.hits[0]["g1"], buf.hits[0]["g2"] = 0, 1
    buf.onsets[0]["slot"], buf.onsets[0]["first"], buf.onsets[1]["first"] = j, 0, 1
    call_inner(write_records, reader.state(), buf, 1, np.array([[0.5, 5.0, 3.0, 0.0]]), 0.02)
    reader.take_records()
    (new,) = reader.newest_records(1)  # (records are made, and close their slot's last one, when read)
    assert not old.open and old.steps == 2
    assert old.impulse_sim == pytest.approx(1.5) and old.duration == pytest.approx(0.02)
    assert reader._open[j] is new
    assert new.open and (new.time, new.geom1, new.geom2, new.speed, new.impulse_pred) == (0.02, 0, 1, 5.0, 3.0)


def test_impact_records_are_made_when_read_and_keep_only_the_newest():
    """Rows taken in several calls, read once: the same records (and closings) as made one by
    one, only the newest ``keep_records`` kept; an older row still closes its slot's record."""
    from mjsound.sim.records import RECORD

    model = mujoco.MjModel.from_xml_string(drop_xml(h=0.3))

    def rows(*spec):  # (time, g1, g2, slot, clamped, prev_impulse)
        r = np.zeros(len(spec), RECORD)
        for i, (t, g1, g2, slot, clamped, p_imp) in enumerate(spec):
            r[i] = (t, g1, g2, 1.0, 2.0, 0.5, slot, clamped, p_imp, 3, t)
        return r

    reader = ContactReader(model, keep_records=3)
    reader.add_records(rows((0.1, 0, 1, 0, 0, 0.0), (0.2, 0, 2, 1, 0, 0.0)))
    (first,) = reader.newest_records(2)[1:]  # (read: made now)
    with pytest.warns(RuntimeWarning, match="clamped"):
        reader.add_records(rows((0.3, 0, 1, 0, 1, 7.0), (0.4, 0, 1, 0, 0, 8.0)))
    reader.add_records(rows((0.5, 0, 2, 1, 0, 9.0), (0.6, 0, 1, 0, 0, 4.0)))
    assert reader.n_impacts == 6 and reader.n_clamped == 1
    assert reader.newest_geoms(3) == [(0, 1), (0, 2), (0, 1)]
    assert reader.newest_geoms(4) is None
    recs = reader.newest_records(3)
    assert [r.time for r in recs] == [0.6, 0.5, 0.4]
    # the slot-0 record read before is closed by the first later slot-0 row (not kept itself)
    assert not first.open and first.impulse_sim == 7.0 and first.duration == pytest.approx(0.3 - 0.1)
    # the kept 0.4 record closed by the 0.6 row; the newest of each slot open
    assert not recs[2].open and recs[2].impulse_sim == 4.0
    assert recs[0].open and recs[1].open
    assert len(reader.impacts) == 3


def test_impact_records_read_lazily_equal_records_read_every_step():
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    recs = []
    for every_step in (True, False):
        model, data, sim = make_sim(drop_xml(h=0.3), models)
        for _ in range(900):
            mujoco.mj_step(model, data)
            sim.step(render=False)
            if every_step:
                sim.impacts  # noqa: B018 (brings the open records up to date)
        recs.append([(r.time, r.impulse_sim, r.steps, r.duration, r.open) for r in sim.impacts])
    assert len(recs[0]) >= 2 and recs[0] == recs[1]


def test_normal_jacobians_equal_mujoco_mj_jac():
    """The numba contact Jacobians (normal_jacobians) against mj_jac on a tree with free, ball,
    hinge and slide joints and a welded (dof-less) child body."""
    from mjsound.jit import call_inner
    from mjsound.sim.impulses import normal_jacobians
    from mjsound.sim.records import HIT

    xml = """
<mujoco><worldbody>
  <geom type="plane" size="1 1 .1"/>
  <body pos="0 0 1"><freejoint/><geom size=".1"/>
    <body pos=".2 0 0"><joint type="ball"/><geom type="capsule" fromto="0 0 0 .2 0 0" size=".03"/>
      <body pos=".2 0 0"><joint type="hinge" axis="0 1 0"/><geom type="box" size=".05 .02 .02"/>
        <body pos=".1 0 0"><geom type="sphere" size=".02"/>
          <body pos=".05 0 0"><joint type="slide" axis="1 0 0"/><geom type="sphere" size=".01"/></body>
        </body>
      </body>
    </body>
  </body>
</worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    d.qpos[:] = rng.normal(size=m.nq)
    d.qpos[3:7] /= np.linalg.norm(d.qpos[3:7])
    d.qpos[7:11] /= np.linalg.norm(d.qpos[7:11])
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_forward(m, d)
    k = 40
    geom = rng.integers(0, m.ngeom, (k, 2))
    pos = rng.normal(size=(k, 3))
    nrm = rng.normal(size=(k, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    hits = np.zeros(k, HIT)
    hits["g1"], hits["g2"], hits["point"], hits["normal"] = geom[:, 0], geom[:, 1], pos, nrm
    Jn = np.full((k, m.nv), np.nan)
    call_inner(normal_jacobians, ContactReader(m).state(), hits, k, d.cdof, d.subtree_com, Jn)
    ref = np.zeros((k, m.nv))
    J = np.zeros((3, m.nv))
    for r in range(k):
        for side, sign in ((0, -1.0), (1, 1.0)):
            b = int(m.geom_bodyid[geom[r, side]])
            if b:
                mujoco.mj_jac(m, d, J, None, pos[r], b)
                ref[r] += sign * nrm[r] @ J
    assert np.abs(ref).max() > 0.1
    np.testing.assert_allclose(Jn, ref, rtol=0, atol=1e-12)


def test_reader_events_objects_match_the_rows_and_the_simulator():
    """ContactReader.events (objects, a view) shows what events_fast returns, and a reader on
    its own finds the same impacts and sustained contacts as a sounding AudioSimulator's step
    kernel (event log) on a bouncing, then rolling ball."""
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.2), models)
    data.qvel[0] = 0.3  # rolls after the bounces
    slow, fast = (ContactReader(model, restitution=sim.reader.restitution) for _ in range(2))
    n_imp = n_sus = 0
    seen = []
    for _ in range(1200):
        mujoco.mj_step(model, data)
        sim.step(render=False)
        t0 = data.time - model.opt.timestep
        imps, cons, _ = slow.events(data)
        rows_i, rows_s = fast.events_fast(data, t0, data.time)
        got = [] if rows_i is None else rows_i
        assert [(e.geom1, e.geom2) for e in imps] == [(int(r["g1"]), int(r["g2"])) for r in got]
        np.testing.assert_array_equal([e.impulse for e in imps], [r["impulse"] for r in got])
        np.testing.assert_array_equal([e.speed for e in imps], [r["speed"] for r in got])
        sus = [] if rows_s is None else rows_s
        assert [c.kind for c in cons] == ["slide" if r["kind"] == 1 else "roll" for r in sus]
        np.testing.assert_array_equal([c.speed for c in cons], [r["speed"] for r in sus])
        seen += [(pytest.approx(t0, abs=1e-12), "impact", e.geom1, e.geom2, e.impulse) for e in imps]
        seen += [(pytest.approx(t0, abs=1e-12), c.kind, c.geom1, c.geom2, c.speed) for c in cons]
        n_imp += len(imps)
        n_sus += len(cons)
    assert n_imp >= 2 and n_sus > 100
    assert sim.event_log == seen
    assert [(r.time, r.impulse_sim) for r in slow.impacts] == [(r.time, r.impulse_sim) for r in fast.impacts]
    # (the simulator's step times come from its exact clock, the reader's from data.time - dt)
    assert [(pytest.approx(r.time, abs=1e-12), pytest.approx(r.impulse_sim, rel=1e-9)) for r in slow.impacts] == [
        (r.time, r.impulse_sim) for r in sim.impacts]


def test_a_contact_that_slides_then_rolls_keeps_one_stream():
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.05), models)
    data.qvel[0] = 0.5  # lands sliding, friction makes it roll
    audio = sim.run(1.5)
    ev = sim.events
    assert ev["slide"] > 0 and ev["roll"] > 0, ev
    assert sim.synth.n_streams == 1  # (floor, ball, struck geom): one stream
    assert np.isfinite(audio).all() and np.abs(audio).max() > 0


def test_reader_keeps_the_last_keep_records_impacts():
    """``keep_records`` bounds the record list (the oldest drop out), in order; the count of
    impact events stays complete."""
    model = mujoco.MjModel.from_xml_string(drop_xml(h=0.3))
    data = mujoco.MjData(model)
    full, short = ContactReader(model), ContactReader(model, keep_records=2)
    for _ in range(1500):
        mujoco.mj_step(model, data)
        for r in (full, short):
            r.events_fast(data, data.time - model.opt.timestep, data.time)
    assert full.n_impacts >= 3 and short.n_impacts == full.n_impacts
    key = [(r.time, r.impulse_pred, r.impulse_sim, r.open) for r in full.impacts]
    assert [(r.time, r.impulse_pred, r.impulse_sim, r.open) for r in short.impacts] == key[-2:]


def test_impact_records_wait_in_the_kernel_rows_until_read():
    """The step kernel leaves its record rows waiting (no Python per step for them) and counts
    the impacts and those with an audible geom; reading the records takes them; rows that
    would overflow are taken by ``grow`` (none lost)."""
    from mjsound.sim.records import RECORD

    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0),
              "plate": stub_model("box:0.3,0.3,0.01", "aluminium", 4, 900.0)}
    model, data, sim = make_sim(drop_xml(h=0.1, plate=True), models)
    reader = sim.reader
    plate = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate")
    audible = np.zeros(model.ngeom, bool)
    audible[plate] = True  # (only the impacts on the plate are heard)
    reader.set_audible(audible)
    with pytest.raises(ValueError, match="set_audible"):
        reader.set_audible(np.ones(model.ngeom + 1, bool))
    for _ in range(12):
        sim.advance(100, render=False)
    waiting = int(reader.counts[0]["n_records"])
    assert waiting == reader.n_impacts >= 3  # (none taken yet: nobody read them)
    recs = reader.impacts
    assert int(reader.counts[0]["n_records"]) == 0 and len(recs) == waiting
    heard = sum(1 for r in recs if audible[r.geom1] or audible[r.geom2])
    assert reader.n_audible == heard == waiting  # (the ball bounces on the plate only)
    assert sim.n_impacts == reader.n_impacts_made == sum(1 for r in recs if r.impulse_pred > 0)
    # full rows: grow takes them before deciding on room
    buf = reader.buffers
    rcap = len(buf.records)
    buf.records[:] = np.zeros(rcap, RECORD)
    buf.records["g1"], buf.records["g2"], buf.records["slot"] = plate, 0, 0
    reader.counts[0]["n_records"] = rcap
    reader.grow(4)
    assert reader.buffers is buf and int(reader.counts[0]["n_records"]) == 0
    assert reader.n_impacts == waiting + rcap and reader.newest_geoms(1) == [(plate, 0)]


@pytest.mark.parametrize("path", ["step", "substeps"])
def test_an_external_reset_clears_the_ringing(path):
    """``data.time`` going backwards (an environment reset the simulator was not told about):
    the simulator resets itself, so what follows sounds exactly like a fresh simulator from
    that state, and the samples counted before the reset still come out first."""
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=0.1), models)

    def play(m, d, s, n):
        if path == "substeps":
            s.advance(n, render=False)
        else:
            for _ in range(n):
                mujoco.mj_step(m, d)
                s.step(render=False)
        return s.flush()

    before = play(model, data, sim, 400)  # the ball hit the floor: it rings
    assert sim.n_impacts >= 1 and np.abs(before[:, -100:]).max() > 0
    held = play(model, data, sim, 10)[:, :0]  # (nothing held yet)
    pending = sim.clock.n
    if path == "substeps":
        sim.advance(7, render=False)
    else:
        for _ in range(7):
            mujoco.mj_step(model, data)
            sim.step(render=False)
    n_pending = sim.clock.n - pending
    mujoco.mj_resetData(model, data)  # back to t = 0, behind the simulator's back
    data.qpos[2] += 0.05  # (a different start: the ball falls from 0.15 m)
    ref_model, ref_data, ref = make_sim(drop_xml(h=0.1), models)
    ref_data.qpos[:] = data.qpos
    after = play(model, data, sim, 500)
    expect = play(ref_model, ref_data, ref, 500)
    assert held.shape[1] == 0 and after.shape[1] == n_pending + expect.shape[1]
    np.testing.assert_array_equal(after[:, n_pending:], expect)
    assert sim.n_impacts == ref.n_impacts >= 1 and sim.clock.k == ref.clock.k == 500


def test_newest_records_are_the_last_impacts_newest_first():
    """``newest_records(n)``: the reader's last ``n`` impact records, newest first; None when it
    keeps fewer than ``n`` (the wrapper then counts every new impact as heard)."""
    model = mujoco.MjModel.from_xml_string(drop_xml(h=0.3))
    data = mujoco.MjData(model)
    reader = ContactReader(model, keep_records=3)
    for _ in range(1500):
        mujoco.mj_step(model, data)
        reader.events_fast(data, data.time - model.opt.timestep, data.time)
    assert reader.n_impacts >= 3
    kept = reader.impacts
    newest = reader.newest_records(2)
    assert [(r.time, r.geom1, r.geom2) for r in newest] == [(r.time, r.geom1, r.geom2) for r in kept[::-1][:2]]
    assert newest[0].time >= newest[1].time
    assert reader.newest_records(0) == []
    assert reader.newest_records(4) is None


def test_steps_per_render_and_replay_step_match_stepping():
    """``steps_per_render`` is ``round(render_block_s / timestep)`` (at least 1); replaying the
    steps of a run with ``driver.replay`` (times and samples given, the clock unused) gives the
    run's audio sample for sample."""
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    _, _, sim = make_sim(drop_xml(dt=0.002, h=0.1), models)
    assert sim.render_block_s == 0.01 and sim.steps_per_render == 5
    sim.render_block_s = 0.0
    assert sim.steps_per_render == 1
    model, data, sim = make_sim(drop_xml(h=0.1), models)
    states, blocks = [], []
    for _ in range(200):
        states.append((data.qpos.copy(), data.qvel.copy(), data.time))
        mujoco.mj_step(model, data)
        blocks.append(sim.step())
    ref = np.concatenate(blocks, axis=1)
    assert np.abs(ref).max() > 0
    model2, data2, replay = make_sim(drop_xml(h=0.1), models)
    fs, out = replay.sample_rate, []
    for i, (qpos, qvel, t) in enumerate(states):
        data2.qpos[:], data2.qvel[:], data2.time = qpos, qvel, t
        mujoco.mj_step(model2, data2)  # the step's contacts and forces, at the end of the step
        n0, n1 = (int(np.ceil(x * fs - 1e-6)) for x in (t, t + model.opt.timestep))
        out.append(replay.driver.replay(n0, n1, t, t + model.opt.timestep, origin=0))
    assert np.array_equal(np.concatenate(out, axis=1), ref)


def test_contact_frames_keep_their_values_while_the_reader_reads_on():
    """A ContactFrame owns its arrays: the reader's working arrays (StepBuffers.quantities,
    reused every substep) never leak into a frame, so reading later steps, through
    ``read`` or through the step kernel, leaves an earlier frame as it was."""
    from mjsound.sim.contacts import ContactReader as Reader

    model = mujoco.MjModel.from_xml_string(BOX_XML)
    data = mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    reader = Reader(model)
    first = reader.read(data)
    kept = {k: np.array(getattr(first, k), copy=True) for k in ("force_n", "normal", "vel_rel", "v_approach", "v_slip")}
    data.qvel[:2] = (0.3, -0.2)  # (sliding: other quantities, still touching)
    for _ in range(2):
        mujoco.mj_step(model, data)
        reader.events(data)  # (the step kernel's reading, in the reader's own buffers)
        second = reader.read(data)
    assert second is not None and not np.allclose(second.vel_rel, kept["vel_rel"])
    for k, v in kept.items():
        np.testing.assert_array_equal(getattr(first, k), v)
    assert not any(np.shares_memory(getattr(first, k), a) for k in kept for a in reader.buffers.quantities)


def test_an_impact_gives_its_modes_at_most_the_energy_the_collision_takes():
    """A steel ball dropped onto the floor from 0.3 m: the step kernel's impact row carries the
    pair's restitution (steel's 0.6, the floor has none), and the energy bound it gets is the
    energy the collision takes from the approach, m v^2 (1 - e^2) / 2 = |J| v (1 - e) / 2,
    not the impulse's whole work |J| v / 2 (which exceeds even the kinetic energy m v^2 / 2)."""
    from mjsound.jit import call_inner
    from mjsound.sim.drive import impact_sides

    h = 0.3
    models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0)}
    model, data, sim = make_sim(drop_xml(h=h), models)
    impacts = None
    while impacts is None and data.time < 0.5:
        mujoco.mj_step(model, data)
        impacts, _ = sim.reader.events_fast(data)  # (the scene's reader: it knows the materials)
    assert impacts is not None and len(impacts) == 1
    e = get_material("steel").restitution
    m, v = float(model.body_mass[1]), float(np.sqrt(2 * G * h))
    im = impacts[0]
    assert im["restitution"] == pytest.approx(e, rel=1e-12)
    assert im["speed"] == pytest.approx(v, rel=0.02)
    assert im["impulse"] == pytest.approx(m * (1 + e) * im["speed"], rel=0.02)
    obj, P, J, tau, budget, mass, n = call_inner(impact_sides, sim._drive_state(sim.reader.state()), impacts, 1)
    assert n == 1  # (the ball sounds, the floor does not)
    assert budget[0] == pytest.approx(0.5 * im["impulse"] * im["speed"] * (1 - e), rel=1e-12)
    assert budget[0] == pytest.approx(0.5 * m * im["speed"] ** 2 * (1 - e * e), rel=0.02)
