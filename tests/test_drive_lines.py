"""The lines' rendering of actuator noise (mjsound.synth.drive_lines) against the exact one
(the drive forces through the links' modes, ``rendering="modal"``): the same lines at their
frequencies; what it leaves out is the modes' own ringing (their transients)."""

import math
from dataclasses import replace

import mujoco
import numpy as np

from mjsound.sim.actuators import PRESETS
from mjsound.sim.simulator import AudioSimulator
from test_actuators import FS, arm_xml

#: the servo's tones (no broadband: the lines' static broadband is not the exact one's; no housing:
#: the exact rendering has none)
TONES = replace(PRESETS["servo"], broadband=0.0, housing=0.0)
STEPS = 1500  # 1.5 s at 1 ms


def render(rendering):
    """The arm at a constant speed (2 rad/s); (audio (3, n): air, link contact, far contact;
    the simulator)."""
    m = mujoco.MjModel.from_xml_string(arm_xml())
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"], progress=False,
                         sample_rate=FS, quality="draft", actuators={"m": TONES})
    assert sim.actuators.rendering == "lines"  # (the default where the scene has a pulse track)
    sim.actuators.rendering = rendering
    out = []
    for _ in range(STEPS):
        d.ctrl[0] = 2.0
        mujoco.mj_step(m, d)
        out.append(sim.step())
    return np.concatenate(out, axis=1).astype(np.float64), sim, float(d.qvel[0])


def spectrum(x):
    """Magnitude spectrum of the last second (Hann window; 1 Hz bins)."""
    return np.abs(np.fft.rfft(x[-FS:] * np.hanning(FS)))


def test_lines_match_the_exact_rendering_at_their_frequencies():
    """Steady speed: at every tone's frequency the lines' level is the exact rendering's
    within 0.1 dB at the contact microphone and 0.4 dB in air, where the link turns under
    the microphone (measured: 0.03 and 0.28 dB)."""
    exact, sim, qd = render("modal")
    lines, _, _ = render("lines")
    rotor = TONES.reduction * qd
    freqs = [o * rotor / (2 * math.pi) for o, _ in TONES.tones]
    freqs = [f for f in freqs if 20.0 < f < 0.45 * FS]
    assert len(freqs) >= 8
    for ch, tol in ((1, 0.1), (0, 0.4)):
        E, L = spectrum(exact[ch]), spectrum(lines[ch])
        for f in freqs:
            k = int(round(f))
            band = slice(k - 2, k + 3)  # (the line's main lobe)
            e, li = np.sqrt(np.sum(E[band] ** 2)), np.sqrt(np.sum(L[band] ** 2))
            assert e > 0
            assert abs(20 * math.log10(li / e)) < tol, (ch, f, 20 * math.log10(li / e))


def test_what_the_lines_leave_out_is_the_links_ringing():
    """At the contact microphone the difference lines - exact lies at the driven bodies' mode
    frequencies (their free ringing since the start, which the steady state leaves out):
    10 Hz or more off every mode it is below 3 % of the exact rendering's RMS (measured
    1.5 %; 5 % with the modes' bins)."""
    exact, sim, _ = render("modal")
    lines, _, _ = render("lines")
    modes = np.concatenate([sim.synth.object_modes(n).damped_omega / (2 * math.pi) for n in ("link", "base")])
    f = np.arange(FS // 2 + 1)
    away = np.all(np.abs(f[:, None] - modes[None, :]) > 10.0, axis=1)  # (10 Hz off any mode)
    E, D = spectrum(exact[1]), spectrum(exact[1] - lines[1])
    assert np.sqrt(np.sum(D[away] ** 2)) < 0.03 * np.sqrt(np.sum(E ** 2))
    # and the far body (undriven, untouched) hears nothing in either
    assert np.abs(lines[2]).max() == 0.0 and np.abs(exact[2]).max() == 0.0


def test_the_resonant_broadband_matches_the_exact_rendering_and_stops_with_the_drive():
    """The servo (broadband noise near the link's modes: it goes through the modes the lines'
    kernel runs, drive_broadband.broadband_resonant) held at 2 rad/s, then stopped: the
    contact microphone's RMS is the exact rendering's within 2 % (measured 0.4 %), and a
    block after the joint stands still the lines are silent (their modes faded out)."""
    def run(rendering):
        m = mujoco.MjModel.from_xml_string(arm_xml())
        d = mujoco.MjData(m)
        sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link"], progress=False,
                             sample_rate=FS, quality="draft", actuators={"m": "servo"})
        sim.actuators.rendering = rendering
        out, kept = [], 0
        for i in range(1000):
            d.ctrl[0] = 2.0
            mujoco.mj_step(m, d)
            out.append(sim.step())
            kept = max(kept, sim.actuators.modes_kept)
        held = np.concatenate(out, axis=1).astype(np.float64)[1, FS // 4:]
        d.qvel[:] = 0.0  # (the joint stands still: the drive's force scale is 0)
        m.actuator_gainprm[0, 0] = m.actuator_biasprm[0, 2] = 0.0
        after = [sim.step() for _ in (mujoco.mj_step(m, d) for _ in range(200))]
        return held, kept, np.concatenate(after, axis=1).astype(np.float64)[1]

    exact, _, _ = run("modal")
    lines, kept, after = run("lines")
    assert kept > 0  # (the resonant route was taken)
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))  # noqa: E731
    assert abs(rms(lines) / rms(exact) - 1.0) < 0.02
    assert np.abs(after[-FS // 20:]).max() == 0.0  # (the last 50 ms: nothing left)


def _render_state(orders, w0, w1, M=3, L=800, seed=0):
    """A synthetic :func:`lines_render` state: actuators ``j`` with components ``orders[j]``,
    rotor speeds ``w0 -> w1`` [rad/s] over the block, random weights and phases, no broadband,
    ``M`` microphones at different delays; (track, act, lw, n0, L, fs, F)."""
    from mjsound.synth.drive_lines import Actuators, LineWeights
    from mjsound.synth.drive_tones import DRIVE, NOISE, TONE
    from mjsound.synth.records import TRACK, TrackState

    rng = np.random.default_rng(seed)
    J = len(orders)
    comp_off = np.zeros(J + 1, np.int64)
    comp_off[1:] = np.cumsum([len(o) for o in orders])
    C = int(comp_off[-1])
    tones = np.zeros(C, TONE)
    tones["order"] = [o for oo in orders for o in oo]
    tones["amp"] = 1.0
    tones["phase"] = rng.uniform(0.0, 2.0 * math.pi, C)
    z = np.zeros
    act = Actuators(comp_off, tones, z(J, NOISE), z(J, DRIVE), z(1, np.int64), z(0, np.int64), z(0, np.int64),
                    z(0), np.ones(J, np.bool_), np.array(w0, float), np.array(w1, float),
                    rng.uniform(0.5, 1.0, J), rng.uniform(0.5, 1.0, J), z(J))
    cw = lambda: rng.standard_normal((C, M)) + 1j * rng.standard_normal((C, M))  # noqa: E731
    lw = LineWeights(cw(), cw(), z((J, M)), z((J, M)), np.array([3, 0, 11, 7][:M], np.int64), z(J, np.bool_), z((J, 2)))
    rec = np.zeros(1, TRACK)
    rec[0]["fs"] = FS
    track = TrackState(rec, z((M, 4096)), z(1, np.complex128), z(1), z(1, np.complex128))
    return track, act, lw, 200, L, float(FS), z((J, L))


def _lines_float64(act, lw, n0, L, fs, M, size):
    """The plain sum: each line ``Im(V_k e^{j phi_k})``, ``phi_k = ph + s0 k + ds k (k - 1) / 2``,
    ``V_k`` linear from ``a0 W0`` to ``a1 W1``, on the samples whose increment is under 0.45 fs;
    (the sum (M, size), the number of lines heard on all, some and none of the block's samples)."""
    out = np.zeros((M, size))
    heard = [0, 0, 0]
    k = np.arange(L)
    for j in range(len(act.w0)):
        for c in range(act.comp_off[j], act.comp_off[j + 1]):
            o = act.tones[c]["order"]
            s0, ds = o * act.w0[j] / fs, o * (act.w1[j] - act.w0[j]) / L / fs
            phi = act.tones[c]["phase"] + s0 * k + ds * k * (k - 1) / 2
            on = np.abs(s0 + ds * k) < 2 * math.pi * 0.45
            heard[0 if on.all() else (1 if on.any() else 2)] += 1
            for m in range(M):
                v0 = act.a0[j] * lw.W0[c, m]
                V = v0 + (act.a1[j] * lw.W1[c, m] - v0) * k / L
                out[m, n0 + lw.Dm[m] + k] += np.where(on, np.imag(V * np.exp(1j * phi)), 0.0)
    return out, heard


def test_lines_render_is_the_float64_sum_of_its_lines():
    """The kernel's lines (float32 lanes restarted from float64 every 64 samples, the lines
    crossing the cut-off in part, one whose weights are 0 left out, harmonics made of the
    lines before them with phases in step and not, two channels a pass and a third alone)
    against the plain float64 sum of each line: the difference within 1e-4 of the peak and its RMS within 3e-5
    of the sum's (float32's rounding over a restart; measured 2.4e-5 and 1.5e-5), the phases
    advanced as drive_tones.advance_phase and the end weights made the next block's start."""
    from mjsound.synth.drive_lines import lines_render
    from mjsound.synth.drive_tones import advance_phase

    # (a servo-like and a qdd-like actuator at speeds whose high components cross 0.45 fs, one
    # reversing through 0, one held: lines sounding all, part and none of the block)
    orders = [[1 / 3, 2 / 3, 1.0, 2.0, 4.0, 6.0, 6.0, 10.0, 20.0, 30.0], [10.0, 20.0, 30.0, 126.0, 252.0],
              [3.0, 7.5, 9.0]]
    track, act, lw, n0, L, fs, F = _render_state(orders, [3000.0, -20.0, 20000.0], [-1000.0, 400.0, 20000.0])
    M = lw.W0.shape[1]
    lw.W0[1] = lw.W1[1] = 0.0  # (a line heard nowhere: not rendered)
    qdd = slice(act.comp_off[1], act.comp_off[2])  # (its phases order x rotor angle, as from the start)
    act.tones["phase"][qdd] = (act.tones["order"][qdd] * 1234.5678) % (2 * math.pi)
    want, heard = _lines_float64(act, lw, n0, L, fs, M, track.acc.shape[1])
    assert min(heard) >= 3  # (lines heard all the block, part of it and not at all)
    ph0, s0, ds = act.tones["phase"].copy(), act.tones["order"] * np.repeat(act.w0, np.diff(act.comp_off)) / fs, \
        act.tones["order"] * np.repeat((act.w1 - act.w0) / L, np.diff(act.comp_off)) / fs
    W1 = lw.W1.copy()
    n = lines_render(track, act, lw, n0, L, fs, F)
    assert n == heard[0] + heard[1] - 1
    d = track.acc - want
    assert np.abs(d).max() < 1e-4 * np.abs(want).max()
    assert np.sqrt(np.mean(d ** 2)) < 3e-5 * np.sqrt(np.mean(want ** 2))
    assert np.allclose(act.tones["phase"], [advance_phase(p, a, b, L) for p, a, b in zip(ph0, s0, ds)], rtol=0,
                       atol=1e-12)
    assert np.array_equal(lw.W0, W1)


def test_lines_render_with_kept_working_arrays_is_the_same_as_without():
    """The working arrays kept between blocks (LineWeights.scratch, drive_lines.lines_scratch):
    a block rendered with them (lines and the static broadband), after they served another block
    with other lines (more of them, another actuator crossing the cut-off), is bit for bit the
    block rendered with arrays of its own; arrays too small for the block (lines, microphones, samples) are replaced for the call."""
    from mjsound.synth.drive_lines import lines_render, lines_scratch

    def block(scratch, orders, w0, w1, seed, M=3, L=800):
        track, act, lw, n0, L, fs, F = _render_state(orders, w0, w1, M=M, L=L, seed=seed)
        rng = np.random.default_rng(seed)
        act.noise["broadband"], act.noise["rng"] = 0.3, rng.integers(1, 2 ** 62, len(w0))  # (the static broadband)
        lw.B0[:], lw.B1[:] = rng.uniform(0.5, 1.0, lw.B0.shape), rng.uniform(0.5, 1.0, lw.B1.shape)
        lw = lw._replace(scratch=scratch)
        n = lines_render(track, act, lw, n0, L, fs, F)
        return track.acc.copy(), n

    big = [[1 / 3, 2 / 3, 1.0, 2.0, 4.0, 6.0, 10.0, 20.0, 30.0], [10.0, 20.0, 30.0, 126.0, 252.0], [3.0, 7.5, 9.0]]
    small = [[10.0, 20.0, 30.0, 126.0, 252.0], [1.0, 2.0]]
    kept = lines_scratch(len(sum(big, [])), 3, 800, len(big))
    block(kept, big, [3000.0, -20.0, 20000.0], [-1000.0, 400.0, 20000.0], 1)  # (another block first)
    for orders, w0, w1 in ((small, [50.0, 900.0], [60.0, 700.0]), (big, [20.0, 300.0, 5.0], [25.0, 280.0, 6.0])):
        want, n = block(lines_scratch(0, 0, 0), orders, w0, w1, 2)
        got, m = block(kept, orders, w0, w1, 2)
        assert n == m > 0
        assert np.array_equal(got, want)
    # (too few lines, microphones and samples for the block: its own arrays)
    want, n = block(lines_scratch(0, 0, 0), big, [20.0, 300.0, 5.0], [25.0, 280.0, 6.0], 3, M=4, L=1000)
    got, m = block(lines_scratch(4, 2, 100), big, [20.0, 300.0, 5.0], [25.0, 280.0, 6.0], 3, M=4, L=1000)
    assert n == m > 0 and np.array_equal(got, want)


def test_a_block_longer_than_the_kept_working_arrays_grows_them_first():
    """The kept working arrays hold blocks of up to twice the drives' cadence; a longer block
    (an ``advance`` of 200 ms in one call) has larger ones made before the kernel renders it
    (lines_drive's GROW_LINES: the kernels allocate nothing), and sounds bit for bit as with
    arrays made large enough from the start."""
    from mjsound.synth.drive_lines import lines_scratch

    outs = []
    for ahead in (False, True):
        m = mujoco.MjModel.from_xml_string(arm_xml())
        d = mujoco.MjData(m)
        sim = AudioSimulator(m, d, microphones=[[0.5, 0.5, 0.8]], contact_mics=["s_link", "s_far"], progress=False,
                             sample_rate=FS, quality="draft", actuators="qdd")
        sound = sim.actuators
        kept = sound.weights.scratch.buf.shape[0]
        assert kept == 2 * sound.cadence < 3200
        if ahead:
            sound.weights = sound.weights._replace(scratch=lines_scratch(len(sound.tones), sound.weights.W1.shape[1],
                                                                         4000, len(sound.ids)))
        out = []
        for _ in range(5):
            d.ctrl[0] = 2.0
            out.append(sim.advance(200))  # (one block of 3200 samples a call)
        assert sound.weights.scratch.buf.shape[0] == (4000 if ahead else 3200)
        outs.append(np.concatenate(out, axis=1))
    assert np.abs(outs[0][1]).max() > 0.0
    assert np.array_equal(outs[0], outs[1])
