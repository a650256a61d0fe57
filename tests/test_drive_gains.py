"""The driven bodies' sub-sample delay factors (mjsound.synth.drive_gains.delay_factors, the
series :func:`bodies_gains` makes them with) against the plain float64 formula they replace,
``e^{Re z} (cos Im z + j sin Im z)``, ``z = lam dts``."""

import numpy as np
import pytest

from mjsound.synth.drive_gains import FACTOR_RANGE, delay_factors

FS = 16000.0


def plain(lam, dts):
    """The factors as libm makes them (the formula the exact rendering keeps)."""
    with np.errstate(invalid="ignore", over="ignore"):
        z = lam * dts
        e = np.exp(z.real)
        return e * np.cos(z.imag) + 1j * e * np.sin(z.imag)


@pytest.mark.parametrize("fs", [16000.0, 48000.0])
@pytest.mark.parametrize("dmax", [2.0, 20.0])
def test_delay_factors_match_the_plain_formula_to_a_few_ulps(fs, dmax):
    """Modes from 1 Hz to the Nyquist frequency, damped from 1/s to ``dmax fs`` [1/s] (20 fs:
    beyond the series' range, those calls take libm), at sub-sample delays over [0, 1/fs]
    and slightly below 0 (the rounding tolerance): within 3e-15 of |e^z| (a few ulps)."""
    rng = np.random.default_rng(7)
    n = 4000
    w = 2 * np.pi * np.exp(rng.uniform(0.0, np.log(fs / 2), n))
    d = np.exp(rng.uniform(0.0, np.log(dmax * fs), n))
    lam = -d + 1j * w
    for dts in [0.0, 1e-3 / fs, 0.37 / fs, 0.999999 / fs, -1e-9 / fs, 1.0 / fs]:
        ref = plain(lam, dts)
        got = delay_factors(lam, dts)
        assert np.all(np.isfinite(got))
        err = np.abs(got - ref) / np.abs(ref)
        assert err.max() < 3e-15, (dts * fs, err.max())


def test_delay_factors_of_small_arguments_are_exact_to_rounding():
    """A body at the microphone's sample (dts 0) gets exactly 1; a few arguments on the unit
    circle land where cos and sin say (e^{j pi} = -1)."""
    lam = np.array([-3.0 + 2j * np.pi * 440.0, -1.0 + 1j])
    assert np.array_equal(delay_factors(lam, 0.0), np.ones(2, complex))
    f = delay_factors(np.array([1j * np.pi, 1j * np.pi / 2, -np.log(2.0) + 0j]), 1.0)
    assert abs(f[0] - (-1.0)) < 1e-15
    assert abs(f[1] - 1j) < 1e-15
    assert abs(f[2] - 0.5) < 5e-16


def test_delay_factors_out_of_range_or_not_finite_take_the_plain_formula():
    """An argument beyond FACTOR_RANGE (a pole above the rate, a long delay) or not finite
    (a bad pose's delay) gives libm's factors, bit for bit, for every mode of that call, and
    a NaN stays NaN (the gains then read 0, never NaN)."""
    lam = np.array([-5.0 + 1j * 1.01 * FACTOR_RANGE * FS, -5.0 + 2j * np.pi * 100.0])
    dts = 1.0 / FS
    assert np.array_equal(delay_factors(lam, dts), plain(lam, dts))
    bad = delay_factors(lam[1:], np.nan)
    assert np.isnan(bad.real[0]) and np.isnan(bad.imag[0])
    far = np.array([-1.0 + 0j, -1.0 + 1j])
    for dts in (-np.inf, 1e300):
        assert np.array_equal(delay_factors(far, dts), plain(far, dts), equal_nan=True)
