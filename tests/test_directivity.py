"""Synthesis hears the direction (issue 35 item 2): each air microphone hears each object's
modes with the model's radiation pattern in the direction from the object's pose to the
microphone, followed per render block without steps; contact microphones and patterns the same
in every direction sound as before."""

import dataclasses

import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.synth.directivity import DIRECTION_FLOOR, evaluate_fit, fit_directions, real_sh, sh_count, sh_tables
from mjsound.synth.synthesizer import Synthesizer

FS = 48000
SQ3 = np.sqrt(3.0)


@dataclasses.dataclass
class PatternModel(ModalModel):
    """A modal model with an analytic far-field pattern: ``pattern(u) -> (n_dirs, n_modes)``
    [Pa m] (``radiation`` is its RMS over directions)."""

    pattern: object = None

    def radiation_pattern(self, directions):
        return self.pattern(np.asarray(directions, np.float64))


def dipole_z(rad):
    """``rad sqrt(3) cos(theta)`` for every mode: a dipole along the object's z (RMS ``rad``)."""
    rad = np.asarray(rad, float)
    return lambda u: SQ3 * u[:, 2:3] * rad[None, :]


def model(pattern=None, f=(440.0,), d=(3.0,), rad=(1.0,)):
    n = len(f)
    shapes = np.zeros((1, 3, n))
    shapes[0, 2] = 1.0
    args = (list(f), list(d), [[0, 0, 0]], [[0, 0, 1]], shapes, list(rad), get_material("steel"))
    if pattern is None:
        return ModalModel(*args, mass_kg=0.1)
    return PatternModel(*args, mass_kg=0.1, pattern=pattern)


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def envelope(y, f):
    """Amplitude of a slowly varying sinusoid of frequency ``f`` per sample (the discrete energy
    operator ``(y[s]^2 - y[s-1] y[s+1]) / sin^2(w)``, exact for a constant one), (len - 2,)."""
    w = 2 * np.pi * f / FS
    return np.sqrt(np.maximum(y[1:-1] ** 2 - y[:-2] * y[2:], 0.0)) / np.sin(w)


# ---------------------------------------------------------------- the basis and the fit
def test_real_harmonics_are_the_closed_forms_and_orthonormal():
    rng = np.random.default_rng(3)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    Y = np.empty(sh_count(2))
    real_sh(2, *u, Y, sh_tables(2))
    x, y, z = u
    c1, c2 = np.sqrt(3 / (4 * np.pi)), np.sqrt(15 / (4 * np.pi))
    ref = [0.5 / np.sqrt(np.pi), c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z,
           np.sqrt(5 / (16 * np.pi)) * (3 * z * z - 1), c2 * x * z, c2 / 2 * (x * x - y * y)]
    np.testing.assert_allclose(Y, ref, rtol=1e-12, atol=1e-14)
    # orthonormal on the sphere (a fine Gauss-Legendre x uniform grid integrates them exactly)
    from mjsound.synth.directivity import _basis, _quadrature

    dirs, w = _quadrature(16)
    B = _basis(16, dirs)
    np.testing.assert_allclose((B * w[:, None]).T @ B, np.eye(sh_count(16)), atol=1e-12)


def test_fit_finds_the_order_and_reproduces_the_pattern():
    # mode 0 a dipole along z, mode 1 a complex mix of monopole and a quadrupole, mode 2 silent
    def pattern(u):
        x, y, z = u.T
        q = np.sqrt(15 / 4) * 2 * x * y  # RMS 1 over the sphere (a Y_2,-2 times sqrt(4 pi))
        return np.stack([2.0 * SQ3 * z, 0.5 * (0.6 + 0.8j * q), 0 * z], -1)

    m = model(pattern, f=(300.0, 900.0, 2000.0), d=(2.0, 2.0, 2.0), rad=(2.0, 0.5, 0.0))
    fit = fit_directions(m, np.arange(3), m.radiation, "test")
    assert fit.order == 2 and fit.orders.tolist() == [1, 2, 0] and fit.coef.shape == (3, 9)
    assert fit.error.max() < 1e-12
    rng = np.random.default_rng(0)
    u = rng.normal(size=(50, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    D = evaluate_fit(fit, u)
    ref = np.conj(pattern(u)) / np.array([2.0, 0.5, 1.0])  # (e^{-j w t} pattern, e^{+j w t} oscillators)
    ref[:, 2] = 1.0  # a mode with no radiation at all is heard with D = 1 (it is silent anyway)
    np.testing.assert_allclose(D, ref, atol=1e-12)
    # the same pattern broadcast everywhere is order -1; a model without a stored one too
    iso = model(lambda u: np.broadcast_to(np.array([1.0]), (len(u), 1)))
    assert fit_directions(iso, np.arange(1), iso.radiation).order == -1
    assert fit_directions(model(), np.arange(1), np.ones(1)).order == -1


@pytest.mark.parametrize("bad,match", [(lambda u: np.ones((len(u), 2)), "shape"),
                                       (lambda u: np.full((len(u), 1), np.nan), "non-finite")])
def test_a_bad_pattern_is_refused_naming_the_object(bad, match):
    syn = Synthesizer(FS)
    with pytest.raises(ValueError, match=f"'bell'.*{match}"):
        syn.add_object("bell", model(bad))


# ---------------------------------------------------------------- static directions
def test_two_microphones_hear_the_dipoles_ratio():
    """A dipole cos(theta) heard at 1 m on its axis, at 60 degrees and at 90 degrees: the
    pattern's 1 : 0.5 : 0 (the null at the floor), each exactly the direction-free sound times
    ``sqrt(3) cos(theta)``."""
    a60 = np.radians(60)
    mics = [[0, 0, 1.0], [np.sin(a60), 0, np.cos(a60)], [1.0, 0, 0]]
    out = {}
    for directivity in (True, False):
        syn = Synthesizer(FS, microphones=mics, dtype="float64", cull_db=None, directivity=directivity)
        syn.add_object("bell", model(dipole_z([1.0])))
        syn.impact("bell", [0, 0, 0], [0, 0, 0.01], 0.0, pulse_s=0.0)
        syn.impact("bell", [0, 0, 0], [0, 0, 0.02], 0.0731, pulse_s=0.0)
        out[directivity] = np.concatenate([syn.render(1000) for _ in range(20)], axis=1)
    y, iso = out[True], out[False]
    peak = np.abs(y[0]).max()
    assert abs(np.abs(y[1]).max() / peak - 0.5) < 1e-6
    np.testing.assert_allclose(y[0], SQ3 * iso[0], rtol=0, atol=1e-6 * peak)  # (render hands out float32)
    np.testing.assert_allclose(y[1], SQ3 * 0.5 * iso[1], rtol=0, atol=1e-6 * peak)  # (render hands out float32)
    assert np.abs(y[2]).max() <= 1.01 * DIRECTION_FLOOR * np.abs(iso[2]).max()


def test_sliding_and_rotated_objects_hear_the_pattern_in_their_own_frame():
    """A forcing source (sliding) goes through the same factors; the pattern turns with the
    object (a dipole along z turned 90 degrees about x points along -y in the world)."""
    R = rot_x(np.pi / 2)
    mics = [[0, -1.0, 0], [0, 0, 1.0]]
    out = {}
    for directivity in (True, False):
        syn = Synthesizer(FS, microphones=mics, dtype="float64", cull_db=None, directivity=directivity)
        syn.add_object("bell", model(dipole_z([1.0, 0.7]), f=(440.0, 1500.0), d=(3.0, 8.0), rad=(1.0, 0.7)),
                       rotation=R)
        syn.slide("bell", [0, 0, 0], [0, 0, 1], 2.0, 0.5, 0.0, 0.1)
        out[directivity] = np.concatenate([syn.render(960) for _ in range(10)], axis=1)
    peak = np.abs(out[False][0]).max()
    np.testing.assert_allclose(out[True][0], SQ3 * out[False][0], rtol=0, atol=1e-6 * peak)
    assert np.abs(out[True][1]).max() <= 1.01 * DIRECTION_FLOOR * np.abs(out[False][1]).max()


def test_a_patterns_phase_is_heard_as_a_delay_of_the_mode():
    """``radiation_pattern`` is ``F`` of ``p = Re(F Q e^{j(k r - w t)}) / r`` for a mode
    ``q = Re(Q e^{-j w t})``: ``F = w e^{j w tau}`` delays the mode by ``tau``. With tau = 10
    samples the sound is the direction-free one 10 samples later (times ``e^{-d tau}``, the
    decay not delayed)."""
    f, d, lag = 523.0, 4.0, 10
    wd = np.sqrt((2 * np.pi * f) ** 2 - d * d)
    phase = np.exp(1j * wd * lag / FS)
    out = {}
    for directivity in (True, False):
        syn = Synthesizer(FS, microphones=[[0.2, 0.1, 1.0]], dtype="float64", cull_db=None, directivity=directivity)
        syn.add_object("bell", model(lambda u: np.full((len(u), 1), phase), f=(f,), d=(d,)))
        syn.impact("bell", [0, 0, 0], [0, 0, 0.01], 0.0, pulse_s=0.0)
        out[directivity] = syn.render(4800)[0].astype(np.float64)
    y, iso = out[True], out[False]
    start = np.flatnonzero(iso)[0] + lag + 1
    np.testing.assert_allclose(y[start:], np.exp(-d * lag / FS) * iso[start - lag: len(iso) - lag], rtol=0,
                               atol=1e-5 * np.abs(iso).max())


# ---------------------------------------------------------------- turning
def test_a_turning_object_follows_the_pattern_per_block_without_steps():
    """A dipole turning about x at 2 turns per second (the microphone on the world z axis),
    hit twice (the second time inside a block whose gain ramps). Each sample is the
    direction-free sound's complex state ``u`` times a gain ``D(s)`` that goes geometrically,
    within block b, from ``sqrt(3) cos`` of the angle before it to that of the angle set before
    it: continuous across blocks (no step), reaching the pattern's value at each block's end."""
    f, d, n, nblk = 700.0, 2.0, 480, 50
    spin = 2 * 2 * np.pi  # rad/s
    blocks = {}
    for directivity in (True, False):
        syn = Synthesizer(FS, microphones=[[0, 0, 1.0]], dtype="float64", cull_db=None, directivity=directivity)
        syn.add_object("bell", model(dipole_z([1.0]), f=(f,), d=(d,)), position=[0, 0, 0])
        syn.impact("bell", [0, 0, 0], [0, 0, 0.01], 0.0, pulse_s=0.0)
        syn.impact("bell", [0, 0, 0], [0, 0, 0.01], (20 * n + 123) / FS, pulse_s=0.0)
        ys = []
        for b in range(nblk):
            syn.set_pose("bell", [0, 0, 0], rot_x(spin * b * n / FS))
            ys.append(syn.render(n))
        blocks[directivity] = np.concatenate(ys, axis=1)[0].astype(np.float64)
    y, iso = blocks[True], blocks[False]
    # the direction-free complex state from two samples: Im u[s+1] = Im(p u[s])
    p = np.exp(complex(-d, np.sqrt((2 * np.pi * f) ** 2 - d * d)) / FS)
    u = (iso[1:] - p.real * iso[:-1]) / p.imag + 1j * iso[:-1]
    angle = spin * np.arange(nblk) * n / FS
    target = SQ3 * np.cos(angle)
    prev = np.concatenate([target[:1], target[:-1]])  # (block 0: silent before, the target at once)
    s = np.arange(len(u))
    blk, pos = s // n, (s % n) / n
    same = np.sign(prev[blk]) == np.sign(target[blk])
    gain = np.sign(target[blk]) * np.exp((1 - pos) * np.log(np.abs(prev[blk])) + pos * np.log(np.abs(target[blk])))
    ref = np.imag(gain * u)
    # (a block where cos changes sign turns the phase by pi at |D| between the two: checked
    # for its level only; the samples where a hit arrives have no u from two samples)
    hits = [round(FS / 343.0), 20 * n + 123 + round(FS / 343.0)]
    ok = same & (np.abs(prev[blk]) > 1e-3) & (np.abs(target[blk]) > 1e-3)
    for h in hits:
        ok[h - 2: h + 1] = False
    peak = np.abs(y).max()
    assert ok.sum() > 0.8 * len(ok)
    np.testing.assert_allclose(y[:-1][ok], ref[ok], rtol=0, atol=2e-6 * peak)
    for b in np.flatnonzero(np.sign(prev) != np.sign(target)):
        seg = slice(b * n, (b + 1) * n)
        hi = max(abs(prev[b]), abs(target[b])) * np.abs(u[seg]).max()
        assert np.abs(y[seg]).max() <= 1.001 * hi + 1e-6 * peak


def test_an_object_at_rest_is_not_evaluated_again_and_silent_voices_take_the_target_at_once():
    syn = Synthesizer(FS, microphones=[[0, 0, 1.0]], dtype="float64")
    syn.add_object("bell", model(dipole_z([1.0])))
    syn.render(480)
    np.testing.assert_array_equal(syn.direction_factors("bell"), [[1.0]])  # (nothing sounded yet)
    syn.set_pose("bell", [0, 0, 0], rot_x(np.radians(60)))
    syn.impact("bell", [0, 0, 0], [0, 0, 0.01], syn.time, pulse_s=0.0)
    syn.render(480)  # silent so far: the target at once
    np.testing.assert_allclose(syn.direction_factors("bell"), [[SQ3 * 0.5]], rtol=1e-12)
    syn.set_pose("bell", [0, 0, 0], rot_x(np.radians(60.5)))  # under DIRECTION_STEP_DEG: kept
    syn.render(480)
    np.testing.assert_allclose(syn.direction_factors("bell"), [[SQ3 * 0.5]], rtol=1e-12)
    syn.set_pose("bell", [0, 0, 0], rot_x(np.radians(70)))  # ringing: ramped, at the target at the end
    syn.render(480)
    np.testing.assert_allclose(syn.direction_factors("bell"), [[SQ3 * np.cos(np.radians(70))]], rtol=1e-12)


def test_a_mode_silent_while_the_object_turned_is_heard_in_the_new_direction():
    """Only the ringing modes are evaluated as an object turns; a silent mode's factor is made
    when something excites it. Mode 0 (a dipole along z) rings while the object turns 60
    degrees about y; mode 1 (a dipole along x) is struck only afterwards: each is heard with
    its pattern in the final direction ``u = (-sin 60, 0, cos 60)``."""
    def rot_y(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    shapes = np.zeros((1, 3, 2))
    shapes[0, 2, 0] = shapes[0, 0, 1] = 1.0  # a z impulse excites mode 0 only, an x impulse mode 1
    pattern = lambda u: SQ3 * u[:, [2, 0]]

    def run(directivity, hits):
        m = PatternModel([440.0, 1210.0], [3.0, 3.0], [[0, 0, 0]], [[0, 0, 1]], shapes, [1.0, 1.0],
                         get_material("steel"), mass_kg=0.1, pattern=pattern)
        syn = Synthesizer(FS, microphones=[[0, 0, 1.0]], dtype="float64", cull_db=None, directivity=directivity)
        syn.add_object("bell", m)
        ys = []
        for b in range(30):
            syn.set_pose("bell", [0, 0, 0], rot_y(np.radians(6.0 * min(b, 10))))
            for hb, J in hits:
                if hb == b:
                    syn.impact("bell", [0, 0, 0], J, syn.time, pulse_s=0.0)
            ys.append(syn.render(480))
        return np.concatenate(ys, axis=1)[0].astype(np.float64), syn

    a = np.radians(60)
    x_obj = rot_y(a) @ [0.01, 0, 0]  # (impulses are given in the world frame)
    y, syn = run(True, [(0, [0, 0, 0.01]), (15, x_obj)])
    iso0, _ = run(False, [(0, [0, 0, 0.01])])
    iso1, _ = run(False, [(15, x_obj)])
    D = syn.direction_factors("bell")[0]
    np.testing.assert_allclose(D.real, [SQ3 * np.cos(a), -SQ3 * np.sin(a)], rtol=1e-9)
    after = slice(11 * 480, None)  # (the turn's last ramp ends with block 10)
    ref = SQ3 * np.cos(a) * iso0 - SQ3 * np.sin(a) * iso1
    np.testing.assert_allclose(y[after], ref[after], rtol=0, atol=2e-6 * np.abs(ref).max())


# ---------------------------------------------------------------- unchanged
def test_contact_microphones_and_isotropic_patterns_sound_as_before():
    """A contact microphone hears a directional object exactly as without directions; an object
    whose pattern is the same in every direction sounds bit for bit as a model without one and
    as ``directivity=False`` (the path before directions), moving and with sliding."""
    def run(m, directivity=True):
        syn = Synthesizer(FS, microphones=[[0.3, 0.2, 1.0], [1.0, 0, 0]], directivity=directivity)
        syn.add_object("bell", m)
        syn.add_contact_microphone("bell", [0, 0, 0], [0, 0, 1])
        syn.impact("bell", [0, 0, 0], [0, 0.003, 0.01], 0.0)
        syn.slide("bell", [0, 0, 0], [0, 0, 1], 2.0, 0.5, 0.05, 0.15)
        ys = []
        for b in range(20):
            syn.set_pose("bell", [0.01 * b, 0, 0], rot_x(0.2 * b))
            if b == 7:
                syn.impact("bell", [0, 0, 0], [0, 0, 0.02], syn.time + 0.001)
            ys.append(syn.render(480))
        return np.concatenate(ys, axis=1)

    f, d, rad = (440.0, 1300.0), (3.0, 9.0), (1.0, 0.3)
    plain = run(model(None, f, d, rad))
    iso = run(model(lambda u: np.broadcast_to(np.array(rad), (len(u), 2)), f, d, rad))
    off = run(model(dipole_z(rad), f, d, rad), directivity=False)
    on = run(model(dipole_z(rad), f, d, rad))
    assert np.array_equal(iso, plain) and np.array_equal(off, plain)
    assert np.array_equal(on[2], plain[2])  # the contact channel
    assert not np.allclose(on[0], plain[0], atol=1e-3 * np.abs(plain[0]).max())


def test_the_per_sample_root_of_a_gain_ratio():
    """``_root(r, n)``: ``x = log(r) / n`` and ``rho = e^x`` (so ``rho^n = r``), by its series
    near 1 and by log / exp elsewhere, the sign flip ``r = -1`` included."""
    from mjsound.jit import call_inner
    from mjsound.synth.directivity import _root

    rng = np.random.default_rng(0)
    rs = np.concatenate([1 + 0.17 * (rng.uniform(-1, 1, 300) + 1j * rng.uniform(-1, 1, 300)),
                         rng.uniform(0.01, 5, 50) * np.exp(1j * rng.uniform(-3, 3, 50)), [-1.0 + 0j, 0.5 + 0j]])
    for r in rs:
        xr, xi, rr, ri = call_inner(_root, r.real, r.imag, 480)
        x, rho = complex(xr, xi), complex(rr, ri)
        ref = np.log(r) / 480
        assert abs(x - ref) <= 1e-9 * abs(ref) + 1e-300
        assert abs(rho - np.exp(x)) <= 1e-15 and abs(rho**480 / r - 1) < 1e-8
