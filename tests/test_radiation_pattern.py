"""The stored far-field pattern: spherical harmonics, the model's API, save/load, frames."""

import numpy as np
import pytest

from mjsound import ModalModel, analyze
from mjsound.modal.sph import fit_coefficients, real_sph_harm, sphere_quadrature


def test_real_harmonics_are_orthonormal_under_the_quadrature():
    L = 7
    d, w = sphere_quadrature(L)
    assert np.isclose(w.sum(), 4 * np.pi)
    Y = real_sph_harm(L, d)
    np.testing.assert_allclose((Y * w[:, None]).T @ Y, np.eye((L + 1) ** 2), atol=1e-12)


def test_harmonics_match_closed_forms():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(20, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    x, y, z = d.T
    Y = real_sph_harm(2, d)
    np.testing.assert_allclose(Y[:, 0], 0.5 / np.sqrt(np.pi))
    np.testing.assert_allclose(Y[:, 2], np.sqrt(3 / (4 * np.pi)) * z)
    np.testing.assert_allclose(np.abs(Y[:, 3]), np.sqrt(3 / (4 * np.pi)) * np.abs(x))
    np.testing.assert_allclose(Y[:, 6], np.sqrt(5 / (16 * np.pi)) * (3 * z * z - 1))


def test_fit_recovers_a_band_limited_pattern():
    L = 5
    rng = np.random.default_rng(1)
    c = rng.normal(size=(3, (L + 1) ** 2)) + 1j * rng.normal(size=(3, (L + 1) ** 2))
    d, _ = sphere_quadrature(L)
    F = real_sph_harm(L, d) @ c.T
    np.testing.assert_allclose(fit_coefficients(L, F), c, atol=1e-12)


@pytest.fixture(scope="module")
def bar():
    return analyze("box:0.2,0.03,0.02", "brass", f_max=6000, cache=False, error_estimate=False)


def test_pattern_rms_is_the_radiation_and_survives_select_and_save(bar, tmp_path):
    assert bar.radiation_sh is not None
    d, w = sphere_quadrature(12)
    F = bar.radiation_pattern(d)
    assert F.shape == (len(d), bar.n_modes) and F.dtype == np.complex128
    rms = np.sqrt((w[:, None] * np.abs(F) ** 2).sum(axis=0) / (4 * np.pi))
    np.testing.assert_allclose(rms, bar.radiation, rtol=1e-5)
    sub = bar.select([2, 0])
    np.testing.assert_allclose(sub.radiation_pattern(d[:5]), F[:5][:, [2, 0]], rtol=1e-6)
    p = tmp_path / "m.npz"
    bar.save(p)
    back = ModalModel.load(p)
    np.testing.assert_array_equal(back.radiation_sh, bar.radiation_sh)
    np.testing.assert_array_equal(back.radiation_centre, bar.radiation_centre)


def test_pattern_turns_with_the_object():
    # the same bar along z and turned 30 degrees about y: its pattern turns with it
    import trimesh

    box = trimesh.creation.box((0.03, 0.02, 0.25))
    a = np.radians(30)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    turned = box.copy()
    turned.vertices = box.vertices @ R.T
    m0 = analyze(box, "aluminium", f_max=4000, cache=False, error_estimate=False)
    m1 = analyze(turned, "aluminium", f_max=4000, cache=False, error_estimate=False)
    assert m1.info.get("analysis_frame") is not None
    d = np.random.default_rng(2).normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    n = min(m0.n_modes, m1.n_modes, 6)
    np.testing.assert_allclose(m0.frequencies_hz[:n], m1.frequencies_hz[:n], rtol=0.02)
    # degenerate pairs mix: compare the summed power of each group of modes
    f0 = m0.frequencies_hz[:n]
    groups = np.cumsum(np.r_[True, np.diff(f0) > 0.01 * f0[1:]]) - 1
    for g in np.unique(groups):
        idx = np.flatnonzero(groups == g)
        p0 = (np.abs(m0.radiation_pattern(d)[:, idx]) ** 2).sum(axis=1)
        p1 = (np.abs(m1.radiation_pattern(d @ R.T)[:, idx]) ** 2).sum(axis=1)
        assert np.all(np.abs(10 * np.log10(p1 / p0)) < 1.0)


def test_bad_directions_are_refused(bar):
    with pytest.raises(ValueError, match="non-zero"):
        bar.radiation_pattern([[0, 0, 0]])
    with pytest.raises(ValueError, match=r"\(k, 3\)"):
        bar.radiation_pattern(np.ones((2, 2)))


def test_a_model_without_a_pattern_radiates_evenly(bar):
    from dataclasses import replace

    plain = replace(bar, radiation_sh=None, radiation_centre=None)
    F = plain.radiation_pattern([[1, 0, 0], [0, 0, 2]])
    np.testing.assert_allclose(F, np.tile(bar.radiation, (2, 1)))


def test_radiation_setting_is_checked_and_false_keeps_the_compact_estimate():
    with pytest.raises(ValueError, match="radiation='best' unknown"):
        analyze("box:0.2,0.03,0.02", "brass", radiation="best", cache=False)
    with pytest.raises(ValueError, match="unknown settings"):
        analyze("box:0.2,0.03,0.02", "brass", radiation={"elements": 3}, cache=False)
    m = analyze("box:0.2,0.03,0.02", "brass", f_max=6000, radiation=False, cache=False, error_estimate=False)
    assert m.info["radiation"]["method"].startswith("compact") and m.radiation_sh.shape[1] == 4


def test_levels_section_replaces_itself_in_the_page(tmp_path):
    from mjsound.report.accuracy_levels import BEGIN, END, levels_section, splice_levels

    row = dict(name="bar", mesh="box:0.3,0.02,0.02", material="aluminium", options={"f_max": 6000.0},
               frequencies_hz=[1145.0, 3071.0], reference_db=[-10.0, 0.0], reference_step_db=[0.1, 2.0],
               settings={"default": dict(power_db=[0.3, -0.4], direction_db=[1.0, 2.0], estimate_db=[0.1, 2.5],
                                         seconds=3.0, radiation_cpu_s=2.0)})
    page = tmp_path / "accuracy.md"
    page.write_text("# page\n\nbody\n")
    splice_levels(page, levels_section([row]))
    splice_levels(page, levels_section([row]))
    text = page.read_text()
    assert text.startswith("# page") and text.count(BEGIN) == 1 and text.count(END) == 1
    assert "| ~3071 |" in text and "+0.3 (1.0)" in text
