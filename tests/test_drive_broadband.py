"""The resonant broadband's kernels (mjsound.synth.drive_broadband) against plain references:
the modes kept and the static part left against a sort, the modes' recursion run in chunks
and heard per body against the complex recursion sample by sample (two microphones at once
as one at a time; a free mode's ring-out from its pole's powers as the recursion), and the
ring's add against one sample at a time; the route's hold, and no gap in the links' noise
where a line crosses a resonance."""

from pathlib import Path

import numpy as np

from mjsound.synth.bandlimited import ring_add
from mjsound.synth.drive_broadband import (RESONANT_OFF, RESONANT_ON, RESONANT_REST, ROUTE_HOLD_S, broadband_modes,
                                          broadband_route, complex_state, free_heard, heard_factors, modes_heard,
                                          modes_heard_pair, modes_run, pole_powers, real_coefficients, real_state)
from mjsound.synth.drive_lines import Actuators, BodyGains, LineWeights
from mjsound.synth.drive_tones import DRIVE, NOISE, TONE


def test_the_modes_kept_hold_all_but_the_rest_and_leave_the_others_static_part():
    """Three bodies, 3 actuators (actuator 1 not exact, body 2 without a stream): on each body
    an exact actuator pushes, the fewest modes holding all but RESONANT_REST of its resonant
    power (a sort's prefix) are kept; an exact actuator's static gain (its bodies' whole
    static response and the housing's part, as the weights made it) loses the kept modes'
    static response, summed over its sides with their signs; the others' are left as they were."""
    rng = np.random.default_rng(3)
    nb, M, nmax, J = 3, 2, 40, 3
    resonant = rng.exponential(1.0, (nb, nmax)) ** 4  # (a few strong modes, many weak)
    resonant[:, 30:] = 0.0  # (beyond the object's modes)
    static = rng.standard_normal((nb, M, nmax))
    sidx = np.array([0, 1, -1])
    sign = np.array([1.0, -1.0, 1.0])
    ptr = np.array([0, 2, 4, 5])
    rows = np.array([0, 2, 1, 3, 4])  # body 0: actuators 0 and 1 (their bodies); body 1: their parents; body 2: 2
    exact = np.array([True, False, True])
    z = np.zeros
    act = Actuators(z(J + 1, np.int64), z(0, TONE), z(J, NOISE), z(J, DRIVE), ptr, rows, sidx, sign, z(J, np.bool_),
                    z(J), z(J), z(J), z(J), z(J))
    B1 = rng.standard_normal((J, M))
    lw = LineWeights(z((0, M), np.complex128), z((0, M), np.complex128), z((J, M)), B1.copy(), z(M, np.int64), exact,
                     z((J, 2)))
    bg = BodyGains(z((nb, M, nmax)), z((nb, M, nmax)), z((nb, nmax)), z((nb, M, nmax), np.complex128),
                   z((nb, M), np.int64), z((nb, M)), z((nb, M, nmax), np.complex128), z((5, 3)), z(5, np.int64),
                   static, resonant, np.ones((nb, nmax), np.bool_), z((nb, nmax), np.complex128), z((nb, nmax)),
                   z((nb, M, 3)), z((nb, M, nmax), np.complex128))
    kept = broadband_modes(act, lw, bg)
    want_keep = np.zeros((nb, nmax), bool)
    for b in (0, 1):
        order = np.argsort(-resonant[b])
        cum = np.cumsum(resonant[b, order])
        n = int(np.argmax(resonant[b].sum() - cum <= RESONANT_REST * resonant[b].sum())) + 1
        want_keep[b, order[:n]] = True
    assert np.array_equal(bg.keep, want_keep)
    assert kept == want_keep.sum() and 0 < kept < 2 * 30  # (some kept, not every mode)
    held = np.einsum("bmk,bk->bm", static, want_keep)
    # (actuator 0: on body 0 its own side, +; on body 1 the parent's side, -, of a body whose sign is -1)
    assert np.allclose(lw.B1[0], B1[0] - held[0] - held[1], rtol=0, atol=1e-12)
    assert np.array_equal(lw.B1[2], B1[2])  # (its only body has no stream: nothing kept)
    assert np.array_equal(lw.B1[1], B1[1])


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


def real_modes(p, g, w, h, K, Kp, zero_row, row):
    """The arguments of modes_run and modes_heard for modes as resonant_run makes them: the
    recursion's a1, a2, its unit c (1 where g = 0: their input the row of zeros), the state
    (u, v) and each microphone's (A, B) (h: (microphones, Kp)), the fillers past K silent."""
    a1, a2, c = np.zeros(Kp), np.zeros(Kp), p.imag * g
    u, v, H = np.zeros(Kp), np.zeros(Kp), np.zeros((2 * len(h), Kp))
    row = row.copy()
    for k in range(Kp):
        if k >= K or c[k] == 0.0:
            c[k] = 1.0
            row[k] = zero_row
        if k < K:
            a1[k], a2[k] = real_coefficients(p[k])
            u[k], v[k] = real_state(p[k], c[k], w[k])
            for m in range(len(h)):
                H[2 * m, k], H[2 * m + 1, k] = heard_factors(p[k], c[k], h[m, k])
    return a1, a2, c, u, v, H, row


def test_the_modes_run_in_chunks_as_the_complex_recursion():
    """Eight modes of three bodies (two groups of four and one of one plus three silent
    fillers), over 300 samples in chunks of 128, 128, 44, as modes_run's real recursion of
    Im w in units of its input gain: one mode at 20 Hz of 48 kHz (its Im p = 0.0026: the
    real form divides by it and drifts by about an ulp of |p|^2 over Im p a sample: 3e-13),
    one with no input gain (its input the row of zeros): each body's heard sum and the end
    states match the complex recursion to 1e-12 of their scale."""
    rng = np.random.default_rng(1)
    L, K, Kp = 300, 9, 12
    f = np.zeros((4, L))
    f[:3] = rng.standard_normal((3, L))
    row = np.array([0, 0, 0, 0, 0, 1, 1, 2, 0, 0, 0, 0])
    p = 0.9995 * np.exp(1j * rng.uniform(0.5, 3.0, Kp))
    p[3] = np.exp(-30.0 / 48000) * np.exp(2j * np.pi * 20.0 / 48000)
    g = rng.standard_normal(Kp)
    g[6] = 0.0
    w = rng.standard_normal(Kp) + 1j * rng.standard_normal(Kp)
    p[K:] = g[K:] = w[K:] = 0.0  # (the fillers)
    h = rng.standard_normal((1, Kp)) + 1j * rng.standard_normal((1, Kp))
    y, w_end = reference(f, row, p, g, w, h[0], np.ones(Kp, bool))
    a1, a2, c, u, v, H, rows = real_modes(p, g, w, h, K, Kp, 3, row)
    bodies = ((0, 5), (5, 7), (7, 9))
    out = np.zeros((len(bodies), L))
    S = np.empty((Kp, 129))
    for s in range(0, L, 128):
        n = min(128, L - s)
        modes_run(S, f, s, n, rows, a1, a2, u, v)
        for i, (k0, k1) in enumerate(bodies):
            modes_heard(out, i, s, S, n, k0, k1, np.vstack([H] * len(bodies)))
    for i, (k0, k1) in enumerate(bodies):
        want = y[k0:k1].sum(axis=0)
        assert np.abs(out[i] - want).max() < 1e-12 * np.abs(want).max()
    got = np.array([complex_state(p[k], c[k], u[k], v[k]) for k in range(K)])
    assert np.abs(got - w_end[:K]).max() < 1e-12 * np.abs(w_end).max()
    assert not u[K:].any() and not v[K:].any()  # (the fillers stay silent)


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


def test_two_microphones_at_once_as_one_at_a_time():
    """modes_heard_pair (two microphones per pass over the modes' states, two modes a pass)
    adds what modes_heard adds for each microphone alone (to 1e-15 of its scale: the same
    products and sums, which the compiler may round in another order), into buffers at
    different delays, bodies of four and of three modes, nothing outside them; and each
    microphone's sum matches the complex recursion (reference) to 1e-12 of its scale."""
    rng = np.random.default_rng(4)
    L, K, Kp = 300, 7, 8
    f = np.zeros((3, L))
    f[:2] = rng.standard_normal((2, L))
    row = np.array([0, 0, 1, 1, 0, 1, 0, 0])
    p = 0.9995 * np.exp(1j * rng.uniform(0.5, 3.0, Kp))
    g = rng.standard_normal(Kp)
    w = rng.standard_normal(Kp) + 1j * rng.standard_normal(Kp)
    p[K:] = g[K:] = w[K:] = 0.0  # (the filler of the second group of four)
    h = rng.standard_normal((2, Kp)) + 1j * rng.standard_normal((2, Kp))
    a1, a2, c, u, v, H, rows = real_modes(p, g, w, h, K, Kp, 2, row)
    delays = (3, 17)
    pair = np.zeros((2, L + 20))
    alone = np.zeros((2, L + 20))
    S = np.empty((Kp, 129))
    for s in range(0, L, 128):
        n = min(128, L - s)
        modes_run(S, f, s, n, rows, a1, a2, u, v)
        for k0, k1 in ((0, 4), (4, K)):  # (two bodies)
            modes_heard_pair(pair, 0, delays[0] + s, delays[1] + s, S, n, k0, k1, H)
            for m in (0, 1):
                modes_heard(alone, m, delays[m] + s, S, n, k0, k1, H)
    assert np.abs(pair - alone).max() <= 1e-15 * np.abs(alone).max()  # (the same sums, up to their rounding's order)
    for m in (0, 1):
        y, _ = reference(f, row, p, g, w, h[m], np.ones(Kp, bool))
        want = y[:K].sum(axis=0)
        got = pair[m, delays[m]:delays[m] + L]
        assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()
        assert not pair[m, :delays[m]].any() and not pair[m, delays[m] + L:].any()


def test_a_free_mode_rings_out_from_its_pole_s_powers_as_the_recursion():
    """A mode no longer forced (its ring-out faded over the block) heard from the pole's
    powers (pole_powers: doubling, p^t within 5e-14 of numpy's p**t over 128 samples) over a block
    of 300 samples in chunks of 128 (free_heard) matches the complex recursion without force
    faded linearly over the block (reference, not steady) to 1e-12 of its scale, at a delay,
    nothing written outside the block or into another microphone's row."""
    rng = np.random.default_rng(5)
    L = 300
    pw = np.empty((2, 128))
    for p in (0.9995 * np.exp(0.7j), 0.98 * np.exp(2.9j), 1.0 + 0.0j):
        pc = pole_powers(pw, p)
        want = p ** np.arange(128)
        assert np.abs(pw[0] + 1j * pw[1] - want).max() < 5e-14  # (128 products' rounding: 128 eps = 2.8e-14)
        assert abs(pc - p ** 128) < 5e-14
        w = complex(rng.standard_normal(), rng.standard_normal())
        h = complex(rng.standard_normal(), rng.standard_normal())
        fade = (L - np.arange(L)) / L
        out = np.zeros((2, L + 10))
        free_heard(out, 1, 4, pw, pc, h * w, fade)
        assert not out[0].any()
        out = out[1]
        y, _ = reference(np.zeros((1, L)), np.zeros(1, np.int64), np.array([p]), np.zeros(1), np.array([w]),
                         np.array([h]), np.array([False]))
        assert np.abs(out[4:4 + L] - y[0]).max() < 1e-12 * np.abs(y[0]).max()
        assert not out[:4].any() and not out[4 + L:].any()


def test_the_route_turns_on_above_on_and_off_only_after_the_hold_below_off():
    """One actuator, blocks of 10 ms at 1 kHz: a share above RESONANT_ON turns the route on;
    between OFF and ON it stays as it was; below OFF it stays on for ROUTE_HOLD_S (a share
    back above OFF meanwhile starts the hold again) and then turns off; without a hold
    array (length 0) it turns off at the first block below."""
    fs, L = 1000.0, 10
    blocks = int(ROUTE_HOLD_S * fs) // L  # (blocks below OFF the hold rides out)

    def run(shares, held):
        lw = LineWeights(*(np.zeros((0, 1), complex),) * 2, np.zeros((1, 1)), np.zeros((1, 1)), np.zeros(1, np.int64),
                         np.zeros(1, np.bool_), np.zeros((1, 2)), held=held)
        out = []
        for s in shares:
            lw.power[0] = s, 1.0
            broadband_route(lw, L, fs)
            out.append(bool(lw.exact[0]))
        return out

    mid, low, high = 0.5 * (RESONANT_ON + RESONANT_OFF), 0.5 * RESONANT_OFF, 2.0 * RESONANT_ON
    assert run([mid, high, mid], np.zeros(1, np.int64)) == [False, True, True]
    below = [low] * (blocks + 1)
    assert run([high] + below, np.zeros(1, np.int64)) == [True] * (blocks + 1) + [False]
    assert run([high] + [low] * (blocks - 1) + [mid] + below, np.zeros(1, np.int64)) == [True] * (2 * blocks + 1) + [False]
    assert run([high, low, low], np.zeros(0, np.int64)) == [True, False, False]


def test_a_line_crossing_a_resonance_leaves_no_gap_in_the_links_noise():
    """The driven arm (``scripts/arm_demo.py``, servo, speed rising): while a tone crosses
    one of the link's resonances its share of what is heard jumps and the resonant share
    falls below RESONANT_OFF for ~8 ms; the links' 8-12 kHz noise at the air microphone, in
    2 ms frames from 0.2 s to 0.9 s, stays within 20 dB of its median (measured 12.3 dB; without
    the hold a 36 dB gap at 0.83 s)."""
    import math

    import mujoco
    from scipy.signal import butter, sosfilt

    from mjsound.sim.simulator import AudioSimulator

    arm = (Path(__file__).parents[1] / "scripts" / "arm_demo.py").read_text()
    xml = arm.split('ARM = """', 1)[1].split('"""', 1)[0]
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.6, 0.6, 0.8]], progress=False, actuators={"shoulder": "servo"})
    out = []
    for i in range(900):
        d.ctrl[0] = 0.3 + 2.7 * math.sin(math.pi * i / 4000)
        mujoco.mj_step(m, d)
        out.append(sim.step())
    fs = sim.sample_rate
    x = sosfilt(butter(4, [8000, 12000], "bandpass", fs=fs, output="sos"), np.concatenate(out, axis=1)[0])
    frames = x[int(0.2 * fs):int(0.9 * fs)].reshape(-1, int(0.002 * fs))
    db = 10 * np.log10(np.mean(frames ** 2, axis=1) + 1e-30)
    assert db.min() > np.median(db) - 20.0, (np.argmin(db) * 2 + 200, np.median(db) - db.min())


def test_the_real_recursion_s_coefficients_are_the_pole_s_rounded_once():
    """real_coefficients: a1 = 2 Re p exactly, a2 the float nearest -|p|^2 (Fractions: the
    floats' exact values; half an ulp at most, where numpy's -|p|^2 is up to an ulp off)."""
    from fractions import Fraction
    rng = np.random.default_rng(7)
    for p in np.exp(-rng.uniform(1e-5, 1e-2, 200)) * np.exp(1j * rng.uniform(1e-3, 3.1, 200)):
        a1, a2 = real_coefficients(p)
        want = -(Fraction(p.real) ** 2 + Fraction(p.imag) ** 2)
        assert a1 == 2 * p.real
        err = abs(Fraction(a2) - want)
        assert err <= abs(Fraction(np.spacing(a2))) / 2
        assert err <= abs(Fraction(np.nextafter(a2, 0.0)) - want) and err <= abs(Fraction(np.nextafter(a2, -2.0)) - want)
