"""Acceleration noise (rigid-body clicks) against the closed forms of a rigid sphere and an
ellipsoid, and the band-limited pulse renderer against plain references."""

import math

import numpy as np
import pytest
from scipy.special import spherical_jn, spherical_yn

from mjsound.synth import accel_noise as an
from mjsound.synth import bandlimited as bl

FS = 48000
RHO, C = an.RHO_AIR, an.SPEED_OF_SOUND


def _half_sine_accel(w, tau, dv):
    """Spectrum of a(t) = dv pi/(2 tau) sin(pi t / tau) on [0, tau], written out directly."""
    wp = math.pi / tau
    w = np.asarray(w, dtype=np.float64)
    num = dv * wp * wp * (1.0 + np.exp(-1j * w * tau))
    den = 2.0 * (wp * wp - w * w)
    near = np.abs(den) < 1e-9 * wp * wp
    out = num / np.where(near, 1.0, den)
    return np.where(near, -1j * dv * math.pi / 4.0, out)


def _hankel_sphere(w, a, r, cos_theta, accel):
    """Rigid sphere, e^{jwt}: p = -j rho c U cos(theta) h1(kr) / h1'(ka), U = A / (j w),
    h1 = j1 - j y1 (Morse & Ingard sec. 7.2), from scipy's spherical Bessel functions."""
    w = np.asarray(w, dtype=np.float64)
    k = w / C
    h = spherical_jn(1, k * r) - 1j * spherical_yn(1, k * r)
    hd = spherical_jn(1, k * a, derivative=True) - 1j * spherical_yn(1, k * a, derivative=True)
    return -1j * RHO * C * (accel / (1j * w)) * cos_theta * h / hd


def _lowpass(f_over_fs):
    x = np.clip((f_over_fs - bl.PASS_FRACTION) / (0.5 - bl.PASS_FRACTION), 0.0, 1.0)
    return np.where(f_over_fs >= 0.5, 0.0, 0.5 * (1.0 + np.cos(np.pi * x)))


def _render(pulses, dv, n, fs=FS):
    track = bl.PulseTrack(int(pulses["channel"].max()) + 1, fs)
    track.add(pulses, dv)
    return track.take(n)


def _reference_samples(spectrum, times, fs=FS, n_w=40000):
    """p_n = (1/pi) int_0^{pi fs} Re(P(w) G(w) e^{j w t_n}) dw by the trapezoid rule."""
    w = np.linspace(1e-3, math.pi * fs, n_w)
    pw = spectrum(w) * _lowpass(w / (2 * math.pi * fs))
    ph = np.exp(1j * np.outer(times, w))
    return np.trapezoid((pw[None, :] * ph).real, w, axis=1) / math.pi


def test_rigid_sphere_matches_hankel_closed_form_level_and_spectrum():
    a, r, theta, tau, dv = 0.05, 0.7, math.radians(40.0), 30e-6, 1.0  # ka = 17 at 19 kHz
    mic = np.array([[r * math.sin(theta), 0.0, 0.3 + r * math.cos(theta)]])
    t_e = 0.0102
    pulses = an.click_pulses([0, 0, 0.3], np.eye(3), [a, a, a], [0, 0, 1], mic, t_e, tau)
    n = 1024
    got = _render(pulses, dv, n)[0]
    times = np.arange(n) / FS

    def spectrum(w):
        return _hankel_sphere(w, a, r, math.cos(theta), _half_sine_accel(w, tau, dv)) * np.exp(-1j * w * t_e)

    ref = _reference_samples(spectrum, times)
    peak = np.abs(ref).max()
    assert peak > 1.0  # a 10 cm sphere stopped by 1 m/s in 30 us: pascals at 0.7 m
    assert np.abs(got - ref).max() < 2e-3 * peak
    level = 20 * math.log10(np.sqrt(np.mean(got**2)) / np.sqrt(np.mean(ref**2)))
    assert abs(level) < 1.0
    # spectrum shape: the rendered click's spectrum against |P| of the closed form in band
    f = np.fft.rfftfreq(n, 1 / FS)
    spec = np.abs(np.fft.rfft(got)) / FS
    band = (f > 100) & (f < 0.38 * FS)
    want = np.abs(spectrum(2 * math.pi * f[band]))
    err_db = 20 * np.log10(spec[band] / want)
    assert np.abs(err_db).max() < 0.1
    # and the closed form has the shape the physics says: the compact dipole (near field and
    # the jerk-following far field) well below c / (2 pi a) = 1.1 kHz, rho c |U| a cos / r far above
    f_lo, f_hi = 60.0, 9000.0
    w_lo, w_hi = 2 * math.pi * f_lo, 2 * math.pi * f_hi
    acc = np.abs(_half_sine_accel(np.array([w_lo, w_hi]), tau, dv))
    compact = RHO * a**3 * math.cos(theta) / (2 * r * r) * abs(1 + 1j * w_lo * r / C) * acc[0]
    rigid_piston = RHO * C * a * math.cos(theta) / r * acc[1] / w_hi
    assert 20 * math.log10(abs(spectrum(w_lo)) / compact) == pytest.approx(0.0, abs=0.1)
    assert 20 * math.log10(abs(spectrum(w_hi)) / rigid_piston) == pytest.approx(0.0, abs=0.5)

def test_compact_sphere_time_domain_closed_form():
    """ka << 1: p(t) = rho a^3 cos(theta) / (2 r^2) (a(t') + (r/c) da/dt(t')), t' = t - r/c."""
    a, r, tau, dv = 0.005, 0.3, 2e-3, 0.8
    t_e = 0.0051
    for theta in (0.0, math.radians(60.0), math.pi):
        mic = np.array([[r * math.sin(theta), 0.0, r * math.cos(theta)]])
        pulses = an.click_pulses([0, 0, 0], np.eye(3), [a, a, a], [0, 0, 1], mic, t_e, tau)
        got = _render(pulses, dv, 800)[0]
        t = np.arange(800) / FS - t_e - r / C
        on = (t >= 0) & (t <= tau)
        acc = np.where(on, dv * math.pi / (2 * tau) * np.sin(math.pi * t / tau), 0.0)
        jerk = np.where(on, dv * math.pi**2 / (2 * tau**2) * np.cos(math.pi * t / tau), 0.0)
        want = RHO * a**3 * math.cos(theta) / (2 * r * r) * (acc + r / C * jerk)
        peak = np.abs(want).max()
        away = (np.abs(t) > 4 / FS) & (np.abs(t - tau) > 4 / FS)  # Gibbs ringing at the jerk's jumps
        if abs(math.cos(theta)) < 1e-12:
            continue
        assert np.abs(got - want)[away].max() < 0.02 * peak
        assert 20 * math.log10(np.abs(got).max() / peak) == pytest.approx(0.0, abs=1.0)
        assert np.sign(got[np.argmax(np.abs(want))]) == np.sign(math.cos(theta))


def test_click_direction_angle_and_clamped_distance():
    a = 0.02
    mics = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 0, -0.5], [0, 0, 0.001]])
    p = an.click_pulses([0, 0, 0], np.eye(3), [a, a, a], [0, 0, 2.0], mics, 0.5, 1e-4)
    k = RHO * a**3 / 2  # 2 pi rho a^3 / (4 pi) per m/s^2
    assert p["b0"][0] == pytest.approx(k / 1.0)
    assert p["b1"][0] == pytest.approx(k / C)
    assert p["b0"][1] == pytest.approx(0.0, abs=1e-15)
    assert p["b0"][2] == pytest.approx(-k / 0.25)
    assert p["b0"][3] == pytest.approx(k / a**2)  # inside the body: at its surface
    assert p["time_s"][:3] == pytest.approx(0.5 + (np.array([1.0, 1.0, 0.5]) - a) / C)
    assert p["d1"][0] == pytest.approx(a / C) and p["d2"][0] == pytest.approx(a * a / (2 * C * C))
    with pytest.raises(ValueError, match="direction"):
        an.click_pulses([0, 0, 0], np.eye(3), [a, a, a], [0, 0, 0], mics, 0.0, 1e-4)


def test_ellipsoid_added_mass_against_lamb():
    assert an.ellipsoid_alphas([0.1, 0.1, 0.1]) == pytest.approx([2 / 3] * 3)
    vol = 4 / 3 * math.pi * 0.1**3
    assert an.dipole_masses([0.1, 0.1, 0.1]) == pytest.approx([1.5 * RHO * vol] * 3)
    # prolate spheroid a > b = c, eccentricity e: alpha_a = 2 (1 - e^2)/e^3 (atanh e - e) (Lamb sec. 115)
    aa, b = 0.3, 0.1
    e = math.sqrt(1 - (b / aa) ** 2)
    alpha0 = 2 * (1 - e * e) / e**3 * (math.atanh(e) - e)
    al = an.ellipsoid_alphas([aa, b, b])
    assert al[0] == pytest.approx(alpha0, rel=1e-10)
    assert al.sum() == pytest.approx(2.0)
    assert al[1] == pytest.approx((2 - alpha0) / 2)
    # thin rod: along it only the displaced air moves, across it twice that
    m = an.dipole_masses([1.0, 1e-3, 1e-3])
    v = 4 / 3 * math.pi * 1e-6
    assert m[0] == pytest.approx(RHO * v, rel=1e-3) and m[1] == pytest.approx(2 * RHO * v, rel=1e-3)
    assert an.equivalent_radius([0.3, 0.1, 0.1]) == pytest.approx((0.3 * 0.01) ** (1 / 3))


def test_carlson_rd_against_scipy_and_closed_forms():
    from scipy.special import elliprd

    rng = np.random.default_rng(0)
    for _ in range(500):
        x, y, z = 10 ** rng.uniform(-6, 3, 3)
        assert an.carlson_rd(x, y, z) == pytest.approx(elliprd(x, y, z), rel=1e-13)
    assert an.carlson_rd(0.0, 2.0, 1.0) == pytest.approx(elliprd(0.0, 2.0, 1.0), rel=1e-13)
    # R_D(x, x, x) = x^(-3/2); sphere: every alpha is 2/3
    assert an.carlson_rd(4.0, 4.0, 4.0) == pytest.approx(0.125, rel=1e-15)
    assert an.ellipsoid_alphas([0.1, 0.1, 0.1]) == pytest.approx([2 / 3] * 3, rel=1e-14)
    for bad in [(-1.0, 1.0, 1.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0), (np.nan, 1.0, 1.0)]:
        with pytest.raises(ValueError, match="R_D"):
            an.carlson_rd(*bad)


def test_equivalent_ellipsoid_from_inertia():
    mass, axes = 2.0, np.array([0.3, 0.1, 0.05])
    inertia = mass / 5 * np.array([axes[1] ** 2 + axes[2] ** 2, axes[0] ** 2 + axes[2] ** 2, axes[0] ** 2 + axes[1] ** 2])
    assert an.ellipsoid_from_inertia(mass, inertia) == pytest.approx(axes)
    # a 5 cm cube: I = m s^2 / 6 about every axis -> a = sqrt(5/3) s / 2
    s = 0.05
    assert an.ellipsoid_from_inertia(0.13, [0.13 * s * s / 6] * 3) == pytest.approx([math.sqrt(5 / 3) * s / 2] * 3)
    rod = an.ellipsoid_from_inertia(1.0, [0.0, 0.1, 0.1])
    assert rod[1] == pytest.approx(1e-3 * rod[0])
    for bad_m, bad_i in ((0.0, [1, 1, 1]), (float("nan"), [1, 1, 1]), (1.0, [0, 0, 0]), (1.0, [1, -1, 1])):
        with pytest.raises(ValueError):
            an.ellipsoid_from_inertia(bad_m, bad_i)
    with pytest.raises(ValueError, match="semi_axes"):
        an.ellipsoid_alphas([0.1, 0.0, 0.1])


def test_fft_matches_numpy():
    rng = np.random.default_rng(0)
    for n in (2, 64, 512):
        x = rng.standard_normal(n) + 1j * rng.standard_normal(n)
        y = x.copy()
        bl.fft_inplace(y, False)
        assert np.abs(y - np.fft.fft(x)).max() < 1e-12 * n
        y = x.copy()
        bl.fft_inplace(y, True)
        assert np.abs(y - np.fft.ifft(x)).max() < 1e-14 * n
        z = x.copy()  # a table kept for a longer transform serves every shorter one, bit for bit
        bl.fft_with(z, bl.twiddles(1024, True), True)
        assert np.array_equal(z, y)


def _accel_pulse(t, tau, channel=0, b0=1.0):
    p = np.zeros(1, bl.PULSE_DTYPE)
    p["time_s"], p["tau_s"], p["b0"], p["channel"] = t, tau, b0, channel
    return p


def test_pulse_track_take_into_adds_what_take_returns():
    """``take_into(block)`` adds to a float32 block exactly what ``block +=
    take(n).astype(float32)`` adds (the ring wrapping inside a block, blocks before, across and
    after the pulses), a non-finite sample as nothing, and leaves the track where ``take``
    leaves it."""
    rng = np.random.default_rng(4)
    tracks = [bl.PulseTrack(2, FS), bl.PulseTrack(2, FS)]
    for tr in tracks:
        tr.reset(900)
        for t, ch in ((0.0201, 1), (0.0213, 0), (0.0440, 1)):
            tr.add(_accel_pulse(t, 5e-6, channel=ch), 2.5)
        tr.state.acc[1, (1000 + 17) & (tr.state.acc.shape[1] - 1)] = np.nan  # (as an exploding simulation could leave it)
    for k in (50, 700, 333, 1024, 400):
        a = rng.standard_normal((2, k)).astype(np.float32)
        b = a.copy()
        extra = tracks[0].take(k)
        if extra is not None:
            a += np.nan_to_num(extra, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
        tracks[1].take_into(b)
        assert np.array_equal(a, b) and np.isfinite(b).all()
        assert (tracks[0].start, tracks[0].pending_from) == (tracks[1].start, tracks[1].pending_from)
    assert tracks[1].take(10) is None and not tracks[1].state.acc.any()


def test_pulse_track_integral_blocks_and_nothing_pending():
    track = bl.PulseTrack(2, FS)
    assert track.take(480) is None  # nothing pending: no work, nothing to add
    track.add(_accel_pulse(0.0201, 5e-6, channel=1), 2.5)
    whole = bl.PulseTrack(2, FS)
    whole.reset(480)
    whole.add(_accel_pulse(0.0201, 5e-6, channel=1), 2.5)
    ref = whole.take(2000)
    sizes = (400, 300, 1300)
    parts = [track.take(k) for k in sizes]
    assert parts[0] is None  # samples 480..879: the pulse's window starts at 932
    got = np.concatenate([np.zeros((2, k)) if b is None else b for b, k in zip(parts, sizes)], axis=1)
    assert np.array_equal(got, ref)
    assert ref[0].max() == 0.0
    assert ref[1].sum() / FS == pytest.approx(2.5, rel=1e-9)  # the acceleration integrates to dv
    assert track.take(10) is None
    # a pulse longer than a window can hold is counted, not rendered
    track.add(_accel_pulse(0.05, 5.0), 1.0)
    assert track.dropped == 1 and track.take(10) is None


def test_pulse_track_drops_only_pre_ringing_before_handed_out_audio():
    tau, t0 = 2e-5, 100 / FS  # on a sample boundary
    full = bl.PulseTrack(1, FS)
    full.add(_accel_pulse(t0, tau), 1.0)
    ref = full.take(400)[0]
    late = bl.PulseTrack(1, FS)
    assert late.take(100) is None
    late.add(_accel_pulse(t0, tau), 1.0)
    got = late.take(300)[0]
    assert np.array_equal(got, ref[100:])
    lost_db = 10 * math.log10(np.sum(got**2) / np.sum(ref**2))
    assert -0.3 < lost_db < 0.0


def test_pulse_track_rejects_bad_input():
    track = bl.PulseTrack(1, FS)
    with pytest.raises(ValueError, match="finite"):
        track.add(_accel_pulse(float("nan"), 1e-4), 1.0)
    with pytest.raises(ValueError, match="channel"):
        track.add(_accel_pulse(0.0, 1e-4, channel=3), 1.0)
    with pytest.raises(ValueError, match="tau_s"):
        track.add(_accel_pulse(0.0, -1e-4), 1.0)
    with pytest.raises(ValueError, match="sample_rate"):
        bl.PulseTrack(1, 0)
    # the trusted path (the simulator's, from an exploding simulation) drops such pulses
    track.add_trusted(_accel_pulse(float("nan"), 1e-4), np.array([1.0]))
    track.add_trusted(_accel_pulse(1e300, 1e-4), np.array([1.0]))
    track.add_trusted(_accel_pulse(0.001, 1e-4), np.array([np.inf]))
    assert track.dropped == 3 and track.take(100) is None


def test_pulse_track_ring_wrap_matches_direct_render():
    p = _accel_pulse(1010 / FS + 0.3 / FS, 4e-5, b0=2.0)
    work, out = np.zeros(256, np.complex128), np.zeros(256)
    first, n = bl.render_pulse(p[0], 1.5, float(FS), work, out, bl.twiddles(256, True))
    track = bl.PulseTrack(1, FS)
    track.reset(1000)  # the ring (1024 samples) wraps inside the pulse's window
    track.add(p, 1.5)
    got = track.take(200)[0]
    want = np.zeros(200)
    want[:first + n - 1000] = out[1000 - first:n]  # (its pre-ringing before sample 1000 is dropped)
    assert first < 1000 and 1024 < first + n
    assert np.array_equal(got, want)


def test_render_pulse_rotated_phases_match_numpy_grid_spectrum():
    """A long pulse (a hollow body's milliseconds, 1024-sample window: the phase factors are
    rotated across 16 RESEED blocks) against the same band-limited grid spectrum evaluated bin
    by bin with numpy's exponentials and inverse real FFT."""
    fs, tau, t_arr, dv = 16000.0, 0.021, 0.5 + 0.37 / 16000, 0.8
    b0, b1, d1, d2 = 2.0, 3e-4, 7e-4, 2.4e-7  # (a rigid sphere's click transfer: a ~ 0.24 m)
    p = np.zeros(1, bl.PULSE_DTYPE)
    p[0]["time_s"], p[0]["tau_s"], p[0]["b0"], p[0]["b1"], p[0]["d1"], p[0]["d2"] = t_arr, tau, b0, b1, d1, d2
    n = 1024
    work, out = np.zeros(n, np.complex128), np.zeros(n)
    first, m = bl.render_pulse(p[0], dv, fs, work, out, bl.twiddles(n, True))
    assert m == n and n // 2 > 8 * bl.RESEED
    k = np.arange(n // 2 + 1)
    w = 2 * np.pi * k / n * fs
    s = 1j * w
    shift = t_arr - first / fs
    g = np.array([_lowpass(f) for f in k / n])
    spec = dv * _half_sine_accel(w, tau, 1.0) * (b0 + b1 * s) / (1 + d1 * s + d2 * s * s) * g * np.exp(-s * shift) * fs
    want = np.fft.irfft(spec, n)
    assert np.max(np.abs(out - want)) < 1e-9 * np.max(np.abs(want))
    assert np.sum(want) != 0.0 and first == int(np.floor(t_arr * fs)) - bl.LEAD
