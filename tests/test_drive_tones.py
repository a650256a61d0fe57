"""Drive-train force kernels (mjsound.synth.drive_tones) against plain numpy references:
the recursive chirp oscillators against sin of the exact phase, the anti-aliasing cut, the
phase carried over blocks, the hinge's force direction against np.cross."""

import math

import numpy as np

from mjsound.synth.drive_tones import NOISE, TONE, audible_span, drive_direction, drive_tones

FS = 16000.0


def reference(w0, w1, a0, a1, orders, amps, phase, L):
    """One actuator's tones on one block, by numpy: ``a[k] sum_c A_c sin(phi_c[k])``,
    ``phi_c[k] = phi_c[0] + s0 k + ds k (k - 1) / 2`` (``s0 = order w0 / fs``, ``ds = order
    (w1 - w0) / (L fs)``), a component's samples above 0.45 fs left out; and the end phases."""
    k = np.arange(L)
    out = np.zeros(L)
    ends = []
    for o, A, ph in zip(orders, amps, phase):
        s0, ds = o * w0 / FS, o * (w1 - w0) / (L * FS)
        phi = ph + s0 * k + ds * k * (k - 1) / 2
        out += A * np.sin(phi) * (np.abs(s0 + ds * k) < 2 * math.pi * 0.45)
        ends.append(ph + s0 * L + ds * L * (L - 1) / 2)
    return (a0 + (a1 - a0) * k / L) * out, np.array(ends)


def run(w0, w1, a0, a1, orders, amps, phase, L):
    """The kernel on one actuator's components; ``phase`` updated in place, as the kernel's."""
    out = np.empty((1, L))
    tones = np.zeros(len(orders), TONE)
    tones["order"], tones["amp"], tones["phase"] = orders, amps, phase
    drive_tones(np.array([w0]), np.array([w1]), np.array([a0]), np.array([a1]), np.array([0, len(orders)]),
                tones, np.zeros(1, NOISE), FS, out)
    phase[:] = tones["phase"]
    return out[0]


def test_tones_match_the_exact_phase_over_blocks_through_a_reversal():
    """Three blocks (speed up, down through zero, up again, 803 samples: not a multiple of the
    four interleaved oscillators): the recursion stays on sin of the exact phase."""
    orders, amps = [10.0, 20.0, 126.0], [0.03, 0.015, 0.02]
    phase = np.array([0.1, 2.0, -1.0]) % (2 * math.pi)
    ref_phase = phase.copy()
    for w0, w1, a0, a1 in ((40.0, 55.0, 1.0, 2.0), (55.0, -30.0, 2.0, 0.5), (-30.0, 10.0, 0.5, 0.7)):
        got = run(w0, w1, a0, a1, orders, amps, phase, 803)
        ref, ends = reference(w0, w1, a0, a1, orders, amps, ref_phase, 803)
        assert np.abs(got - ref).max() < 1e-9 * np.abs(ref).max()
        ref_phase = ends % (2 * math.pi)
        assert np.allclose(phase, ref_phase, atol=1e-9)


def test_a_component_sweeping_over_0_45_fs_is_cut_there():
    """Order 100 from 0.40 fs to 0.50 fs: the samples above 0.45 fs are zero, the rest the
    reference's (but for the rounding of the one sample on the cut, k = 500); a component
    above it throughout is silent."""
    to_w = 2 * math.pi * FS / 100.0
    got = run(0.40 * to_w, 0.50 * to_w, 1.0, 1.0, [100.0], [1.0], np.zeros(1), 1000)
    ref, _ = reference(0.40 * to_w, 0.50 * to_w, 1.0, 1.0, [100.0], [1.0], np.zeros(1), 1000)
    assert set(np.flatnonzero(np.abs(got - ref) > 1e-9)) <= {500}
    assert np.all(got[520:] == 0.0) and np.abs(got[:480]).max() > 0.9
    assert np.all(run(0.46 * to_w, 0.49 * to_w, 1.0, 1.0, [100.0], [1.0], np.zeros(1), 64) == 0.0)


def test_audible_span_is_the_interval_under_the_cut():
    for s0, ds, L in ((0.5, 0.001, 4000), (3.0, -0.001, 4000), (-2.0, 0.0005, 9000), (1.0, 0.0, 10), (3.0, 0.0, 10),
                        (1.0, 1e-300, 50), (3.0, -1e-300, 50), (2.8274, 1e-300, 50)):
        k = np.arange(L)
        inside = np.flatnonzero(np.abs(s0 + ds * k) < 2 * math.pi * 0.45)
        lo, hi = audible_span(s0, ds, 2 * math.pi * 0.45, L)
        expect = (inside[0], inside[-1] + 1) if len(inside) else (0, 0)
        assert (lo, hi) == expect, (s0, ds)


def test_broadband_is_linear_in_the_force_scale_and_a_still_joint_is_silent():
    def noise(a):
        out = np.empty((1, 500))
        noise = np.array([(0.01, 7, 0.0)], NOISE)
        drive_tones(np.array([60.0]), np.array([60.0]), np.array([a]), np.array([a]), np.array([0, 0]),
                    np.zeros(0, TONE), noise, FS, out)
        return out[0]

    one = noise(1.0)
    assert np.abs(one).max() > 0
    assert np.array_equal(noise(2.0), 2.0 * one)
    assert np.all(noise(0.0) == 0.0)


def test_the_drive_direction_is_axis_cross_the_least_aligned_world_axis():
    rng = np.random.default_rng(1)
    out = np.empty(3)
    for axis in list(rng.normal(size=(20, 3))) + [np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])]:
        axis = axis / np.linalg.norm(axis)
        e = np.zeros(3)
        e[np.argmin(np.abs(axis))] = 1.0
        c = np.cross(axis, e)
        drive_direction(axis, False, out)
        assert np.allclose(out, c / np.linalg.norm(c), atol=1e-12)
        drive_direction(axis, True, out)
        assert np.array_equal(out, axis)
