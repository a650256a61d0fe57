"""The floor answers (issue 39): planes reflect as image microphones, rooms add their walls.

Closed forms: a source above a rigid plane is the two-source field (modes and clicks); an
absorbing plane lowers the image by its reflection factor per mode frequency; a shoebox's
image-source energy decay follows Sabine / Eyring; free field is what it was.
"""

import math

import mujoco
import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.sim import AudioSimulator
from mjsound.sim.images import fold, mirror_affine, scene_surfaces
from mjsound.sim.rooms import Room, room_from_text
from mjsound.sim.scene import SoundScene
from mjsound.sim.surfaces import BANDS_HZ, get_surface, reflection_at
from mjsound.synth import accel_noise as an
from mjsound.synth.pulse import contact_time, hertz_coefficient

C = 343.0
FS = 48000
H_SRC, MIC = 0.1, np.array([1.0, 0.0, 0.3])  # the bar's centre above the floor; the microphone
R1 = float(np.linalg.norm(MIC - [0, 0, H_SRC]))
R2 = float(np.linalg.norm(MIC * [1, 1, -1] - [0, 0, H_SRC]))
F_NOTCH = C / (2 * (R2 - R1))  # the first notch of the two-source comb, 2998 Hz

BAR_XML = f"""<mujoco><option timestep="0.001"/>
<worldbody>
  <geom name="floor" type="plane" size="3 3 0.1"/>
  <geom name="bar" type="box" size="0.02 0.02 0.02" pos="0 0 {H_SRC}"/>
  <site name="mic0" pos="{MIC[0]} {MIC[1]} {MIC[2]}"/>
</worldbody></mujoco>"""


def _bar_model(freqs):
    """Modes at ``freqs`` [Hz], all moving the bar's one surface sample along z."""
    n = len(freqs)
    return ModalModel(np.asarray(freqs, float), np.full(n, 8.0), [[0, 0, 0]], [[0, 0, 1]], np.ones((1, 3, n)),
                      np.full(n, 1.0), get_material("steel"), mass_kg=0.5)


def _bar_run(freqs, reflections, dt=0.001, seconds=0.25, te=0.0102):
    """Strike the bar (1 mN s along z at ``te``) and render ``seconds`` in float64."""
    model = mujoco.MjModel.from_xml_string(BAR_XML)
    model.opt.timestep = dt
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(model, materials={"bar": "steel"}, models={"bar": _bar_model(freqs)},
                                  sample_rate=FS, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, reflections=reflections, clicks=False,
                         synth_kwargs={"dtype": "float64", "cull_db": None})
    sim.synth.impact("bar", [0, 0, H_SRC], [0, 0, 1e-3], te, pulse_s=0.0)
    out = sim.run(seconds)
    return sim, out[0].astype(np.float64)


def _two_source(sim, t, te, gains):
    """Mode by mode ``w G / w_d e^{-d tau} sin(w_d tau) / r`` at the microphone (r = R1) plus
    ``gains[k]`` times the same from the mirror image (r = R2)."""
    om = sim.synth.object_modes("bar")
    out = np.zeros_like(t)
    for k in range(len(om.decay)):
        for r, g in ((R1, 1.0), (R2, gains[k])):
            tau = t - te - r / C
            q = 1e-3 * om.shapes[0, 2, k] / om.damped_omega[k] * np.exp(-om.decay[k] * tau) \
                * np.sin(om.damped_omega[k] * tau)
            out += g * np.where(tau >= 0, om.weights[k] * q / r, 0.0)
    return out


# ---------------------------------------------------------------- planes
def test_mirror_affine_mirrors_across_the_plane():
    A = mirror_affine([0, 0, 2.0], [5.0, -1.0, 0.25])
    x = np.array([0.3, 0.4, 1.0])
    assert np.allclose(A[:, :3] @ x + A[:, 3], [0.3, 0.4, -0.5])
    n = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    B = mirror_affine(n, [1.0, 0.0, 0.0])
    y = B[:, :3] @ x + B[:, 3]
    assert np.dot(x - [1, 0, 0], n) == pytest.approx(-np.dot(y - [1, 0, 0], n))  # same distance, other side
    assert np.allclose(B[:, :3] @ (B[:, :3] @ x + B[:, 3]) + B[:, 3], x)  # a mirror twice is the identity
    with pytest.raises(ValueError, match="normal"):
        mirror_affine([0, 0, 0], [0, 0, 0])


def test_source_above_a_rigid_plane_is_the_two_source_closed_form():
    """Modes at, around and between the comb's notches: the rendered pressure is the direct
    path plus the mirror image's, sample for sample (float64: within 1e-6 of the peak); the
    mode at the notch frequency c / (2 delta) is 30 dB below the one at the next peak."""
    freqs = F_NOTCH * np.array([0.5, 0.9, 0.99, 1.0, 1.01, 1.1, 2.0])
    te = 0.0102
    sim, p = _bar_run(freqs, {"floor": "rigid"}, te=te)
    assert len(sim.images) == 1 and sim.synth.n_channels == 2 and p.ndim == 1
    assert np.allclose(sim.synth.microphones[1], MIC * [1, 1, -1])
    t = np.arange(p.size) / FS
    ref = _two_source(sim, t, te, np.ones(len(freqs)))
    assert np.abs(p - ref).max() < 1e-6 * np.abs(ref).max()
    # the comb itself: each mode alone, its level relative to free field
    levels = []
    for f in (F_NOTCH, 2 * F_NOTCH):
        _, on = _bar_run([f], {"floor": "rigid"}, te=te)
        _, off = _bar_run([f], False, te=te)
        late = t > te + R2 / C + 0.002  # (both paths arrived)
        levels.append(20 * math.log10(np.abs(on[late]).max() / np.abs(off[late]).max()))
    depth = 20 * math.log10((1 / R1 - 1 / R2) / (1 / R1 + 1 / R2))  # closed form: -31.3 dB
    assert levels[0] - levels[1] == pytest.approx(depth, abs=0.3)
    assert levels[1] == pytest.approx(20 * math.log10(1 + R1 / R2), abs=0.05)  # (+5.8 dB at the peak)


def test_the_image_hears_the_pattern_in_its_own_direction():
    """A vertical dipole (each mode ``sqrt(3) cos(theta)``, the directivity of
    ``ModalModel.radiation_pattern``) above a rigid floor: the direct path is heard with the
    pattern toward the microphone, the reflection with the pattern toward the image microphone
    (below the floor: the other sign of cos(theta)), each exactly."""
    from tests.test_directivity import SQ3, dipole_z
    from tests.test_directivity import model as pattern_model

    freqs = (700.0, 2300.0)
    te = 0.0102
    out = {}
    for pattern in (True, False):
        model = mujoco.MjModel.from_xml_string(BAR_XML)
        data = mujoco.MjData(model)
        bar = pattern_model(dipole_z([1.0, 1.0]) if pattern else None, f=freqs, d=(8.0, 8.0), rad=(1.0, 1.0))
        scene = SoundScene.from_model(model, materials={"bar": "steel"}, models={"bar": bar}, sample_rate=FS,
                                      progress=False)
        sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, reflections={"floor": "rigid"}, clicks=False,
                             synth_kwargs={"dtype": "float64", "cull_db": None})
        sim.synth.impact("bar", [0, 0, H_SRC], [0, 0, 1e-3], te, pulse_s=0.0)
        out[pattern] = (sim, sim.run(0.2)[0].astype(np.float64))
    sim, p = out[True]
    iso_sim = out[False][0]
    t = np.arange(p.size) / FS
    src = np.array([0, 0, H_SRC])
    cos1 = (MIC - src)[2] / R1
    cos2 = (MIC * [1, 1, -1] - src)[2] / R2
    assert cos1 > 0 > cos2
    direct = _two_source(iso_sim, t, te, np.zeros(2))  # (the isotropic closed form, direct path only)
    both = _two_source(iso_sim, t, te, np.ones(2))
    ref = SQ3 * cos1 * direct + SQ3 * cos2 * (both - direct)
    assert np.abs(p - ref).max() < 1e-6 * np.abs(ref).max()


def test_absorbing_plane_lowers_each_mode_by_its_reflection_factor():
    """Carpet: modes at band centres and between get sqrt(1 - alpha(f)) on the image, alpha
    interpolated in log frequency (at 4 kHz: -4.6 dB against a rigid floor)."""
    freqs = np.array([125.0, 700.0, 1000.0, 4000.0, 9000.0])
    te = 0.0102
    sim, p = _bar_run(freqs, {"floor": "carpet"}, te=te)
    carpet = get_surface("carpet")
    gains = reflection_at(carpet.reflection, freqs)
    assert gains[0] == pytest.approx(math.sqrt(1 - 0.02)) and gains[3] == pytest.approx(math.sqrt(1 - 0.65))
    assert gains[4] == gains[3]  # constant above the last band
    t = np.arange(p.size) / FS
    ref = _two_source(sim, t, te, gains)
    assert np.abs(p - ref).max() < 1e-6 * np.abs(ref).max()
    # the image alone of the 4 kHz mode: 4.56 dB below a rigid floor's
    _, rigid = _bar_run([4000.0], {"floor": "rigid"}, te=te)
    _, soft = _bar_run([4000.0], {"floor": "carpet"}, te=te)
    _, free = _bar_run([4000.0], False, te=te)
    drop = 20 * math.log10(np.abs(soft - free).max() / np.abs(rigid - free).max())
    assert drop == pytest.approx(10 * math.log10(1 - 0.65), abs=1e-6)


def test_reflections_follow_the_timestep_and_keep_sample_counts():
    freqs = [300.0, 2500.0]
    _, a = _bar_run(freqs, True, dt=0.001, seconds=0.2)
    _, b = _bar_run(freqs, True, dt=0.0007, seconds=0.2)
    n = round(0.2 * FS)
    assert a.size == n and b.size == round(round(0.2 / 0.0007) * 0.0007 * FS)
    k = min(a.size, b.size)
    assert np.abs(a[:k] - b[:k]).max() < 1e-9 * np.abs(a).max()


def test_free_field_option_is_the_sound_without_planes():
    """reflections=False, or every plane turned off, renders with the air microphones only
    (no image rows at all): the same arrays as before reflections existed."""
    sim_a, a = _bar_run([440.0, 3000.0], False)
    sim_b, b = _bar_run([440.0, 3000.0], {"floor": None})
    assert len(sim_a.images) == 0 and len(sim_b.images) == 0 and sim_a.synth.n_channels == 1
    assert np.array_equal(a, b)
    _, on = _bar_run([440.0, 3000.0], True)  # (a concrete floor: the image is there)
    assert np.abs(on - a).max() > 0.5 * np.abs(a).max()


def test_plane_surfaces_from_options_text_and_material():
    xml = """<mujoco><custom><text name="mjsound-surface:rug" data="carpet"/></custom><worldbody>
      <geom name="floor" type="plane" size="1 1 .1"/><geom name="rug" type="plane" size="1 1 .1" pos="0 0 .5"/>
      <geom name="wall" type="plane" size="1 1 .1" zaxis="1 0 0" pos="-1 0 0"/>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    mats = [None, None, get_material("oak")]
    s = scene_surfaces(model, mats, True)
    assert sorted(s) == [0, 1, 2]
    assert s[0].name == "concrete" and s[1].name == "carpet" and s[2].name == "wood"
    s = scene_surfaces(model, mats, {"floor": 0.5, "wall": None})
    assert sorted(s) == [0, 1] and s[0].absorption == (0.5,) * 6
    assert scene_surfaces(model, mats, False) == {}
    with pytest.raises(ValueError, match="not a plane"):
        scene_surfaces(model, mats, {"table": "carpet"})
    with pytest.raises(ValueError, match="unknown surface"):
        scene_surfaces(model, mats, {"floor": "velvet"})
    with pytest.raises(ValueError, match=r"\[0, 1\)"):
        get_surface(1.0)


def test_fold_adds_each_image_into_its_microphone():
    """The image rows carry their reflection already (the synthesizer's modes get ``R(f)``,
    the clicks' images join their microphone's pulse): the fold is a plain sum."""
    from mjsound.sim.images import ImageSet

    block = np.arange(5 * 4, dtype=np.float32).reshape(5, 4)  # 2 air, 2 images, 1 contact
    im = ImageSet(np.array([1, 0]), np.zeros((2, 3, 4)), np.ones((2, 6)), np.array([0.5, 0.25]), ["a", "b"])
    out = fold(block.copy(), 2, im)
    assert out.shape == (3, 4) and out.dtype == np.float32
    assert np.array_equal(out[0], block[0] + block[3])
    assert np.array_equal(out[1], block[1] + block[2])
    assert np.array_equal(out[2], block[4])



@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_fold_kernel_is_the_plain_sum_image_by_image(dtype):
    """fold_rows (one call per block) against the plain numpy sums, bit for bit: a room's
    images (several per microphone, in order), factors rounded to the block's dtype, and the
    contact rows moved up."""
    from mjsound.sim.images import ImageSet

    rng = np.random.default_rng(3)
    n_air, parent, n_contact = 2, np.array([0, 1, 0, 0, 1]), 2
    gains = rng.uniform(0.2, 1.0, parent.size)
    block = rng.standard_normal((n_air + parent.size + n_contact, 48)).astype(dtype)
    ref, plain = block.copy(), block.copy()
    for i, p in enumerate(parent):
        ref[p] += ref[n_air + i] * dtype(gains[i])
        plain[p] += plain[n_air + i]
    ref = np.concatenate([ref[:n_air], ref[n_air + parent.size:]])
    plain = np.concatenate([plain[:n_air], plain[n_air + parent.size:]])
    im = ImageSet(parent, np.zeros((parent.size, 3, 4)), np.ones((parent.size, 6)), gains, list("abcde"))
    out = fold(block.copy(), n_air, im)  # (the image rows as they are: their modes carry R(f))
    assert out.dtype == dtype and out.shape == ref.shape
    assert np.array_equal(out, plain)
    given = fold(block.copy(), n_air, im, gains=gains)  # (the factors given)
    assert np.array_equal(given, ref)
    assert np.array_equal(given[1], block[1] + block[3] * dtype(gains[1]) + block[6] * dtype(gains[4]))

# ---------------------------------------------------------------- clicks
BALL_XML = """<mujoco><option timestep="0.001"/>
<custom><text name="mjsound:ball" data="steel"/></custom>
<worldbody>
  <geom name="floor" type="plane" size="2 2 0.1"/>
  <site name="mic0" pos="0 0 1.01"/>
  <body name="ball" pos="0 0 0.11"><freejoint/><geom name="ball" type="sphere" size="0.01" density="7850"/></body>
</worldbody></mujoco>"""


def _ball(reflections, fs):
    m = mujoco.MjModel.from_xml_string(BALL_XML)
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, sample_rate=fs, quality="draft", progress=False, reflections=reflections)
    return sim, sim.run(0.2)[0].astype(np.float64)


@pytest.mark.filterwarnings("ignore:mjsound.*ring")
def test_steel_ball_on_a_rigid_floor_clicks_with_its_image():
    """The issue's 20 mm steel ball dropped 10 cm, microphone 1 m above: free field is the
    rigid-sphere closed form at the microphone; with the floor it is that plus the closed form
    at the image microphone (a vertical dipole's image points the other way: cos = -1), and an absorbing floor scales the image
    click by the 4 kHz band's reflection factor."""
    from tests.test_clicks import FS as CLICK_FS
    from tests.test_clicks import _hankel_click

    sim, free = _ball(False, CLICK_FS)
    _, rigid = _ball({"floor": "rigid"}, CLICK_FS)
    _, carpet = _ball({"floor": "carpet"}, CLICK_FS)
    (rec,) = sim.impacts
    mass = float(sim.model.body_mass[1])
    dv = rec.impulse_pred / mass
    tau = contact_time(hertz_coefficient(mass, 0.01, get_material("steel"), None), rec.speed)
    t = np.arange(free.size) / CLICK_FS - rec.time
    near = np.abs(t - 1.0 / an.SPEED_OF_SOUND) < 0.003
    # (a 50 us click at 16 kHz: each closed form is compared at the sub-sample time that fits
    # best, within a sample of the step's time; the image's must trail the direct one's by
    # the path difference 2 z / c, z the ball's centre above the floor at the impact: 1 cm,
    # less up to 1.5 mm of MuJoCo's contact squeeze)
    def best(signal, r, cos_t):
        fit = (np.inf, 0.0, None)
        for grid in (np.linspace(-1.0, 1.0, 11), np.linspace(-0.1, 0.1, 9)):  # (samples: coarse, then fine)
            for shift in (fit[1] + grid / CLICK_FS):
                ref = _hankel_click(dv, tau, 0.01, r, cos_t, t[near] - shift)
                fit = min(fit, (np.abs(signal[near] - ref).max(), shift, ref), key=lambda f: f[0])
        return fit

    want = float(np.abs(free).max())
    err, shift, direct = best(free, 1.0, 1.0)
    assert err < 0.05 * want
    err, shift_image, image = best(rigid - free, 1.02, -1.0)
    z = 0.01 + (shift_image - shift) * an.SPEED_OF_SOUND / 2
    assert 0.0085 < z < 0.0105
    assert np.abs(rigid[near] - (direct + image)).max() < 0.05 * want
    r_click = get_surface("carpet").click_reflection
    assert np.allclose(carpet - free, r_click * (rigid - free), atol=1e-5 * want)


# ---------------------------------------------------------------- rooms
def test_room_images_are_the_shoebox_lattice():
    room = Room(lo=(-2, -1, 0), hi=(3, 2, 2.5), walls={"walls": "plaster", "floor": "carpet"}, order=2)
    mic = np.array([[0.5, 0.2, 1.2]])
    im = room.images(mic)
    assert len(im) == 24 and len(Room((0, 0, 0), (1, 1, 1), order=3).images([[.5, .5, .5]])) == 62
    pos = im.positions(mic)
    lab = {k: i for i, k in enumerate(im.labels)}
    assert np.allclose(pos[lab["room(0, 0, -1)"]], [0.5, 0.2, -1.2])  # the floor's mirror
    assert np.allclose(pos[lab["room(1, 0, 0)"]], [5.5, 0.2, 1.2])  # x+ at 3: 2*3 - 0.5
    assert np.allclose(pos[lab["room(-2, 0, 0)"]], [-9.5, 0.2, 1.2])  # two walls: x - 2 L
    assert np.allclose(pos[lab["room(0, 0, 2)"]], [0.5, 0.2, 6.2])
    Rp, Rc = get_surface("plaster").reflection, get_surface("carpet").reflection
    assert np.allclose(im.reflection[lab["room(0, 0, -1)"]], Rc)
    assert np.allclose(im.reflection[lab["room(0, 0, 2)"]], Rc * Rp)  # floor and ceiling once each
    assert np.allclose(im.reflection[lab["room(1, 1, 0)"]], Rp * Rp)
    with pytest.raises(ValueError, match="outside the room"):
        room.images([[5.0, 0, 1]])
    with pytest.raises(ValueError, match="wall"):
        Room((0, 0, 0), (1, 1, 1), walls={"roof": "carpet"})
    r = room_from_text("lo=-2 -1 0; hi=3 2 2.5; walls=plaster; floor=carpet; order=2")
    assert np.allclose(r.images(mic).positions(mic), pos)
    assert Room((0, 0, 0), (5, 4, 3), rt60=0.5).rt60("eyring") == pytest.approx(np.full(6, 0.5))


def test_room_renders_each_image_through_its_walls():
    """A first-order room around the bar without its late tail: the rendered pressure is the
    direct path plus the six wall images, each with its walls' reflection at each mode's
    frequency."""
    freqs = np.array([500.0, 2000.0])
    room = Room(lo=(-2, -1.5, 0), hi=(2.5, 1.5, 2.4), walls={"walls": "brick", "floor": "wood"}, order=1,
                tail=False)  # (the images alone: the tail is tests/test_room_tail.py's)
    model = mujoco.MjModel.from_xml_string(BAR_XML)
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(model, materials={"bar": "steel"}, models={"bar": _bar_model(freqs)},
                                  sample_rate=FS, progress=False)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS, room=room, clicks=False,
                         synth_kwargs={"dtype": "float64", "cull_db": None})
    te = 0.0051
    sim.synth.impact("bar", [0, 0, H_SRC], [0, 0, 1e-3], te, pulse_s=0.0)
    p = sim.run(0.15)[0].astype(np.float64)
    om = sim.synth.object_modes("bar")
    t = np.arange(p.size) / FS
    src = np.array([0, 0, H_SRC])
    paths = [(float(np.linalg.norm(MIC - src)), np.ones(len(freqs)))]
    for x, refl in zip(sim.images.positions([MIC]), sim.images.reflection):
        paths.append((float(np.linalg.norm(x - src)), reflection_at(refl, freqs)))
    ref = np.zeros_like(t)
    for k in range(len(freqs)):
        for r, g in paths:
            tau = t - te - r / C
            q = 1e-3 / om.damped_omega[k] * np.exp(-om.decay[k] * tau) * np.sin(om.damped_omega[k] * tau)
            ref += g[k] * np.where(tau >= 0, om.weights[k] * q / r, 0.0)
    assert len(sim.images) == 6
    assert np.abs(p - ref).max() < 1e-6 * np.abs(ref).max()


def _lattice(room, mic, order):
    """Every image of ``mic`` up to ``order`` (vectorised; the rooms' formula): positions
    (k, 3) and the log of the wall product per wall crossing count, (k, 6) crossings."""
    L, lo = room.size, room.lo
    n = np.arange(-order, order + 1)
    grid = np.stack([g.ravel() for g in np.meshgrid(n, n, n, indexing="ij")], axis=1)
    grid = grid[(np.abs(grid).sum(axis=1) >= 1) & (np.abs(grid).sum(axis=1) <= order)]
    pos = np.zeros(grid.shape, float)
    hits = np.zeros((len(grid), 6))
    for ax in range(3):
        k = grid[:, ax]
        pos[:, ax] = np.where(k % 2 == 0, mic[ax] + k * L[ax], 2 * lo[ax] + (k + 1) * L[ax] - mic[ax])
        hits[:, 2 * ax + 1] = np.where(k > 0, (k + 1) // 2, (-k) // 2)  # the high wall
        hits[:, 2 * ax] = np.where(k > 0, k // 2, (-k + 1) // 2)  # the low wall
    return pos, hits


def _schroeder_t(room, src, mic, order, band=3, lo_db=-5.0, hi_db=-25.0):
    """Decay time [s] of the image sources' energy response (direct sound and images up to
    ``order``; Schroeder's backward integral, its slope from ``lo_db`` to ``hi_db`` extrapolated
    to 60 dB) at octave band ``band``; and the time up to which the lattice is complete."""
    pos, hits = _lattice(room, mic, order)
    R = np.array([s.reflection[band] for s in room.surfaces])
    d2 = np.concatenate([[np.sum((mic - src) ** 2)], np.sum((pos - src) ** 2, axis=1)])
    g2 = np.concatenate([[1.0], np.prod(R ** (2 * hits), axis=1)])
    t = np.sqrt(d2) / C
    t_max = (order + 1) * room.size.min() / C  # (every image arriving before this has order <= order)
    keep = t < t_max
    t, e = t[keep], (g2 / d2)[keep]
    i = np.argsort(t)
    t, e = t[i], e[i]
    edc = 10 * np.log10(np.cumsum(e[::-1])[::-1] / e.sum())
    a, b = np.searchsorted(-edc, -lo_db), np.searchsorted(-edc, -hi_db)
    slope = np.polyfit(t[a:b], edc[a:b], 1)[0]
    return -60.0 / slope, t_max, t[b]


def test_shoebox_image_sources_decay_at_the_sabine_rate():
    """The image lattice the rooms are made of (their positions and wall products, checked
    against Room.images at order 3) decays, summed to order 70, at the rate Sabine predicts
    for the box: T20 within 10 % (measured 2.5 % longer; Eyring's is 7 % shorter still)."""
    walls = {"walls": 0.12, "floor": 0.2}
    room3 = Room(lo=(0, 0, 0), hi=(3.2, 2.6, 2.2), walls=walls, order=3)
    src, mic = np.array([1.1, 0.9, 0.7]), np.array([2.3, 1.7, 1.4])
    ours = room3.images([mic])
    pos, hits = _lattice(room3, mic, 3)
    mine, theirs = np.lexsort(np.round(pos, 9).T), np.lexsort(np.round(ours.positions([mic]), 9).T)
    assert len(pos) == len(ours) == 62
    assert np.allclose(pos[mine], ours.positions([mic])[theirs])
    R = np.array([s.reflection for s in room3.surfaces])
    assert np.allclose(np.prod(R[None] ** hits[:, :, None], axis=1)[mine], ours.reflection[theirs])
    room = Room(lo=(0, 0, 0), hi=(3.2, 2.6, 2.2), walls=0.12)  # (uniform: a diffuse enough field)
    T, t_max, t_end = _schroeder_t(room, src, mic, order=70)
    assert t_end < 0.6 * t_max  # (the fitted range ends well before the lattice does)
    assert T == pytest.approx(room.rt60("sabine")[3], rel=0.10)
    assert T > 0.95 * room.rt60("eyring")[3]


def test_the_gymnasium_wrapper_takes_the_option():
    """AudioObservation (and dm_control's AudioEnvironment, through the same EnvAudio) passes
    ``reflections``: by default its following listener has an image in the floor that moves
    with it; ``reflections=False`` is the free field."""
    from mjsound.sim.stub import stub_model
    from mjsound.wrappers import AudioObservation
    from tests.test_wrappers import _HandSteppedEnv

    out = {}
    for refl in (True, False):
        inner = _HandSteppedEnv()
        env = AudioObservation(inner, materials={"box": "steel"}, substeps="manual", sample_rate=16000,
                               window_s=0.01, reflections=refl,
                               models={"box": stub_model("box:0.3,0.3,0.01", "steel", 8, 400.0)})
        inner.on_substep = env.on_substep
        env.reset(seed=0)
        out[refl] = np.concatenate([env.step(np.zeros(1))[0]["audio"] for _ in range(30)], axis=-1)
        n_img = len(env.sim.images)
        mics = env.sim.synth.microphones
        if refl:
            assert n_img == 1 and np.allclose(mics[1], mics[0] * [1, 1, -1])
        else:
            assert n_img == 0 and len(mics) == 1
    assert np.abs(out[True]).max() > 0 and not np.allclose(out[True], out[False])
