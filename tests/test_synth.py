"""Tests of the synthesis engine (issue 3): exactness, linearity, precision, block
independence, Hertz pulses, delay/attenuation, stability and input validation."""

import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.synth.pulse import half_sine_spectrum, hertz_contact_time
from mjsound.synth.synthesizer import D_MIN_PER_S, Synthesizer

FS = 48000
C = 343.0


def one_mode(f=440.0, d=3.0, shape=(0.0, 0.0, 1.0), rad=1.0, mass=0.1, material="steel"):
    return ModalModel([f], [d], [[0, 0, 0]], [[0, 0, 1]], np.array(shape, float).reshape(1, 3, 1), [rad],
                      get_material(material), mass_kg=mass)


def many_modes(n=40, n_points=20, seed=1, material="steel", fmax=15000.0, damping=None):
    rng = np.random.default_rng(seed)
    f = np.sort(np.geomspace(120.0, fmax, n) * rng.uniform(0.97, 1.03, n))
    mat = get_material(material)
    w = 2 * np.pi * f
    d = (mat.alpha + mat.beta * w**2) / 2 if damping is None else np.full(n, damping)
    pts = rng.normal(size=(n_points, 3)) * 0.05
    nrm = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    shapes = rng.normal(size=(n_points, 3, n)) * 3.0
    rad = rng.uniform(0.5, 2.0, n) * 1e-2 * w / 1000
    return ModalModel(f, d, pts, nrm, shapes, rad, mat, mass_kg=0.3)


def closed_form(t, te, r, J, f=440.0, d=3.0, rad=1.0):
    wd = np.sqrt((2 * np.pi * f) ** 2 - d**2)
    tau = t - te - r / C
    q = J / wd * np.exp(-d * tau) * np.sin(wd * tau)
    return np.where(tau >= 0, rad * q / r, 0.0)


# ---------------------------------------------------------------- correctness
@pytest.mark.parametrize("te", [0.0, 0.01, 0.0123456789, 0.5 / FS + 0.02, 3.999999 / FS])
def test_closed_form_float64(te):
    mics = [[0, 0, 1.0], [0, 2.0, 0]]
    syn = Synthesizer(FS, microphones=mics, dtype="float64", cull_db=None)
    syn.add_object("o", one_mode())
    syn.impact("o", [0, 0, 0], [0, 0, 0.02], te, pulse_s=0.0)
    y = syn.render(FS // 2)
    t = np.arange(FS // 2) / FS
    for m, r in enumerate([1.0, 2.0]):
        ref = closed_form(t, te, r, 0.02)
        assert np.abs(y[m] - ref).max() < 1e-6 * np.abs(ref).max()


def test_mic_twice_as_far_half_amplitude_and_delay():
    syn = Synthesizer(FS, microphones=[[1.0, 0, 0], [2.0, 0, 0]], dtype="float64", cull_db=None)
    syn.add_object("o", one_mode(f=1000.0, d=5.0))
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], 0.01, pulse_s=0.0)
    y = syn.render(FS)
    a1, a2 = np.abs(y[0]).max(), np.abs(y[1]).max()
    assert abs(a2 / a1 - 0.5) < 1e-3  # 1/r (the wave decays from its arrival)
    # the far signal is the near one delayed by 1/c (sub-sample) and halved
    t = np.arange(FS) / FS
    near = closed_form(t - 1.0 / C, 0.01, 1.0, 0.01, f=1000.0, d=5.0)
    assert np.abs(y[1] - 0.5 * near).max() < 1e-6 * np.abs(near).max()
    # onset sample
    first = np.flatnonzero(y[1])[0]
    assert first == int(np.ceil((0.01 + 2.0 / C) * FS))


def test_linearity_and_superposition():
    model = many_modes(20)

    def render(events):
        syn = Synthesizer(FS, dtype="float64", cull_db=None)
        syn.add_object("o", model)
        for p, J, t in events:
            syn.impact("o", p, J, t, pulse_s=5e-5)
        return syn.render(FS // 4)[0].astype(np.float64)

    p1, p2 = model.points[3], model.points[7]
    e1 = (p1, [0.01, -0.02, 0.005], 0.01)
    e2 = (p2, [0.0, 0.03, -0.01], 0.0321)
    y1, y2, y12 = render([e1]), render([e2]), render([e1, e2])
    peak = np.abs(y12).max()
    assert np.abs(y12 - (y1 + y2)).max() < 1e-6 * peak
    y3 = render([(p1, [0.03, -0.06, 0.015], 0.01)])
    assert np.abs(y3 - 3 * y1).max() < 1e-6 * np.abs(y3).max()


def test_impact_energy_bound_scales_to_the_budget_and_leaves_the_rest():
    """A given approach speed bounds the vibration energy by what the collision takes from the
    approach, |J| v (1 - e) / 2 (steel struck by a rigid partner: e = 0.6): an impact whose modes
    would take more is scaled to exactly that energy, one within it is rendered unchanged."""
    model = many_modes(30)
    p, J, tau = model.points[5], np.array([0.02, -0.01, 0.03]), 4e-5

    def render(speed):
        syn = Synthesizer(FS, dtype="float64", cull_db=None)
        syn.add_object("o", model)
        syn.impact("o", p, J, 0.01, pulse_s=tau, speed=speed)
        return syn.render(FS // 8)[0]

    # the unbounded energy sum_m |phi_m(x).J S(w_m tau)|^2 / 2 of the kept modes
    wd = np.sqrt((2 * np.pi * model.frequencies_hz) ** 2 - model.decay_per_s**2)
    v = model.shapes[5].T @ J * half_sine_spectrum(wd, tau)
    energy = 0.5 * float(np.sum(np.abs(v) ** 2))
    free = render(None)
    e = model.material.restitution
    assert e == pytest.approx(0.6)
    speed = 0.1 * energy / (0.5 * np.linalg.norm(J) * (1 - e))  # a budget of a tenth of it
    capped = render(speed)
    assert np.abs(capped - np.sqrt(0.1) * free).max() < 1e-6 * np.abs(free).max()  # (float32 output)
    np.testing.assert_array_equal(render(1.01 * energy / (0.5 * np.linalg.norm(J) * (1 - e))), free)
    # the whole impulse's work |J| v / 2 is (1 + e) / (1 - e) = 4 times that: no longer the bound
    bounded = render(energy / (0.5 * np.linalg.norm(J)))
    assert np.abs(bounded - np.sqrt(1 - e) * free).max() < 1e-6 * np.abs(free).max()


def test_lost_energy_is_the_approach_energy_the_restitution_removes():
    """|J| v (1 - e) / 2 = m* v^2 (1 - e^2) / 2 for J = m* (1 + e) v; no speed: no bound."""
    from mjsound.synth.impact_energy import lost_energy

    m, v = 3.0, 2.0
    for e in (0.0, 0.3, 0.55, 1.0):
        assert lost_energy(m * (1 + e) * v, v, e) == pytest.approx(0.5 * m * v * v * (1 - e * e), rel=1e-12)
    assert lost_energy(-6.0, 2.0, 0.0) == pytest.approx(6.0)  # (the impulse's sign does not matter)
    assert lost_energy(6.0, 2.0, float("nan")) == pytest.approx(6.0)  # (unknown e: the plastic hit)
    assert lost_energy(6.0, 0.0, 0.5) == np.inf and lost_energy(6.0, float("nan"), 0.5) == np.inf


def test_nodal_direction_excites_nothing():
    syn = Synthesizer(FS)
    syn.add_object("o", one_mode(shape=(0.0, 0.0, 1.0)))
    syn.impact("o", [0, 0, 0], [0.5, -0.3, 0.0], 0.0)
    assert np.all(syn.render(4800) == 0)
    assert syn.active_modes("o") == 0


def test_float32_matches_float64_dense_impacts():
    model = many_modes(60)
    rng = np.random.default_rng(5)
    k = 1000
    times = np.sort(rng.uniform(0, 10.0, k))
    idx = rng.integers(0, len(model.points), k)
    J = rng.normal(size=(k, 3)) * 0.01
    outs = {}
    for dt in ("float32", "float64"):
        syn = Synthesizer(FS, dtype=dt, microphones=[[0.3, 0.2, 0.5], [-1, 0, 0]])
        syn.add_object("o", model)
        syn.impacts("o", model.points[idx], J, times)
        outs[dt] = np.concatenate([syn.render(FS) for _ in range(10)], axis=1).astype(np.float64)
    err = np.abs(outs["float32"] - outs["float64"]).max()
    peak = np.abs(outs["float64"]).max()
    assert 20 * np.log10(err / peak) < -80


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_block_splits_bit_identical(dtype):
    model = many_modes(30, damping=None)
    rng = np.random.default_rng(2)
    total = 3 * FS // 2
    times = rng.uniform(0, 1.3, 200)
    idx = rng.integers(0, len(model.points), 200)
    J = rng.normal(size=(200, 3)) * 0.01

    def run(blocks, incremental):
        syn = Synthesizer(FS, dtype=dtype, microphones=[[0, 0, 1], [0.5, 0.5, 0]], seed=3)
        syn.add_object("a", model)
        syn.add_object("b", one_mode(f=700.0, d=40.0), position=(0.2, 0, 0))
        pending = list(np.argsort(times))

        def add_upto(t_end):
            while pending and times[pending[0]] < t_end:
                i = pending.pop(0)
                syn.impact("a", model.points[idx[i]], J[i], times[i])
                syn.impact("b", [0.2, 0, 0], J[i], times[i] + 0.001)

        extras = lambda: (syn.slide("a", model.points[0], [0, 0, 1], 2.0, 0.5, 0.2, 0.55),
                          syn.roll("a", model.points[1], [0, 1, 0], 3.0, 0.8, 0.6, 0.9))
        if not incremental:
            add_upto(np.inf)
            extras()
        out = []
        pos = 0
        for i, b in enumerate(blocks):
            if incremental:
                add_upto((pos + b) / FS)
                if i == 0:
                    extras()
            out.append(syn.render(b))
            pos += b
        return np.concatenate(out, axis=1)

    ref = run([total], False)
    sizes = [0, 1, 255, 256, 257, 1000, 17, 4096, 3, 48000]
    blocks = []
    while sum(blocks) < total:
        blocks.append(sizes[len(blocks) % len(sizes)])
    blocks[-1] -= sum(blocks) - total
    assert np.array_equal(run(blocks, False), ref)
    assert np.array_equal(run([100] + [480] * ((total - 100) // 480) + [(total - 100) % 480], True), ref)
    assert np.abs(ref).max() > 0


# ---------------------------------------------------------------- Hertz pulse
def test_half_sine_spectrum_matches_numeric_transform():
    tau = 1e-3
    n = 200000
    t = (np.arange(n) + 0.5) * (tau / n)
    f = np.pi / (2 * tau) * np.sin(np.pi * t / tau)  # unit-area half sine
    w = np.array([0.0, 100.0, 1000.0, np.pi / tau, np.pi / tau * (1 + 1e-9), 5000.0, 20000.0, 1e5])
    num = (f[None, :] * np.exp(-1j * w[:, None] * t[None, :])).sum(axis=1) * (tau / n)
    S = half_sine_spectrum(w, tau)
    assert np.allclose(S, num, atol=1e-6)
    assert abs(half_sine_spectrum(np.pi / tau, tau) - (-1j * np.pi / 4)) < 1e-12
    assert half_sine_spectrum(1000.0, 0.0) == 1.0


def test_hertz_contact_time_values_and_trends():
    steel, rubber, glass = get_material("steel"), get_material("rubber"), get_material("glass")
    tau = hertz_contact_time(0.1, 0.1, 0.01, 0.01, steel, steel, 1.0)
    assert 20e-6 < tau < 300e-6
    assert hertz_contact_time(0.1, 0.1, 0.01, 0.01, steel, steel, 4.0) < tau  # faster: shorter
    assert hertz_contact_time(0.1, 0.1, 0.01, 0.01, rubber, steel, 1.0) > 1e-3  # rubber: ms
    assert hertz_contact_time(0.1, np.inf, 0.01, np.inf, steel, None, 1.0) < tau * 1.0 + 1e-12
    assert hertz_contact_time(0.1, 0.1, 0.01, 0.01, glass, steel, 0.0) > 0.1


def _centroid(y):
    s = np.abs(np.fft.rfft(y)) ** 2
    f = np.fft.rfftfreq(len(y), 1 / FS)
    return (f * s).sum() / s.sum()


def test_harder_and_faster_is_brighter_rubber_is_dull():
    model = many_modes(60, fmax=18000.0)

    def clip(**kw):
        syn = Synthesizer(FS)
        syn.add_object("o", model)
        syn.impact("o", model.points[0], [0, 0, -0.05], 0.0, other_mass_kg=0.2, other_radius_m=0.01, **kw)
        return syn.render(FS // 2)[0].astype(np.float64)

    steel = get_material("steel")
    c_hard = _centroid(clip(other_material=steel, speed=2.0))
    c_slow = _centroid(clip(other_material=steel, speed=0.05))
    c_rub = _centroid(clip(other_material=get_material("rubber"), speed=2.0))
    c_wood = _centroid(clip(other_material=get_material("pine"), speed=2.0))
    assert c_hard > c_wood > c_rub
    assert c_hard > c_slow
    assert c_rub < 0.5 * c_hard


# ---------------------------------------------------------------- stability
def test_one_hour_of_ringing_matches_closed_form():
    d = 1e-3
    f = 100.0
    syn = Synthesizer(FS, microphones=[[0, 0, 1]])
    syn.add_object("o", one_mode(f=f, d=d))
    syn.impact("o", [0, 0, 0], [0, 0, 1.0], 0.0, pulse_s=0.0)
    block = FS * 120
    for _ in range(29):
        syn.render(block)
    y = syn.render(block)
    assert np.all(np.isfinite(y))
    t = (np.arange(block) + 29 * block) / FS
    ref = closed_form(t, 0.0, 1.0, 1.0, f=f, d=d)
    amp = np.abs(ref).max()
    assert abs(np.abs(y).max() / amp - 1) < 1e-2  # no growth, same decay
    assert np.abs(y[0] - ref).max() < 2e-2 * amp  # and the same phase


def test_zero_negative_damping_and_nyquist():
    fs = 16000
    syn = Synthesizer(fs)
    m = ModalModel([200.0, 500.0, 7199.0, 7200.0, 8000.0, 9000.0, 300.0], [0.0, -5.0, 1.0, 1.0, 1.0, 1.0, 3000.0],
                   [[0, 0, 0]], [[0, 0, 1]], np.ones((1, 3, 7)), np.ones(7), get_material("steel"))
    syn.add_object("o", m)
    assert syn.n_modes("o") == 3  # 200, 500 (damping floored), 7199; >= 0.45 fs and overdamped dropped
    ob = syn.object_modes("o")
    assert np.all(ob.decay >= D_MIN_PER_S)
    np.testing.assert_array_equal(ob.keep, [0, 1, 2])
    np.testing.assert_allclose(ob.damped_omega, np.sqrt((2 * np.pi * np.array([200.0, 500.0, 7199.0])) ** 2
                                                        - ob.decay**2))
    syn.impact("o", [0, 0, 0], [0, 0, 1.0], 0.0)
    a = np.abs(syn.render(fs)).max()
    for _ in range(5):
        b = np.abs(syn.render(fs)).max()
    assert np.isfinite(b) and b <= a * 1.0001


def test_million_events_in_one_block():
    m = many_modes(4, n_points=5)
    syn = Synthesizer(FS)
    syn.add_object("o", m)
    rng = np.random.default_rng(0)
    k = 1_000_000
    syn.impacts("o", m.points[rng.integers(0, 5, k)], rng.normal(size=(k, 3)), rng.uniform(0, 1, k), pulse_s=0.0)
    y = syn.render(FS)
    assert np.all(np.isfinite(y)) and np.abs(y).max() > 0


def test_impulse_range_finite_and_linear():
    model = many_modes(10)
    peaks = []
    for J in [1e-12, 1e-6, 1.0, 1e3, 1e6]:
        syn = Synthesizer(FS)
        syn.add_object("o", model)
        syn.impact("o", model.points[0], [0, 0, J], 0.0, pulse_s=1e-5)
        y = syn.render(FS // 2)
        assert np.all(np.isfinite(y))
        peaks.append(np.abs(y).max() / J)
    assert np.allclose(peaks, peaks[0], rtol=1e-4)


def test_culling_stops_and_restarts():
    syn = Synthesizer(FS, cull_db=-60)
    syn.add_object("o", one_mode(f=1000.0, d=200.0))
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], 0.0)
    syn.render(FS // 50)  # 20 ms: -35 dB
    assert syn.active_modes("o") == 1
    syn.render(FS // 10)  # -60 dB after 35 ms
    assert syn.active_modes("o") == 0
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], syn.time)
    assert np.abs(syn.render(4800)).max() > 0


# ---------------------------------------------------------------- sustained contact
def test_slide_roll_and_silence():
    model = many_modes(50, fmax=16000.0)

    def run(kind, speed, seed=0):
        syn = Synthesizer(FS, seed=seed)
        syn.add_object("o", model)
        getattr(syn, kind)("o", model.points[2], [0, 0, 1], 5.0, speed, 0.0, 0.5)
        return syn.render(FS)[0].astype(np.float64)

    assert np.all(run("slide", 0.0) == 0) and np.all(run("roll", 0.0) == 0)
    s = run("slide", 1.0)
    assert np.abs(s).max() > 0
    assert np.array_equal(s, run("slide", 1.0))  # deterministic
    assert not np.array_equal(s, run("slide", 1.0, seed=1))
    r = run("roll", 1.0)
    assert _centroid(r) < _centroid(s)  # rolling is duller
    assert np.abs(run("slide", 2.0)).max() > np.abs(s).max()  # faster: louder


def test_streams_with_and_without_forcing_sources_superpose():
    """A slide alone (its rows placed straight into the banks) plus a force signal alone equals
    both at once (the general path that merges and sorts all source rows), on two microphones."""
    model = many_modes(30)
    mics = [[0, 0, 1.0], [0.5, -1.0, 0.3]]

    def run(slide, force):
        syn = Synthesizer(FS, microphones=mics, dtype="float64", cull_db=None, seed=3)
        syn.add_object("o", model)
        syn.add_object("p", many_modes(12, seed=2), position=(0.3, 0, 0))
        if slide:
            syn.slide("o", model.points[1], [0, 0, 1], 4.0, 0.8, 0.01, 0.2)
            syn.slide("p", [0.3, 0, 0.05], [0, 1, 0], 2.0, 0.5, 0.0, 0.1)
        if force:
            syn.excite("o", model.points[4], [1, 0, 0], np.sin(np.arange(3000) * 0.05), 0.02)
        return np.hstack([syn.render(2000), syn.render(FS // 4)])

    a, b, both = run(True, False), run(False, True), run(True, True)
    assert np.abs(a).max() > 0 and np.abs(b).max() > 0
    np.testing.assert_allclose(both, a + b, rtol=0, atol=1e-6 * np.abs(both).max())  # (float32 output)


def test_excite_signal_matches_impulse():
    syn = Synthesizer(FS, dtype="float64", cull_db=None)
    syn.add_object("o", one_mode())
    sig = np.zeros(10)
    sig[0] = 0.01 * FS  # one sample of force = impulse 0.01 N s
    syn.excite("o", [0, 0, 0], [0, 0, 1], sig, 0.001)
    y = syn.render(FS // 4)[0]
    ref = closed_form(np.arange(FS // 4) / FS, 0.001, 1.0, 0.01)
    assert np.abs(y - ref).max() < 1e-5 * np.abs(ref).max()


# ---------------------------------------------------------------- validation
def test_invalid_input_errors_and_state_unchanged():
    model = many_modes(10)

    def make():
        syn = Synthesizer(FS)
        syn.add_object("o", model)
        syn.impact("o", model.points[0], [0, 0, 0.01], 0.0)
        syn.render(1000)
        return syn

    syn, ref = make(), make()
    bad_calls = [
        lambda: syn.impact("o", model.points[0], [np.nan, 0, 0], 0.1),
        lambda: syn.impact("o", model.points[0], [0, 0, np.inf], 0.1),
        lambda: syn.impact("o", [np.nan, 0, 0], [0, 0, 1], 0.1),
        lambda: syn.impact("o", model.points[0], [0, 0, 1], 0.001),  # before the rendered time
        lambda: syn.impact("o", model.points[0], [0, 0, 1], np.nan),
        lambda: syn.impact("nope", model.points[0], [0, 0, 1], 0.1),
        lambda: syn.impacts("o", model.points[:2], [[0, 0, 1], [0, 0, np.nan]], [0.1, 0.2]),
        lambda: syn.slide("o", model.points[0], [0, 0, 1], 1.0, np.nan, 0.1, 0.2),
        lambda: syn.slide("o", model.points[0], [0, 0, 1], 1.0, 1.0, 0.3, 0.2),
        lambda: syn.roll("x", model.points[0], [0, 0, 1], 1.0, 1.0, 0.1, 0.2),
        lambda: syn.set_pose("o", [0, 0, np.nan], np.eye(3)),
        lambda: syn.add_object("o", model),
        lambda: syn.render(-1),
    ]
    for call in bad_calls:
        with pytest.raises(ValueError):
            call()
    with pytest.raises(ValueError, match="unknown object"):
        syn.impact("nope", [0, 0, 0], [0, 0, 1], 0.1)
    with pytest.raises(ValueError, match="before"):
        syn.impact("o", [0, 0, 0], [0, 0, 1], 0.0)
    for s in (syn, ref):
        s.impact("o", model.points[1], [0, 0.01, 0], 0.05)
    assert np.array_equal(syn.render(FS), ref.render(FS))
    for fs in (999, 800000, float("nan"), float("inf"), 44100.5):
        with pytest.raises(ValueError, match="sample_rate"):
            Synthesizer(fs)


def test_event_in_future_block_and_time_property():
    syn = Synthesizer(FS)
    syn.add_object("o", one_mode())
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], 0.5)
    assert np.all(syn.render(FS // 4) == 0)
    assert syn.time == 0.25 and syn.samples_rendered == FS // 4
    assert np.abs(syn.render(FS // 2)).max() > 0
    syn.reset()
    assert syn.time == 0.0 and np.all(syn.render(FS) == 0)


def test_pose_moves_point_and_distance():
    # rotating the object by 90 deg about z turns a world-x impulse into a body-y one
    syn = Synthesizer(FS, dtype="float64", cull_db=None)
    m = one_mode(shape=(0.0, 1.0, 0.0))
    Rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    syn.add_object("o", m, position=(0, 0, -1.0), rotation=Rz)  # 2 m from the default mic
    syn.impact("o", [0, 0, -1.0], [0.01, 0, 0], 0.0, pulse_s=0.0)
    y = syn.render(FS // 4)[0]
    ref = closed_form(np.arange(FS // 4) / FS, 0.0, 2.0, -0.01)
    assert np.abs(y - ref).max() < 1e-6 * np.abs(ref).max()


def test_radiation_off_proxy_finite():
    syn = Synthesizer(FS, radiation=False)
    syn.add_object("o", many_modes(10))
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], 0.0)
    y = syn.render(FS // 4)
    assert np.all(np.isfinite(y)) and np.abs(y).max() > 0


def test_moving_microphones_and_channel_count():
    syn = Synthesizer(FS, microphones=[[0, 0, 1.0]], dtype="float64", cull_db=None)
    syn.add_object("o", one_mode())
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], 0.0, pulse_s=0.0)
    a = syn.render(FS // 10)
    syn.set_microphones([[0, 0, 1.0], [0, 0, 3.0]])  # second channel starts silent
    assert syn.n_channels == 2
    syn.impact("o", [0, 0, 0], [0, 0, 0.01], syn.time, pulse_s=0.0)
    b = syn.render(FS // 10)
    assert b.shape == (2, FS // 10) and np.abs(a).max() > 0
    t = np.arange(FS // 10) / FS + 0.1
    ref3 = closed_form(t, 0.1, 3.0, 0.01)
    assert np.abs(b[1] - ref3).max() < 1e-6 * np.abs(ref3).max()
    with pytest.raises(ValueError):
        syn.set_microphones([[0, 0, np.nan]])
    assert syn.n_channels == 2


def test_many_objects_keep_their_poses_and_delays():
    """Poses live in one table that grows as objects are added; every object keeps its own,
    and an impact on the last one arrives after its own distance."""
    syn = Synthesizer(FS, microphones=[[0, 0, 0]], dtype="float64", cull_db=None)
    for i in range(20):
        syn.add_object(f"o{i}", one_mode(f=500.0 + 10 * i), position=(1.0 + i, 0, 0))
    syn.set_pose("o3", (0, 5.0, 0), np.eye(3)[[1, 0, 2]])
    for i in range(20):
        pos, R = syn.object_pose(f"o{i}")
        np.testing.assert_array_equal(pos, (0, 5.0, 0) if i == 3 else (1.0 + i, 0, 0))
        np.testing.assert_array_equal(R, np.eye(3)[[1, 0, 2]] if i == 3 else np.eye(3))
    np.testing.assert_allclose(syn.object_modes("o19").mic_distances, [20.0])
    syn.impact("o19", (20.0, 0, 0), (0, 0, 0.01), 0.0, pulse_s=0.0)
    y = syn.render(FS // 10)[0]
    first = np.flatnonzero(y)[0]
    assert first == int(np.ceil(20.0 / C * FS - 1e-9))


def test_gather_takes_the_active_modes_and_their_gains_within_each_sources_modes():
    """``_gather`` against numpy: the active modes' state and poles in order, every source's
    gains at them (zero elsewhere, whatever an earlier gather left in the arrays), each
    source's span of gathered modes with a non-zero gain as ``source_spans`` finds it; a
    source visits only its modes ``cols`` (a gain outside them is not taken)."""
    from mjsound.jit import call_inner
    from mjsound.synth.kernels import Voice, _gather, source_spans

    rng = np.random.default_rng(7)
    m, nsrc = 30, 4
    zr, zi, pr, pi = (rng.standard_normal(m) for _ in range(4))
    active = rng.uniform(size=m) < 0.6
    active[[2, 3, 4, 20]] = True, True, False, True
    voice = Voice(zr, zi, np.zeros(m), active, pr, pi, np.ones(m), np.zeros(m))
    gr, gi = np.zeros((nsrc, m)), np.zeros((nsrc, m))
    gr[0, 3:9], gi[0, 5:12] = rng.standard_normal(6), rng.standard_normal(7)  # source 0: modes 3..11
    gr[1, 4] = 1.0  # source 1: only an inactive mode; source 2: no gains
    gr[3, 15:m] = rng.standard_normal(m - 15)
    cols = np.array([[3, 4, m, 15], [12, 5, m, m]], np.int64)
    gr[3, 2] = 5.0  # (outside source 3's modes: not taken)
    work = tuple(np.full(m, np.nan) for _ in range(4))
    gwr, gwi = np.full((nsrc, m), 9.0), np.full((nsrc, m), 9.0)  # (an earlier gather's leftovers)
    idx, kof, span = np.zeros(m, np.int64), np.zeros(m, np.int64), np.full((2, nsrc), -1, np.int64)
    na = call_inner(_gather, voice, gr, gi, cols, work, (gwr, gwi), idx, kof, span)
    on = np.flatnonzero(active)
    assert na == len(on) and idx[:na].tolist() == on.tolist()
    for w, ref in zip(work, (zr, zi, pr, pi)):
        np.testing.assert_array_equal(w[:na], ref[on])
    gr[3, 2] = 0.0
    np.testing.assert_array_equal(gwr[:, :na], gr[:, on])
    np.testing.assert_array_equal(gwi[:, :na], gi[:, on])
    assert not gwr[:, na:].any() and not gwi[:, na:].any()
    ref_span = np.full((2, nsrc), -1, np.int64)
    call_inner(source_spans, gr[:, on].copy(), gi[:, on].copy(), na, ref_span)
    assert span.tolist() == ref_span.tolist()
    assert span[:, 1].tolist() == [0, 0] and span[:, 2].tolist() == [0, 0]


@pytest.mark.parametrize("na,nact", [(12, 3), (20, 1), (20, 2), (24, 3), (24, 4), (24, 5)])
def test_forced_bank_visits_only_each_sources_span(na, nact):
    """``bank_forced`` with each source's span of non-zero gains (``source_spans``) is the
    plain recursion ``z += sum_q g_q F_q[s]; out[s] += Im z; z *= p`` over every mode (numpy,
    float64), and the spans are the first and one past the last non-zero gain (empty: 0, 0).
    Banks of 16 modes or more fold the last one to three acting sources with a gain into the
    oscillator loop (a fourth is added over its span first), smaller ones do not: one, two,
    three and four acting sources, an acting source without any gain (skipped), sources
    acting in another order than their rows."""
    from mjsound.jit import call_inner
    from mjsound.synth.bank_loops import bank_forced
    from mjsound.synth.kernels import source_spans

    rng = np.random.default_rng(3)
    nsrc, n, o0 = 5, 40, 3
    gwr, gwi = np.zeros((nsrc, na)), np.zeros((nsrc, na))
    gwr[0, 2:5], gwi[0, 3:6] = rng.standard_normal(3), rng.standard_normal(3)  # source 0: modes 2..5
    gwr[1, 9:12] = rng.standard_normal(3)  # source 1: modes 9..11; source 2: no gain at all
    gwr[3, 4:na], gwi[3, 4:na] = rng.standard_normal(na - 4), rng.standard_normal(na - 4)  # overlaps 0 and 1
    gwi[4, 0:7] = rng.standard_normal(7)  # source 4: modes 0..6
    span = np.full((2, nsrc), -7, np.int64)
    call_inner(source_spans, gwr, gwi, na, span)
    assert span.tolist() == [[2, 9, 0, 4, 0], [6, 12, 0, na, 7]]
    p = 0.99 * np.exp(1j * rng.uniform(0.1, 3.0, na))
    z0 = rng.standard_normal(na) + 1j * rng.standard_normal(na)
    F = rng.standard_normal((nsrc, o0 + n))  # (the segment starts at sample o0 of the block)
    act = np.array([3, 0, 2, 4, 1], np.int64)[:nact]
    work = (z0.real.copy(), z0.imag.copy(), p.real.copy(), p.imag.copy())
    out = np.zeros(o0 + n)
    call_inner(bank_forced, work, na, out, o0, n, 0.0, gwr, gwi, F, act, nact, span)
    assert not out[:o0].any()
    z, ref = z0.copy(), np.zeros(n)
    g = (gwr + 1j * gwi)[act]
    for s in range(n):
        z = z + g.T @ F[act, o0 + s]
        ref[s] = z.imag.sum()
        z = z * p
    np.testing.assert_allclose(out[o0:], ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(work[0] + 1j * work[1], z, rtol=1e-12, atol=1e-12)
