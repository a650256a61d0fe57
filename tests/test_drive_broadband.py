"""The resonant broadband's kernels (mjsound.synth.drive_broadband) against plain references:
the modes' recursion run in chunks and heard per body against the complex recursion sample
by sample, and the ring's add against one sample at a time."""

import numpy as np

from mjsound.synth.drive_broadband import modes_heard, modes_run, ring_add


def reference(f, row, p, g, w, h, steady):
    """Each mode's heard signal ``Im(h b[q])``, ``b = w + g f[row][q]``, ``w <- p b``, sample by
    sample in complex numbers (a mode not ``steady`` faded out, ``(L - q) / L``); and the end states."""
    K, L = len(p), f.shape[1]
    y = np.zeros((K, L))
    w = w.astype(complex).copy()
    for k in range(K):
        for q in range(L):
            b = w[k] + g[k] * f[row[k], q]
            y[k, q] = (h[k] * b).imag * (1.0 if steady[k] else (L - q) / L)
            w[k] = p[k] * b
    return y, w


def test_the_modes_run_in_chunks_as_the_complex_recursion():
    """Seven modes of three bodies (one group of four and one of three plus a silent filler),
    over 300 samples in chunks of 128, 128, 44, two of them fading: each body's heard sum and
    the end states match the complex recursion to 1e-12 of their scale."""
    rng = np.random.default_rng(1)
    L, K, Kp = 300, 7, 8
    f = rng.standard_normal((3, L))
    row = np.array([0, 0, 0, 0, 0, 1, 2, 0])
    p = 0.9995 * np.exp(1j * rng.uniform(0.5, 3.0, Kp))
    g = rng.standard_normal(Kp)
    w = rng.standard_normal(Kp) + 1j * rng.standard_normal(Kp)
    p[K:] = g[K:] = w[K:] = 0.0  # (the filler)
    h = rng.standard_normal(Kp) + 1j * rng.standard_normal(Kp)
    steady = np.array([True, True, False, True, True, True, False, True])
    y, w_end = reference(f, row, p, g, w, h, steady)
    bodies = ((0, 5), (5, 6), (6, 7))
    wr, wi = w.real.copy(), w.imag.copy()
    out = np.zeros((len(bodies), L))
    X = np.empty((2 * Kp, 128))
    for s in range(0, L, 128):
        n = min(128, L - s)
        modes_run(X, f, s, n, row, p.real.copy(), p.imag.copy(), g, wr, wi)
        for i, (k0, k1) in enumerate(bodies):
            modes_heard(out[i, s:s + n], X, n, k0, k1, h.real.copy(), h.imag.copy(), steady, s, L)
    for i, (k0, k1) in enumerate(bodies):
        want = y[k0:k1].sum(axis=0)
        assert np.abs(out[i] - want).max() < 1e-12 * np.abs(want).max()
    assert np.abs((wr + 1j * wi)[:K] - w_end[:K]).max() < 1e-12 * np.abs(w_end).max()
    assert wr[K] == wi[K] == 0.0  # (the filler stays silent)


def test_ring_add_wraps_and_leaves_out_samples_before_the_first():
    """Adds into a ring of 64 across its wrap, with samples before ``first`` left out, as one
    sample at a time (absolute sample k at k & 63); the other channel untouched."""
    rng = np.random.default_rng(2)
    for off, first, n in ((50, 0, 30), (50, 60, 30), (10, 0, 64), (100, 90, 20), (5, 200, 10)):
        acc = rng.standard_normal((2, 64))
        want = acc.copy()
        x = rng.standard_normal(n)
        for q in range(n):
            if off + q >= first:
                want[1, (off + q) & 63] += x[q]
        ring_add(acc, 1, off, first, x)
        assert np.array_equal(acc, want), (off, first, n)
