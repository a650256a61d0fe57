"""The lines' per-block weights' kernels (mjsound.synth.drive_weights, the direction factors'
harmonics of mjsound.synth.directivity) against their plain references."""

import numpy as np
from scipy.special import sph_harm_y

from mjsound.jit import call_inner
from mjsound.synth.directivity import real_sh, sh_count, sh_tables
from mjsound.synth.drive_weights import _transfer_sums


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
