"""A room's late reverberant tail (issue 39): the feedback delay network decays at the room's
reverberation time per octave band, carries the statistical late energy, renders the same
samples for any block split, and is off bit for bit when turned off."""

import math

import mujoco
import numpy as np
import pytest
from scipy import signal

from mjsound import ModalModel, get_material
from mjsound.sim import AudioSimulator
from mjsound.sim.room_tail import late_energy_rate
from mjsound.sim.rooms import Room, room_from_text
from mjsound.sim.scene import SoundScene
from mjsound.jit import call_inner
from mjsound.synth import reverb
from mjsound.synth.reverb import LateTail, cascade_db, fit_graphic_eq

BANDS = np.array([125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0])
FS = 16000
C = 343.0


def _band_energy(p, band, fs):
    """``p`` through an octave band filter (4th-order Butterworth, forwards and back), squared."""
    sos = signal.butter(4, [band / math.sqrt(2), min(band * math.sqrt(2), 0.49 * fs)], "bandpass", fs=fs, output="sos")
    return signal.sosfiltfilt(sos, p) ** 2


def _decay_time(e, fs, lo_db, hi_db):
    """Schroeder's backward integral of the energy ``e``, its slope from ``lo_db`` to ``hi_db``
    (least squares) extrapolated to 60 dB [s] (ISO 3382: T20 is -5 .. -25, T30 -5 .. -35)."""
    edc = np.cumsum(e[::-1])[::-1]
    level = 10 * np.log10(edc / edc[0])
    a, b = np.argmax(level < lo_db), np.argmax(level < hi_db)
    t = np.arange(e.size) / fs
    return -60.0 / np.polyfit(t[a:b], level[a:b], 1)[0]


# ---------------------------------------------------------------- the network
def test_graphic_eq_has_its_gains_at_the_band_centres():
    target = np.array([-0.3, -1.2, -0.8, -2.5, -4.0, -3.1])
    for fs in (16000, 48000):
        g, sos = fit_graphic_eq(BANDS, target, fs)
        assert np.allclose(20 * math.log10(g) + cascade_db(sos, BANDS, fs), target, atol=1e-6)
    g, sos = fit_graphic_eq(BANDS, target, 8000)  # (4 kHz is Nyquist: left out, flat shelf)
    assert np.allclose((20 * math.log10(g) + cascade_db(sos, BANDS, 8000))[:5], target[:5], atol=1e-6)


def test_the_mixing_is_the_normalised_hadamard_matrix():
    v = np.random.default_rng(1).standard_normal(reverb.N_LINES)
    w = v.copy()
    call_inner(reverb._hadamard_in_place, w)
    assert np.allclose(w, reverb._hadamard(reverb.N_LINES) @ v)
    assert np.allclose(reverb._hadamard(8) @ reverb._hadamard(8).T, 8 * np.eye(8))  # (H / sqrt(8): orthogonal)


def test_an_impulse_decays_at_each_bands_rt60_with_the_stated_energy():
    """One send row's unit impulse: every octave band's T30 within 10 % of its rt60 (a
    frequency-dependent set, 0.35 .. 1.1 s); with the same rt60 in every band, the output's
    energy per sample is ``impulse_energy() exp(-n / (fs tau))`` (mean over 0.1 .. 0.5 s within 10 %);
    the rows that are not outputs are left alone."""
    rt60 = np.array([1.1, 0.9, 0.7, 0.55, 0.45, 0.35])
    tail = LateTail(FS, BANDS, rt60, np.ones(6), [1.0, 1.0], 0.012, ([0], [1.0]), [2, 3], [1.0, 1.0])
    n = int(1.6 * FS)
    block = np.zeros((4, n))
    block[2, 0] = 1.0
    before = block[2:].copy()
    tail.apply(block)
    assert np.array_equal(block[2:], before)
    for band, t in zip(BANDS, rt60):
        assert _decay_time(_band_energy(block[0], band, FS), FS, -5, -35) == pytest.approx(t, rel=0.10)
    flat = LateTail(FS, BANDS, np.full(6, 0.6), np.ones(6), [1.0], 0.012, ([0], [1.0]), [1], [1.0])
    block = np.zeros((2, n))
    block[1, 0] = 1.0
    flat.apply(block)
    tau = 0.6 / (6 * math.log(10))
    k = np.arange(int(0.1 * FS), int(0.5 * FS))
    level = np.mean(block[0, k] ** 2 * np.exp(k / (FS * tau)))
    assert level == pytest.approx(flat.impulse_energy()[0], rel=0.10)
    assert np.corrcoef(*LateTail(FS, BANDS, np.full(6, 0.6), np.ones(6), [1.0, 1.0], 0.012, ([0], [1.0]), [2],
                                 [1.0]).apply(np.vstack([np.zeros((2, n)), block[1:]]))[:2])[0, 1] < 0.1  # (uncorrelated outputs)


def test_every_line_loses_energy_at_every_frequency():
    """The lines' filters stay below 0 dB between and beyond the band centres (the network is
    stable) for decays from 0.1 s to an hour, and a long impulse response does not grow."""
    grid = np.concatenate([[0.0], np.geomspace(10.0, FS / 2, 2000)])
    for rt60 in ([0.1, 0.2, 0.1, 0.3, 0.1, 0.2], [7.0, 4.1, 2.2, 0.95, 0.6, 0.5], [3600.0] * 6,
                 [3600, 0.05, 3600, 0.05, 3600, 0.05]):  # (the first and last: no room's, a fit's limits)
        tail = LateTail(FS, BANDS, rt60, np.ones(6), [1.0], 0.01, ([0], [1.0]), [1], [1.0])
        p = tail.plan
        for i in range(reverb.N_LINES):
            assert 20 * math.log10(p.line_g[i]) + cascade_db(p.line_eq[:, :, i], grid, FS).max() < 0
    block = np.zeros((2, 20 * FS))
    block[1, 0] = 1.0
    tail.apply(block)
    second = np.abs(block[0]).reshape(20, FS).max(axis=1)
    assert np.all(np.isfinite(block)) and second[-1] < 1.01 * second[1:].max() and second[-1] > 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_any_split_into_blocks_renders_the_same_samples(dtype):
    rng = np.random.default_rng(7)
    n = 3000
    src = np.zeros((5, n), dtype)
    src[2:] = rng.standard_normal((3, n)).astype(dtype) * (rng.uniform(size=(3, n)) < 0.01)

    def render(cuts):
        tail = LateTail(FS, BANDS, [0.8, 0.7, 0.6, 0.5, 0.4, 0.3], np.full(6, 2.0), [1.0, 0.5], 0.004,
                        ([0, 17, 90], [1.0, 0.5, 0.25]), [2, 3, 4], [1.0, 0.7, 0.3])
        out = src.copy()
        for a, b in zip(cuts[:-1], cuts[1:]):
            out[:, a:b] = tail.apply(np.ascontiguousarray(out[:, a:b]))
        return out

    whole = render([0, n])
    assert np.abs(whole[:2]).max() > 0
    for cuts in ([0, 1, 2, 48, 1000, n], list(range(0, n, 16)) + [n], sorted({0, n, *rng.integers(0, n, 40)})):
        assert np.array_equal(render(cuts), whole)


def test_bad_reverberation_times_and_gains_are_refused():
    ok = dict(fs=FS, bands_hz=BANDS, rt60=np.full(6, 0.5), band_gain=np.ones(6), out_scale=[1.0], mean_delay=0.01,
              taps=([0], [1.0]), send_row=[1], send_weight=[1.0])
    for bad in (np.zeros(6), np.full(6, -0.5), np.full(6, np.nan), [0.5] * 5):
        with pytest.raises(ValueError, match="rt60"):
            LateTail(**{**ok, "rt60": bad})
    with pytest.raises(ValueError, match="band_gain"):
        LateTail(**{**ok, "band_gain": [1, 1, 0, 1, 1, 1]})
    with pytest.raises(ValueError, match="send_row"):
        LateTail(**{**ok, "send_row": [-1]})
    with pytest.raises(ValueError, match="rows"):
        LateTail(**{**ok, "send_row": [3]}).apply(np.zeros((2, 10)))  # (no row 3 in the block)
    for bad in (0.0, -1.0, float("nan"), "long"):
        with pytest.raises(ValueError, match="rt60"):
            Room((0, 0, 0), (5, 4, 3), rt60=bad)
    with pytest.raises(ValueError, match="tail"):
        Room((0, 0, 0), (5, 4, 3), tail="yes")
    with pytest.raises(ValueError, match="tail"):
        room_from_text("lo=0 0 0; hi=5 4 3; tail=maybe")
    assert room_from_text("lo=0 0 0; hi=5 4 3; tail=off").tail is False
    assert room_from_text("lo=0 0 0; hi=5 4 3").tail is True


# ---------------------------------------------------------------- a room
SRC, MIC = np.array([2.2, 1.7, 1.3]), np.array([3.1, 2.1, 1.55])
LO, HI = (0.0, 0.0, 0.0), (5.0, 4.0, 3.0)
XML = f"""<mujoco><option timestep="0.001"/><worldbody>
  <geom name="bar" type="box" size="0.02 0.02 0.02" pos="{SRC[0]} {SRC[1]} {SRC[2]}"/>
  <site name="mic0" pos="{MIC[0]} {MIC[1]} {MIC[2]}"/></worldbody></mujoco>"""
TE = 0.0051  # (the strike's time [s])


def _struck(room, reflections=True, dt=0.001, seconds=1.5):
    """A bar of 600 modes (88 Hz .. 5.7 kHz, each decaying at 150 /s: a short, broadband
    source) struck at TE in the room, rendered in float64 at 16 kHz."""
    n = 600
    freqs = np.geomspace(88.0, 5700.0, n) * np.random.default_rng(0).uniform(0.99, 1.01, n)
    bar = ModalModel(freqs, np.full(n, 150.0), [[0, 0, 0]], [[0, 0, 1]], np.ones((1, 3, n)), np.ones(n),
                     get_material("steel"), mass_kg=0.5)
    model = mujoco.MjModel.from_xml_string(XML)
    model.opt.timestep = dt
    scene = SoundScene.from_model(model, materials={"bar": "steel"}, models={"bar": bar}, sample_rate=FS,
                                  progress=False)
    sim = AudioSimulator(model, mujoco.MjData(model), scene=scene, sample_rate=FS, room=room,
                         reflections=reflections, clicks=False, synth_kwargs={"dtype": "float64", "cull_db": None})
    sim.synth.impact("bar", SRC, [0, 0, 1e-3], TE, pulse_s=0.0)
    return sim, sim.run(seconds)[0].astype(np.float64)


WALLS = {"walls": "window", "floor": "carpet"}


def test_a_shoebox_decays_at_its_eyring_time_with_the_statistical_late_energy():
    """A 5 x 4 x 3 m room (window-glass walls and ceiling, a carpet floor; Eyring 0.31 .. 0.55
    s), images to order 2 and the tail: in every octave band T30 of the rendered response is
    within 10 % of Eyring's time (T20 too from 1 kHz up; below, the early reflections' few
    strong paths shape the first 25 dB); the energy after 80 ms is the statistical late energy
    ``E_1 4 pi c / V int_t exp(-t / tau) dt``, E_1 the direct sound's energy at 1 m (within
    2 dB in each band from 250 Hz up, above the room's Schroeder frequency 2000 sqrt(T / V) =
    about 180 Hz, where a room's field is statistical; 1 dB on their mean)."""
    room = Room(LO, HI, walls=WALLS, order=2)
    sim, p = _struck(room)
    _, free = _struck(None, reflections=False)
    T = room.rt60("eyring")
    r = float(np.linalg.norm(MIC - SRC))
    t = np.arange(p.size) / FS - TE
    errors = []
    for k, band in enumerate(BANDS):
        e = _band_energy(p, band, FS)
        assert _decay_time(e, FS, -5, -35) == pytest.approx(T[k], rel=0.10), band
        if band >= 1000:
            assert _decay_time(e, FS, -5, -25) == pytest.approx(T[k], rel=0.10), band
        if band >= 250:
            e1 = _band_energy(free, band, FS).sum() * r * r
            tau = T[k] / (6 * math.log(10))
            want = e1 * late_energy_rate(room) * tau * math.exp(-0.08 / tau)
            errors.append(10 * math.log10(e[t > 0.08].sum() / want))
    assert np.all(np.abs(errors) < 2.0) and abs(np.mean(errors)) < 1.0, errors


def test_tail_off_is_the_images_alone_and_on_adds_only_after_the_mixing_time():
    """``tail=False`` renders no tail (the images only, as before the tail existed: the
    closed-form test of the images runs with it); ``tail=True`` leaves every sample before its
    first tap's reach unchanged, bit for bit, and adds energy after."""
    off_sim, off = _struck(Room(LO, HI, walls=WALLS, order=1, tail=False), seconds=0.3)
    on_sim, on = _struck(Room(LO, HI, walls=WALLS, order=1), seconds=0.3)
    assert off_sim.tail is None and on_sim.tail is not None
    plan = on_sim.tail.plan
    r_first = np.linalg.norm(MIC - SRC)  # (the direct sound: the first sound the tail is fed)
    first = int(np.ceil((TE + r_first / C) * FS)) + int(plan.tap_delay.min() + plan.line_len.min()) - 1
    assert np.array_equal(on[:first], off[:first])
    assert np.sum((on - off)[first:] ** 2) > 0.5 * np.sum(off[first:] ** 2)


def test_the_tail_follows_the_timestep_and_keeps_sample_counts():
    room = Room(LO, HI, rt60=0.5, order=1)
    _, a = _struck(room, dt=0.001, seconds=0.4)
    _, b = _struck(room, dt=0.0007, seconds=0.4)
    assert a.size == round(0.4 * FS) and b.size == math.ceil(round(0.4 / 0.0007) * 0.0007 * FS)  # (ceil(t fs))
    k = min(a.size, b.size)
    assert np.abs(a[:k] - b[:k]).max() < 1e-9 * np.abs(a).max()


def test_the_gymnasium_wrapper_takes_a_room_with_or_without_its_tail():
    """AudioObservation passes ``room`` through (dm_control's AudioEnvironment too, through the
    same EnvAudio): its tail is on unless the room says ``tail=False``, and it rings on after
    the steps that struck the box."""
    from mjsound.sim.stub import stub_model
    from mjsound.wrappers import AudioObservation
    from tests.test_wrappers import _HandSteppedEnv

    out = {}
    for tail in (True, False):
        inner = _HandSteppedEnv()
        env = AudioObservation(inner, materials={"box": "steel"}, substeps="manual", sample_rate=16000,
                               window_s=0.01, room=Room((-3, -3, -0.5), (3, 3, 3), rt60=0.8, tail=tail),
                               models={"box": stub_model("box:0.3,0.3,0.01", "steel", 8, 400.0)})
        inner.on_substep = env.on_substep
        env.reset(seed=0)
        out[tail] = np.concatenate([env.step(np.zeros(1))[0]["audio"] for _ in range(30)], axis=-1)
        assert (env.sim.tail is not None) == tail and len(env.sim.images) == 6
    assert np.abs(out[False]).max() > 0 and not np.allclose(out[True], out[False])
