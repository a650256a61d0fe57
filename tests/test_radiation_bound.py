"""The radiation efficiency bound (mjsound.modal.radiation_bound): a mode radiates at most
rho0 c omega sqrt(A_eff / 4 pi) at 1 m. The analysis caps each mode's pattern there where it
makes the model, so the stored pattern, its RMS, the radiation damping and what the
synthesizer hears agree."""

from __future__ import annotations

import numpy as np
import pytest

from mjsound import ModalModel, analyze, get_material
from mjsound.modal.radiation import AIR_DENSITY, SPEED_OF_SOUND, radiation_damping
from mjsound.modal.radiation_bound import cap_radiation, radiation_limit
from mjsound.modal.sph import degree_of, sphere_quadrature

#: boundary elements far too coarse for the modes (a level of 8 and one of 24 elements, 1
#: per wavelength, at 15 kHz on a 15 cm plate): their solves radiate up to ~25 dB over the bound
UNDER_RESOLVED = dict(n_max=40, n_min=10, budget=1e5, epw=1.0)
PLATE = ("box:0.15,0.1,0.004", "aluminium")
PLATE_KW = dict(f_max=15000, quality="draft", cache=False, error_estimate=False, progress=False,
                radiation=UNDER_RESOLVED)


def plate_model(radiation, area=0.02):
    """Two modes on four samples of a 0.02 m^2 surface, normals +z: mode 0 moves every sample
    by 1 / sqrt(kg) along z, mode 1 by 0.5 along z and 2 along x (only its normal part counts)."""
    pts = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]], float)
    nrm = np.tile([0.0, 0.0, 1.0], (4, 1))
    shapes = np.zeros((4, 3, 2))
    shapes[:, 2, 0] = 1.0
    shapes[:, 2, 1] = 0.5
    shapes[:, 0, 1] = 2.0
    f = np.array([500.0, 3000.0])
    w = 2 * np.pi * f
    mat = get_material("aluminium")
    rad = np.asarray(radiation, float)
    decay = 0.5 * (mat.alpha + mat.beta * w**2) + radiation_damping(rad, w)
    return ModalModel(f, decay, pts, nrm, shapes, rad, mat, mass_kg=0.1, info={"area_m2": area})


def test_the_limit_is_efficiency_one_of_the_normal_motion():
    model = plate_model([1.0, 1.0])
    w = 2 * np.pi * np.array([500.0, 3000.0])
    a = 0.02 / 4
    a_eff = np.array([4 * a * 1.0, 4 * a * 0.25])  # (the x motion of mode 1 radiates nothing)
    want = AIR_DENSITY * SPEED_OF_SOUND * w * np.sqrt(a_eff / (4 * np.pi))
    np.testing.assert_allclose(radiation_limit(model), want, rtol=1e-12)
    # W = 2 pi R_max^2 / (rho0 c) is rho0 c <v_n^2> A for a unit modal coordinate: efficiency 1
    power = 2 * np.pi * want**2 / (AIR_DENSITY * SPEED_OF_SOUND)
    np.testing.assert_allclose(power, AIR_DENSITY * SPEED_OF_SOUND * w**2 * a_eff / 2, rtol=1e-12)
    model.info.pop("area_m2")
    assert radiation_limit(model) is None


def test_a_pattern_over_the_limit_is_scaled_whole_and_the_rest_kept():
    rng = np.random.default_rng(3)
    coef = rng.normal(size=(3, 9)) + 1j * rng.normal(size=(3, 9))
    rms = np.linalg.norm(coef, axis=1) / np.sqrt(4 * np.pi)
    limit = np.array([2.0 * rms[0], rms[1] / 30.0, 0.0])  # under, 29.5 dB over, a mode with no normal motion
    r, c, over = cap_radiation(rms, coef, limit)
    assert r[0] == rms[0] and np.array_equal(c[0], coef[0]) and over[0] == 0.0
    assert r[1] == pytest.approx(limit[1], rel=1e-12)
    np.testing.assert_allclose(c[1], coef[1] / 30.0, rtol=1e-12)  # same shape, RMS at the limit
    assert np.linalg.norm(c[1]) / np.sqrt(4 * np.pi) == pytest.approx(limit[1], rel=1e-12)
    assert over[1] == pytest.approx(20 * np.log10(30.0), rel=1e-12)
    assert r[2] == 0.0 and np.all(c[2] == 0) and np.isfinite(over[2]) and over[2] > 100


@pytest.fixture(scope="module")
def capped_and_raw():
    """The under-resolved plate as analysed, and the same analysis with the cap left out."""
    import mjsound.modal.analyze as an

    capped = analyze(*PLATE, **PLATE_KW)
    keep = an.cap_radiation
    an.cap_radiation = lambda rms, coef, limit: (np.asarray(rms), np.asarray(coef), np.zeros(len(rms)))
    try:
        raw = analyze(*PLATE, **PLATE_KW)
    finally:
        an.cap_radiation = keep
    return capped, raw


def test_the_analysis_caps_pattern_rms_and_damping_alike(capped_and_raw):
    m, raw = capped_and_raw
    np.testing.assert_allclose(m.frequencies_hz, raw.frequencies_hz, rtol=1e-12)
    limit = radiation_limit(m)
    over = raw.radiation > limit * (1 + 1e-5)
    assert over.sum() >= 5 and (raw.radiation / limit).max() > 10  # (solves up to tens of dB over)
    info = m.info["radiation"]
    # what was capped, by how much, is in the model, and the error estimate says at least that
    capped_db = np.array(info["capped_db"])
    assert info["capped"] == over.sum() and np.array_equal(capped_db > 0, over)
    np.testing.assert_allclose(capped_db[over], 20 * np.log10(raw.radiation[over] / limit[over]), atol=0.01)
    est = np.array([np.nan if e is None else e for e in info["error_db"]])
    assert np.all(est[over] >= capped_db[over])
    np.testing.assert_array_equal(est[~over], [np.nan if e is None else e for e in
                                               np.array(raw.info["radiation"]["error_db"], object)[~over]])
    # radiation: at most the limit, the limit where capped, untouched elsewhere
    assert np.all(m.radiation <= limit * (1 + 1e-6))
    np.testing.assert_allclose(m.radiation[over], limit[over], rtol=1e-6)
    np.testing.assert_array_equal(m.radiation[~over], raw.radiation[~over])
    # the pattern: the raw one scaled by limit / raw, every direction alike; its RMS is radiation
    d, w = sphere_quadrature(degree_of(m.radiation_sh.shape[1]))  # (|F|^2 integrated exactly)
    F, Fr = m.radiation_pattern(d), raw.radiation_pattern(d)
    scale = np.where(over, limit / raw.radiation, 1.0)
    np.testing.assert_allclose(F, Fr * scale[None, :], rtol=1e-5, atol=1e-6 * np.abs(F).max())
    np.testing.assert_allclose(np.sqrt(w @ np.abs(F) ** 2 / (4 * np.pi)), m.radiation, rtol=1e-5)
    # the radiation damping is the capped radiation's
    mat = m.material
    w0 = 2 * np.pi * m.frequencies_hz
    np.testing.assert_allclose(m.decay_per_s, 0.5 * (mat.alpha + mat.beta * w0**2) + radiation_damping(m.radiation, w0),
                               rtol=1e-9)
    assert np.all(m.decay_per_s[over] < raw.decay_per_s[over])
    # and select keeps the per-mode marks with their modes
    sub = m.select(np.flatnonzero(over)[::-1])
    assert sub.info["radiation"]["capped_db"] == capped_db[over][::-1].tolist()


def test_the_synthesizer_hears_the_models_capped_weights_decay_and_pattern(capped_and_raw):
    from mjsound.synth.synthesizer import Synthesizer

    m, _ = capped_and_raw
    mic = np.array([0.3, -0.2, 1.0])
    syn = Synthesizer(48000, microphones=[mic], dtype="float64", cull_db=None)
    syn.add_object("plate", m)
    om = syn.object_modes("plate")
    assert len(om.keep) >= 5
    np.testing.assert_array_equal(om.weights, m.radiation[om.keep])
    np.testing.assert_allclose(om.decay, m.decay_per_s[om.keep], rtol=1e-12)
    syn.impact("plate", [0, 0, 0], [0, 0, 1e-3], 0.0, pulse_s=0.0)
    syn.render(480)
    # weight times direction factor is the model's (capped) pattern towards the microphone
    u = mic / np.linalg.norm(mic)
    want = np.conj(m.radiation_pattern(u[None, :])[0, om.keep])
    got = om.weights * syn.direction_factors("plate")[0]
    loud = np.abs(want) > 0.1 * np.abs(want).max()
    np.testing.assert_allclose(got[loud], want[loud], rtol=0.05)
