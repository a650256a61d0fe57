"""Modal models from recordings (mjsound.fit): round trip, material fitting, sound design,
bad input and the CLI."""

import json
import warnings

import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.fit import FitResult, FitWarning, fit_material, fit_recording, render_excitation
from mjsound.synth.synthesizer import Synthesizer

FS = 48000
C = 343.0


def random_model(seed, n=16, f_lo=200.0, f_hi=10000.0, d_lo=2.0, d_hi=60.0):
    """A one-point model with n modes (>= 2 % apart), log-uniform frequencies and decays and
    random signed amplitudes; returns (model, damped f, d, signed amplitude at 1 m for 1 N s)."""
    rng = np.random.default_rng(seed)
    while True:
        f = np.sort(np.exp(rng.uniform(np.log(f_lo), np.log(f_hi), n)))
        if np.all(np.diff(np.log(f)) > 0.02):
            break
    d = np.exp(rng.uniform(np.log(d_lo), np.log(d_hi), n))
    A = np.exp(rng.uniform(np.log(0.05), np.log(1.0), n)) * rng.choice([-1.0, 1.0], n)
    wd = 2 * np.pi * f
    sh = np.zeros((1, 3, n))
    sh[0, 2] = 1.0
    m = ModalModel(np.sqrt(wd**2 + d**2) / (2 * np.pi), d, [[0, 0, 0]], [[0, 0, 1]], sh, A * wd,
                   get_material("steel"))
    return m, f, d, A


def strike(model, t_imp=0.05, T=1.0, point=(0, 0, 0), impulse=(0, 0, 1.0)):
    """Noise-free recording of one impact through the Synthesizer (mic 1 m away)."""
    # a mic off every axis of the box, where no mode of it has a node
    syn = Synthesizer(FS, microphones=[[0.48, 0.6, 0.64]], dtype="float64", cull_db=None)
    syn.add_object("o", model)
    syn.impact("o", point, impulse, t_imp, pulse_s=0.0)
    return syn.render(int(T * FS))[0].astype(np.float64)


def add_noise(y, snr_db, seed=0):
    rng = np.random.default_rng(seed)
    return y + rng.standard_normal(len(y)) * np.sqrt(np.mean(y**2) / 10 ** (snr_db / 10))


def match(fit, f):
    return int(np.argmin(np.abs(fit.damped_frequencies_hz - f)))


# ---------------------------------------------------------------- round trip
@pytest.mark.parametrize("seed", [0, 3])
def test_round_trip_30db_snr(seed):
    model, f, d, A = random_model(seed)
    clean = strike(model)
    rec = add_noise(clean, 30.0, seed)
    fit = fit_recording(rec, FS)
    strongest = np.argsort(-np.abs(A))[:10]
    for i in strongest:
        j = match(fit, f[i])
        assert abs(fit.damped_frequencies_hz[j] / f[i] - 1) < 0.005, (f[i], fit.damped_frequencies_hz[j])
        assert abs(fit.decay_per_s[j] / d[i] - 1) < 0.10, (f[i], d[i], fit.decay_per_s[j])
        assert abs(fit.gains[j] / A[i] - 1) < 0.10
    # white noise at 30 dB SNR is what the model cannot explain
    assert -33 < fit.residual_db < -27
    # onset: impact time + propagation delay 1 m / c, to well below a sample
    assert fit.impulse_like
    assert abs(fit.onset_s - (0.05 + 1 / C)) < 0.1 / FS
    assert fit.warnings == []


def test_fitted_model_plays_in_synthesizer(tmp_path):
    model, f, d, A = random_model(1, n=12)
    clean = strike(model)
    fit = fit_recording(add_noise(clean, 40.0, 1), FS)
    m = fit.to_model(mass_kg=0.3)
    assert m.info["fitted"] is True and len(m.points) == 1 and m.method == "fitted"
    m.save(tmp_path / "fit.npz")
    m2 = ModalModel.load(tmp_path / "fit.npz")
    assert m2.info["fitted"] is True
    np.testing.assert_allclose(m2.radiation, m.radiation)
    # a 1 N s impulse along +z, 1 m away, replays the recording
    # a mic off every axis of the box, where no mode of it has a node
    syn = Synthesizer(FS, microphones=[[0.48, 0.6, 0.64]], dtype="float64", cull_db=None)
    syn.add_object("fitted", m2)
    syn.impact("fitted", [0, 0, 0], [0, 0, 1.0], fit.onset_s - 1 / C, pulse_s=0.0)
    y = syn.render(len(clean))[0]
    err = 10 * np.log10(np.sum((y - clean) ** 2) / np.sum(clean**2))
    assert err < -30, err
    # the closed form of the fit agrees too
    z = fit.synthesize(len(clean))
    assert 10 * np.log10(np.sum((z - clean) ** 2) / np.sum(clean**2)) < -30


def test_n_modes_keeps_the_most_energetic():
    model, f, d, A = random_model(2, n=14)
    rec = add_noise(strike(model), 35.0, 2)
    full = fit_recording(rec, FS)
    few = fit_recording(rec, FS, n_modes=5)
    assert few.n_modes == 5
    top = np.sort(full.frequencies_hz[np.argsort(-full.energies())[:5]])
    np.testing.assert_allclose(np.sort(few.frequencies_hz), top, rtol=1e-3)
    assert few.residual_db > full.residual_db


def test_multichannel_mix_and_channel_pick():
    model, f, d, A = random_model(4, n=8)
    clean = strike(model)
    stereo = np.stack([add_noise(clean, 40, 1), add_noise(0.5 * clean, 40, 2)], axis=1)  # (n, 2)
    mix = fit_recording(stereo, FS)
    right = fit_recording(stereo.T, FS, channel=1)  # (channels, n) layout works too
    assert mix.channels == "mix of 2" and right.channels == "channel 1 of 2"
    i = int(np.argmax(np.abs(A)))
    assert abs(mix.gains[match(mix, f[i])] / (0.75 * A[i]) - 1) < 0.05
    assert abs(right.gains[match(right, f[i])] / (0.5 * A[i]) - 1) < 0.05


# ---------------------------------------------------------------- bad input
def test_silent_and_noise_only_raise():
    with pytest.raises(ValueError, match="silent"):
        fit_recording(np.zeros(FS), FS)
    noise = np.random.default_rng(0).standard_normal(FS) * 1e-3
    with pytest.raises(ValueError, match="no impact found.*noise floor"):
        fit_recording(noise, FS)
    with pytest.raises(ValueError, match="NaN"):
        fit_recording(np.full(FS, np.nan), FS)
    with pytest.raises(ValueError, match="sample_rate"):
        fit_recording(np.ones(100))


def test_too_short_raises():
    model, *_ = random_model(0, n=6)
    y = strike(model, t_imp=0.001, T=0.3)
    with pytest.raises(ValueError, match="too short"):
        fit_recording(y[: int(0.01 * FS)], FS)
    with pytest.raises(ValueError, match="too short"):  # onset 5 ms before the end
        fit_recording(np.concatenate([np.zeros(int(0.1 * FS)), y[: int(0.006 * FS)]]), FS)
    with pytest.raises(ValueError, match="too short for 400 modes"):
        fit_recording(y[: int(0.03 * FS)], FS, n_modes=400)


def test_clipped_warns_and_still_fits():
    model, f, d, A = random_model(5, n=8, d_hi=20.0)
    clean = strike(model)
    rec = add_noise(clean, 40.0, 5)
    clipped = np.clip(rec, -0.5 * np.abs(rec).max(), 0.5 * np.abs(rec).max())
    with pytest.warns(FitWarning, match="clipped.*lower gain"):
        fit = fit_recording(clipped, FS)
    assert fit.analysis_start_s > 0.053  # starts after the clipped samples
    i = int(np.argmax(np.abs(A)))
    j = match(fit, f[i])
    assert abs(fit.damped_frequencies_hz[j] / f[i] - 1) < 0.005
    assert abs(fit.decay_per_s[j] / d[i] - 1) < 0.10
    assert any("clipped" in w for w in fit.warnings)


def test_clipped_too_long_raises():
    t = np.arange(FS // 2) / FS
    y = np.clip(50 * np.sin(2 * np.pi * 440 * t) * np.exp(-2 * t), -1, 1)
    with pytest.raises(ValueError, match="clipped for too long.*lower gain"):
        fit_recording(y, FS)


def test_second_impact_warns_and_fits_the_first():
    model, f, d, A = random_model(6, n=8, d_lo=20.0, d_hi=60.0)
    # a mic off every axis of the box, where no mode of it has a node
    syn = Synthesizer(FS, microphones=[[0.48, 0.6, 0.64]], dtype="float64", cull_db=None)
    syn.add_object("o", model)
    syn.impact("o", [0, 0, 0], [0, 0, 1.0], 0.05, pulse_s=0.0)
    syn.impact("o", [0, 0, 0], [0, 0, 1.0], 0.45, pulse_s=0.0)
    rec = add_noise(syn.render(FS)[0].astype(np.float64), 30.0, 6)
    with pytest.warns(FitWarning, match="more than one impact.*Trim"):
        fit = fit_recording(rec, FS)
    assert fit.analysis_end_s < 0.46
    i = int(np.argmax(np.abs(A)))
    assert abs(fit.decay_per_s[match(fit, f[i])] / d[i] - 1) < 0.10


def test_beating_pair_is_not_a_second_impact():
    """Two modes 3 Hz apart beat (deep envelope nulls): no multi-event warning."""
    f = np.array([1000.0, 1003.0])
    d = np.array([3.0, 3.0])
    sh = np.zeros((1, 3, 2))
    sh[0, 2] = 1.0
    m = ModalModel(f, d, [[0, 0, 0]], [[0, 0, 1]], sh, [1.0 * 2 * np.pi * 1000, 1.0 * 2 * np.pi * 1003],
                   get_material("steel"))
    rec = add_noise(strike(m, T=1.5), 30.0, 7)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        fit = fit_recording(rec, FS)
    assert fit.n_modes == 2
    np.testing.assert_allclose(np.sort(fit.damped_frequencies_hz), np.sqrt(f**2 - (d / 2 / np.pi) ** 2), rtol=1e-4)


# ---------------------------------------------------------------- sound design
def test_render_excitation_impulse_linearity_convolution():
    model, f, d, A = random_model(8, n=6, d_lo=20.0, d_hi=60.0)
    n = 4000
    delta = np.zeros(n)
    delta[0] = FS  # 1 N for one sample = 1 N s
    h = render_excitation(model, delta, FS, tail_s=0.0)
    t = np.arange(n) / FS
    ref = (A[:, None] * np.exp(-d[:, None] * t) * np.sin(2 * np.pi * f[:, None] * t)).sum(0)
    assert np.abs(h - ref).max() < 1e-6 * np.abs(ref).max()
    # the same as an impact of 1 N s through the synthesizer (no propagation delay)
    syn = Synthesizer(FS, microphones=[[0, 0, 1]], dtype="float64", cull_db=None, speed_of_sound=1e12)
    syn.add_object("o", model)
    syn.impact("o", [0, 0, 0], [0, 0, 1.0], 0.0, pulse_s=0.0)
    assert np.abs(syn.render(n)[0] - h).max() < 1e-6 * np.abs(h).max()
    rng = np.random.default_rng(0)
    s1 = rng.standard_normal(800)
    s2 = np.sin(2 * np.pi * 300 * np.arange(800) / FS)
    y1 = render_excitation(model, s1, FS, tail_s=0.05)
    y2 = render_excitation(model, s2, FS, tail_s=0.05)
    y12 = render_excitation(model, 2 * s1 - 3 * s2, FS, tail_s=0.05)
    assert np.abs(y12 - (2 * y1 - 3 * y2)).max() < 1e-6 * np.abs(y12).max()  # float32 output
    conv = np.convolve(s1 / FS, h)[: len(y1)]
    assert np.abs(y1 - conv).max() < 1e-6 * np.abs(conv).max()


def test_render_excitation_of_a_fit_replays_the_recording():
    model, f, d, A = random_model(9, n=10)
    clean = strike(model, t_imp=0.0, T=0.5)
    fit = fit_recording(add_noise(np.concatenate([np.zeros(480), clean]), 40.0, 9), FS)
    delta = np.zeros(1)
    delta[0] = FS
    y = render_excitation(fit.to_model(), delta, FS, tail_s=0.3)
    t = np.arange(int(0.3 * FS)) / FS
    z = (A[:, None] * np.exp(-d[:, None] * t) * np.sin(2 * np.pi * f[:, None] * t)).sum(0)
    assert 10 * np.log10(np.sum((y[: len(z)] - z) ** 2) / np.sum(z**2)) < -30


# ---------------------------------------------------------------- material fitting
def test_fit_material_recovers_stiffness_and_damping():
    import mjsound

    mesh = "box:0.2,0.03,0.01"
    base = get_material("aluminium")
    E_scale, alpha, beta = 1.21, 20.0, 1e-7  # frequencies x 1.1
    true = base.scaled(stiffness=E_scale)
    from dataclasses import replace

    true = replace(true, alpha=alpha, beta=beta, name="true")
    truth = mjsound.analyze(mesh, true, f_max=9000, cache=False, error_estimate=False)
    assert truth.n_modes >= 4
    # strike a corner obliquely so that every mode sounds
    corner = truth.points[np.argmax(truth.points.sum(1))]
    rec = strike(truth, t_imp=0.02, T=1.0, point=corner, impulse=-np.array([1.0, 1.0, 1.0]) * 1e-2)
    rec = add_noise(rec, 40.0, 10)
    res = fit_material(mesh, rec, "aluminium", sample_rate=FS, f_max=8100)
    assert len(res.matches) >= 4
    assert abs(res.stiffness_scale / E_scale - 1) < 0.005
    assert abs(res.alpha / alpha - 1) < 0.15
    assert abs(res.beta / beta - 1) < 0.10
    assert res.material.name == "fitted" and res.material.rho == base.rho
    assert res.rms_cents < 5
    # reusable: a material, analysed on another mesh like any other
    assert res.material.E == pytest.approx(base.E * res.stiffness_scale)


def test_fit_material_with_a_given_model_and_no_match():
    fit = FitResult(np.array([123.0]), np.array([5.0]), np.array([1.0]), np.array([0.0]), FS)
    m, *_ = random_model(0, n=4, f_lo=2000, f_hi=4000)
    with pytest.raises(ValueError, match="no analysed mode matches"):
        fit_material(None, fit, model=m, scale_range=(0.9, 1.1))


# ---------------------------------------------------------------- CLI
def test_cli_fit_json(tmp_path, capsys):
    import soundfile as sf

    from mjsound.cli import main

    model, f, d, A = random_model(11, n=8)
    rec = add_noise(strike(model), 35.0, 11)
    wav = tmp_path / "hit.wav"
    sf.write(wav, (rec / np.abs(rec).max() * 0.5).astype(np.float32), FS, subtype="FLOAT")
    out = tmp_path / "hit.npz"
    assert main(["fit", str(wav), "--json", "--modes", "6", "-o", str(out)]) == 0
    js = json.loads(capsys.readouterr().out)
    for key in ("frequencies_hz", "decay_per_s", "amplitudes", "residual_db"):
        assert key in js
    assert len(js["frequencies_hz"]) == 6
    m = ModalModel.load(out)
    assert m.info["fitted"] and m.n_modes == 6
    # a bad file is a clear error, not a traceback
    bad = tmp_path / "silent.wav"
    sf.write(bad, np.zeros(FS, np.float32), FS)
    assert main(["fit", str(bad)]) == 2
    assert "silent" in capsys.readouterr().err


# ---------------------------------------------------------------- what a recording supports (issue 17)
@pytest.mark.parametrize("seed", [0, 3])
def test_noise_free_strike_gives_exactly_its_modes(seed):
    model, f, d, A = random_model(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        fit = fit_recording(strike(model), FS)
    assert fit.n_modes == fit.modes_supported == len(f)  # nothing invented
    for i in range(len(f)):
        j = match(fit, f[i])
        assert abs(fit.damped_frequencies_hz[j] / f[i] - 1) < 1e-4
        assert abs(fit.gains[j] / A[i] - 1) < 0.01


def test_one_pure_decay_is_one_mode():
    t = np.arange(FS) / FS
    fit = fit_recording(np.exp(-3 * t) * np.sin(2 * np.pi * 440 * t), FS)
    assert fit.n_modes == 1
    assert abs(fit.damped_frequencies_hz[0] - 440) < 1e-3 and abs(fit.amplitudes[0] - 1) < 1e-3


def test_asking_for_more_modes_than_supported_warns_and_invents_none():
    model, f, d, A = random_model(0)
    with pytest.warns(FitWarning, match="30 modes asked for, but the recording supports only 16"):
        fit = fit_recording(strike(model), FS, n_modes=30)
    assert fit.n_modes == fit.modes_supported == 16
    fit = fit_recording(strike(model), FS, n_modes=5)
    assert fit.n_modes == 5 and fit.modes_supported == 16
    assert fit.summary()["modes_supported"] == 16


def test_repeated_identical_strikes_are_not_clipped():
    model, f, d, A = random_model(1, n=4, d_lo=200.0, d_hi=400.0)
    one = strike(model, t_imp=0.0, T=0.02)
    rec = np.concatenate([np.zeros(2400), np.tile(one, 600)])  # 600 identical strikes, 20 ms apart
    with pytest.warns(FitWarning) as got:
        fit = fit_recording(rec, FS)
    msgs = [str(w.message) for w in got]
    assert not any("clipped" in m for m in msgs) and any("more than one impact" in m for m in msgs)
    assert fit.n_modes >= 1


def test_quiet_16_bit_strike_is_not_clipped_but_a_full_scale_one_is(tmp_path):
    import soundfile as sf

    model, f, d, A = random_model(2, n=6, d_hi=20.0)
    clean = strike(model)
    quiet = clean / np.abs(clean).max() * 10 ** (-60 / 20)  # -60 dBFS: 33 steps of 16 bits
    sf.write(tmp_path / "quiet.wav", quiet, FS, subtype="PCM_16")
    fit = fit_recording(tmp_path / "quiet.wav")
    assert not any("clipped" in w for w in fit.warnings)
    i = int(np.argmax(np.abs(A)))
    assert abs(fit.damped_frequencies_hz[match(fit, f[i])] / f[i] - 1) < 0.005
    loud = np.clip(clean / np.abs(clean).max() * 1.5, -1, 1)
    sf.write(tmp_path / "loud.wav", loud, FS, subtype="PCM_16")
    with pytest.warns(FitWarning, match="clipped"):
        fit_recording(tmp_path / "loud.wav")
