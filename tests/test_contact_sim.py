"""Clicks and contact microphones through the simulator: channel order, what each channel
hears and what it must not, the synthesizer's contact channel against the closed form."""

import math

import mujoco
import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.sim import AudioSimulator
from mjsound.synth import contact_mic as cm
from mjsound.synth.synthesizer import Synthesizer

FS = 16000


def _model_with_modes():
    rng = np.random.default_rng(7)
    pts = rng.uniform(-0.05, 0.05, (12, 3))
    nrm = np.tile([0, 0, 1.0], (12, 1))
    shapes = rng.standard_normal((12, 3, 4))
    return ModalModel([700.0, 1900.0, 3100.0, 5200.0], [6.0, 11.0, 25.0, 40.0], pts, nrm, shapes, np.ones(4),
                      get_material("aluminium"), mass_kg=0.5)


def test_synth_contact_channel_matches_closed_form_and_hears_only_its_object():
    model = _model_with_modes()
    syn = Synthesizer(FS, microphones=[[0.0, 0.0, 1.0]], dtype="float64")
    syn.add_object("a", model)
    syn.add_object("b", model, position=[1.0, 0.0, 0.0])
    site, axis = model.points[3], [0.0, 0.6, 0.8]
    ch = syn.add_contact_microphone("a", site, axis)
    assert ch == 1 and syn.n_channels == 2
    hit, J, tau, t0 = model.points[5], np.array([0.0, 0.01, 0.02]), 1e-4, 0.01013
    syn.impact("a", hit, J, t0, pulse_s=tau)
    syn.impact("b", np.asarray(hit) + [1.0, 0.0, 0.0], J, t0, pulse_s=tau)  # another object: not heard
    out = syn.render(1600)
    t = np.arange(1600) / FS - t0
    want = cm.modal_site_acceleration(model, site, axis, hit, J, tau, t)
    assert np.abs(out[1] - want).max() < 1e-6 * np.abs(want).max()
    # the air channel hears both objects, the contact channel only "a"
    syn2 = Synthesizer(FS, microphones=[[0.0, 0.0, 1.0]], dtype="float64")
    syn2.add_object("a", model)
    syn2.add_object("b", model, position=[1.0, 0.0, 0.0])
    syn2.add_contact_microphone("a", site, axis)
    syn2.impact("a", hit, J, t0, pulse_s=tau)
    assert np.array_equal(syn2.render(1600)[1], out[1])
    with pytest.raises(ValueError, match="unknown object"):
        syn.add_contact_microphone("nope", site, axis)


def test_synth_contact_channel_hears_its_objects_forcing_only():
    model = _model_with_modes()
    syn = Synthesizer(FS, microphones=[[0.0, 0.0, 1.0]])
    syn.add_object("a", model)
    syn.add_object("b", model, position=[1.0, 0.0, 0.0])
    syn.add_contact_microphone("a", model.points[2], [0.0, 0.0, 1.0])
    syn.slide("b", [1.0, 0.0, 0.0], [0, 0, 1.0], 5.0, 0.5, 0.0, 0.05)
    out = syn.render(800)
    assert np.abs(out[0]).max() > 0 and not out[1].any()  # b's slide: in the air only
    syn.slide("a", model.points[4], [0, 0, 1.0], 5.0, 0.5, 0.05, 0.1)
    out = syn.render(800)
    assert np.abs(out[1]).max() > 0  # a's slide: in a's contact channel
    with pytest.raises(ValueError, match="contact microphones"):
        syn.set_microphones([[0.0, 0.0, 1.0]])


XML = """<mujoco><option timestep="0.001"/>
<custom>{custom}</custom>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1" friction="{mu}"/>
  <site name="mic0" pos="0.3 -0.3 0.4"/>
  <body name="block" pos="{block}"><freejoint/>
    <geom name="block" type="box" size="0.025 0.025 0.025" density="1050" friction="{mu}"/>
    <site name="contact_mic_block" pos="0 0 0.025"/>
  </body>
  <body name="plate" pos="0.5 0 0.005"><freejoint/>
    <geom name="plate" type="box" size="0.1 0.08 0.005" density="2700" friction="{mu}"/>
    <site name="contact_mic_plate" pos="0.03 0.02 0.005"/>
  </body>
</worldbody></mujoco>"""


def _sim(block=(0, 0, 0.125), vel=None, custom="", mu=1.0, seconds=0.4, **kw):
    m = mujoco.MjModel.from_xml_string(XML.format(block=" ".join(map(str, block)), custom=custom, mu=mu))
    d = mujoco.MjData(m)
    if vel is not None:
        d.qvel[:3] = vel
    sim = AudioSimulator(m, d, sample_rate=FS, progress=False, quality="draft", **kw)
    return sim, sim.run(seconds)


def test_channel_order_and_block_on_silent_floor_clicks():
    sim, x = _sim()
    assert sim.channel_names == ["mic0", "contact_mic_block", "contact_mic_plate"]
    assert list(sim.contact_channels) == [1, 2]
    peak = float(np.abs(x[0]).max())
    assert 20 * math.log10(peak / 2e-5) > 80  # a 5 cm block on a silent floor is heard (docs/clicks.md)
    assert np.abs(x[1]).max() > 100.0  # its own sensor feels the landing [m/s^2]
    assert not x[2].any()  # the plate was not touched
    quiet, y = _sim(clicks=False, contact_mics=[])
    assert quiet.channel_names == ["mic0"] and not y.any()  # no material anywhere: silent without clicks
    named, _ = _sim(contact_mics=["contact_mic_plate"], seconds=0.01)
    assert named.channel_names == ["mic0", "contact_mic_plate"]
    with pytest.raises(ValueError, match="not in the model"):
        _sim(contact_mics=["contact_mic_nowhere"], seconds=0.0)


MATS = '<text name="mjsound:block" data="abs"/><text name="mjsound:plate" data="aluminium"/>' \
       '<text name="mjsound:floor" data="concrete"/>'


def test_resting_and_sliding_add_no_clicks():
    resting = {"block": (0, 0, 0.025)}
    sliding = {"block": (0.42, 0, 0.035), "vel": [0.5, 0, 0], "mu": 0.2}  # along the plate, 6 cm
    for kw in (resting, sliding):
        sim, on = _sim(custom=MATS, contact_mics=[], **kw)
        assert sim.events["impact"] == 0
        _, off = _sim(custom=MATS, contact_mics=[], clicks=False, **kw)
        assert np.array_equal(on, off)
    assert sim.events["slide"] > 100 and np.abs(on).max() > 1e-4  # (the slide itself is heard)


def test_contact_mic_hears_own_impact_not_one_elsewhere():
    # the block lands on the plate: both sensors hear it
    sim, x = _sim(block=(0.5, 0, 0.14), custom=MATS)
    own = float(np.abs(x[2]).max())
    assert own > 100.0
    # the block lands on the floor beside the plate: the plate's sensor stays below -40 dB
    sim, y = _sim(block=(0.0, 0, 0.14), custom=MATS)
    assert np.abs(y[0]).max() > 0 and np.abs(y[1]).max() > 0
    assert np.abs(y[2]).max() < 0.01 * own


def test_object_slid_along_a_body_is_heard_by_its_contact_mic():
    sim, x = _sim(block=(0.42, 0, 0.035), vel=[0.5, 0, 0], custom=MATS, mu=0.2, seconds=0.2)
    assert sim.events["slide"] > 0
    late = x[2, int(0.05 * FS):]  # after the set-down
    assert np.sqrt(np.mean(late**2)) > 0.1  # m/s^2 of scraping in the plate
    rest, y = _sim(block=(0.42, 0, 0.035), custom=MATS, mu=0.2, seconds=0.2)
    assert np.sqrt(np.mean(y[2, int(0.05 * FS):] ** 2)) < 0.01 * np.sqrt(np.mean(late**2))


def test_sonify_writes_contact_channels_at_their_full_scale(tmp_path):
    import soundfile as sf

    from mjsound.sim.rollout import sonify

    scene = tmp_path / "drop.xml"
    scene.write_text(XML.format(block="0.5 0 0.14", custom=MATS, mu=1.0))
    out = tmp_path / "take.wav"
    s = sonify(scene, duration=0.3, sample_rate=FS, out=out, quality="draft", progress=False,
               contact_mics=["contact_mic_plate"], contact_full_scale=5000.0)
    assert s["channel_names"] == ["mic0", "contact_mic_plate"] and s["channels"] == 2
    audio = s["audio"]
    wav, fs = sf.read(out, dtype="float64")
    assert fs == FS and wav.shape == (audio.shape[1], 2)
    assert np.allclose(wav[:, 0], audio[0] / 20.0, atol=1e-6)  # 20 Pa -> 1
    assert np.allclose(wav[:, 1], np.clip(audio[1] / 5000.0, -1, 1), atol=1e-6)  # 5000 m/s^2 -> 1
    assert np.abs(audio[1]).max() > 100.0 and s["peak_pa"] == pytest.approx(float(np.abs(audio[0]).max()))


def test_pinv_psd_matches_numpy_pinv_on_contact_space_inertias():
    """The step kernel's pseudo-inverse (Jacobi, no LAPACK) against numpy's SVD one, on
    symmetric positive semi-definite matrices of full and deficient rank (several contacts
    of one body: ``A = Jn M^-1 Jn^T`` has rank at most its dofs), and near-duplicates."""
    from mjsound.jit import call_inner
    from mjsound.sim.impulses import pinv_psd

    rng = np.random.default_rng(7)
    for k in range(1, 9):
        for trial in range(40):
            B = rng.standard_normal((k, int(rng.integers(1, k + 1)))) * rng.uniform(0.1, 10.0)
            S = B @ B.T + (1e-9 * np.eye(k) if trial % 3 == 0 else 0.0)
            ref = np.linalg.pinv(S, 1e-4)
            np.testing.assert_allclose(call_inner(pinv_psd, S, 1e-4), ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    assert np.all(call_inner(pinv_psd, np.zeros((3, 3)), 1e-4) == 0.0)  # (nothing invertible)
