"""The lines' per-block weights' kernels (mjsound.synth.drive_weights, the direction factors'
harmonics of mjsound.synth.directivity) against their plain references."""

import math

import numpy as np
import pytest
from scipy.special import sph_harm_y

from mjsound.jit import call_inner
from mjsound.synth.directivity import DIRECTION_FLOOR, real_sh, sh_count, sh_tables
from mjsound.synth.drive_lines import SceneView
from drive_directions_reference import direction_factors_f64
from mjsound.synth.drive_weights import _transfer_sums
from mjsound.synth.records import AIR, CHANNEL, DIRECTIONS


def test_transfer_sums_are_the_steady_state_weights():
    """2 W = 2 (H(th) - conj(H(-th))) / 2j, H(th) = sum_i g_i / (1 - p_i e^{-j th}), per
    microphone and component; a component at step 0 (above the cut-off) is left alone."""
    rng = np.random.default_rng(5)
    n, M, nmax = 7, 3, 9
    p = rng.uniform(0.9, 0.9999, n) * np.exp(1j * rng.uniform(0.01, 3.0, n))
    g = rng.normal(size=(M, n)) + 1j * rng.normal(size=(M, n))
    th = np.array([0.3, 0.0, 2.5, -0.7, np.angle(p[2])])  # (one at a mode's own frequency)
    xr, xi = np.zeros((M, nmax)), np.zeros((M, nmax))
    xr[:, :n], xi[:, :n] = g.real, g.imag
    pr, pi = np.zeros(nmax), np.zeros(nmax)
    pr[:n], pi[:n] = p.real, p.imag
    hs = np.full((2, 6, M), 7.0)
    call_inner(_transfer_sums, pr, pi, n, np.cos(th), np.sin(th), th, 0, len(th), xr, xi, np.zeros((4, nmax)), hs)

    def H(t):
        return (g / (1 - p * np.exp(-1j * t))).sum(1)

    for c, t in enumerate(th):
        if t == 0.0:
            np.testing.assert_array_equal(hs[:, c], 7.0)
            continue
        ref = 2 * (H(t) - np.conj(H(-t))) / 2j
        np.testing.assert_allclose(hs[0, c] + 1j * hs[1, c], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_real_harmonics_at_high_order_are_scipys():
    """real_sh against scipy's complex harmonics (Condon-Shortley phase): Y_l,+m = sqrt(2)
    (-1)^m Re Y_l^m, Y_l,-m = sqrt(2) (-1)^m Im Y_l^m, Y_l0 = Y_l^0, at random directions and
    the poles."""
    L = 16
    tab = sh_tables(L)
    rng = np.random.default_rng(8)
    dirs = rng.normal(size=(20, 3))
    dirs = np.vstack([dirs / np.linalg.norm(dirs, axis=1, keepdims=True), [[0, 0, 1], [0, 0, -1]]])
    for u in dirs:
        Y = np.empty(sh_count(L))
        real_sh(L, *u, Y, tab)
        theta, phi = np.arccos(np.clip(u[2], -1, 1)), np.arctan2(u[1], u[0])
        ref = np.empty(sh_count(L))
        for l in range(L + 1):
            for m in range(l + 1):
                y = sph_harm_y(l, m, theta, phi)
                if m == 0:
                    ref[l * l + l] = y.real
                else:
                    ref[l * l + l + m] = np.sqrt(2) * (-1) ** m * y.real
                    ref[l * l + l - m] = np.sqrt(2) * (-1) ** m * y.imag
        np.testing.assert_allclose(Y, ref, rtol=1e-10, atol=1e-12)


def _basis(L, u):
    Y = np.empty(sh_count(L))
    real_sh(L, *u, Y, sh_tables(L))
    return Y


def test_direction_factors_are_the_fits_at_each_microphones_direction():
    """Each air microphone's gains times sum_lm Y_lm(u) c_lm (per mode, to its own order; the
    floor where the fit is below it) at u = R^T (mic - pos) / |mic - pos|, made again only
    when u turned by more than the step; a contact microphone's gains are left alone. Three
    air microphones (made two at a time and one alone) and a contact one, object 1 of 2."""
    rng = np.random.default_rng(11)
    L, n, M = 10, 5, 4
    orders = np.array([10, 10, 3, 0, 10])
    msh = np.array([sh_count(o) for o in orders])
    msh_off = np.concatenate([[0, 2], 2 + np.cumsum(np.concatenate([[0], msh]))])  # (object 0: 2 and 0)
    coef = rng.normal(size=(msh_off[-1], 2)) * 0.3
    coef[msh_off[2 + 2]:msh_off[2 + 3]] = 0.0  # (mode 2 of object 1: a null everywhere, floored)
    mics = rng.normal(size=(M, 3))
    channels = np.zeros(M, CHANNEL)
    channels["owner"] = [AIR, AIR, 1, AIR]
    channels["w_off"] = -1
    pos = rng.normal(size=(2, 3))
    R = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2)])
    params = np.zeros(1, DIRECTIONS)
    params["cos_step"], params["floor"] = np.cos(np.radians(1.0)), DIRECTION_FLOOR
    view = SceneView(None, None, np.array([0, 2, 2 + n]), mics, pos, R, channels, np.array([0, L]), msh_off,
                     np.ascontiguousarray(coef[:, 0]), np.ascontiguousarray(coef[:, 1]), np.zeros((M, sh_count(16))),
                     sh_tables(16), params)
    g = rng.normal(size=(M, n + 2)) + 1j * rng.normal(size=(M, n + 2))
    U = np.full((M, 3), np.nan)
    Fd = np.zeros((M, n + 2), np.complex128)

    def expected():
        out = g.copy()
        for m in range(M):
            if channels["owner"][m] != AIR:
                continue
            u = R[1].T @ (mics[m] - pos[1])
            Y = _basis(L, u / np.linalg.norm(u))
            for k in range(n):
                c = coef[msh_off[2 + k]:msh_off[3 + k]]
                f = Y[:len(c)] @ (c[:, 0] + 1j * c[:, 1])
                if abs(f) < DIRECTION_FLOOR:
                    f = DIRECTION_FLOOR * (f / abs(f) if f != 0 else 1.0)
                out[m, k] *= f
        return out

    def run():
        xr, xi = g.real.copy(), g.imag.copy()
        direction_factors_f64(xr, xi, n, 1, 2, view, U, Fd, np.zeros(M))
        return xr + 1j * xi

    np.testing.assert_allclose(run(), expected(), rtol=1e-11, atol=1e-14)
    assert np.all(np.isnan(U[2])) and np.all(np.isfinite(U[[0, 1, 3]]))
    assert np.abs(Fd[:, 2][[0, 1, 3]]) == pytest.approx(DIRECTION_FLOOR)
    # the object turns by half the step: the factors are kept; by twice the step: made again
    R0 = R[1].copy()
    for deg, kept in ((0.5, True), (2.0, False)):
        a = np.radians(deg)
        turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        R[1] = R0 @ turn
        ref = expected()
        before = Fd.copy()
        got = run()
        if kept:
            np.testing.assert_array_equal(Fd, before)
            assert not np.allclose(got, ref, rtol=1e-6)  # (the old factors, not those of now)
        else:
            np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-14)


def test_phase_steps_are_the_components_cosines_and_sines():
    """Each component's step t = order w / fs (0 from 0.45 of a turn on) and cos t, sin t:
    those of a component at 2 or 3 times the order of one before it of the same actuator
    (from its own by the double- and triple-angle products) as the others within 4 ulp of
    the math module's."""
    from mjsound.synth.drive_tones import TONE
    from mjsound.synth.drive_weights import _phase_steps

    orders = [10.0, 20.0, 30.0, 126.0, 252.0, 1 / 3, 2 / 3, 1.0, 6.0, 7.0, 40.0]
    comp_off = np.array([0, 5, 11], np.int64)
    tones = np.zeros(len(orders), TONE)
    tones["order"] = orders
    fs = 16000.0
    for w in ([3.1, -40.0], [200.0, 1e-3], [0.0, 650.0]):
        w = np.array(w)
        th, cth, sth = (np.full(len(orders), 9.0) for _ in range(3))
        call_inner(_phase_steps, tones, comp_off, w, fs, 2 * np.pi * 0.45, th, cth, sth)
        t = np.array(orders) * np.repeat(w, np.diff(comp_off)) / fs
        np.testing.assert_array_equal(th, np.where(np.abs(t) < 2 * np.pi * 0.45, t, 0.0))
        cos, sin = np.array([math.cos(x) for x in t]), np.array([math.sin(x) for x in t])
        np.testing.assert_allclose(cth, cos, rtol=0, atol=4 * 2.0**-52)
        np.testing.assert_allclose(sth, sin, rtol=0, atol=4 * 2.0**-52)
