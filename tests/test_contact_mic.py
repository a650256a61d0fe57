"""Contact microphones: modal and rigid-body surface acceleration against closed forms."""

import math

import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.synth import bandlimited as bl
from mjsound.synth import contact_mic as cm
from mjsound.synth.pulse import half_sine_spectrum


def _model():
    """Three modes sampled at four surface points (mass-normalised shapes, 1/sqrt(kg))."""
    rng = np.random.default_rng(3)
    pts = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]], float)
    nrm = np.tile([0, 0, 1.0], (4, 1))
    shapes = rng.standard_normal((4, 3, 3))
    return ModalModel([500.0, 1300.0, 2900.0], [4.0, 9.0, 20.0], pts, nrm, shapes, [1.0, 1.0, 1.0],
                      get_material("aluminium"), mass_kg=0.4)


def test_modal_acceleration_is_second_derivative_of_displacement():
    model = _model()
    x, n = [0.1, 0.0, 0.0], [0, 0, 1.0]
    p, J, tau = [0.0, 0.1, 0.0], [0.0, 0.0, 0.02], 1e-4
    lam = -model.decay_per_s + 2j * np.pi * model.damped_frequencies_hz
    wd = lam.imag
    gx = model.gains([x], [n])[0]
    gp = model.gains([p], [J])[0]

    def displacement(t):  # u . n = sum (phi_i(x).n) q_i, q_i = Im(c_i e^{lambda t})
        c = gp / wd * half_sine_spectrum(wd, tau)
        return (np.exp(np.multiply.outer(t, lam)) * (gx * c)).imag.sum(axis=-1)

    h = 5e-7  # central difference: relative error (h w)^2 / 12 < 1e-5 at 2.9 kHz
    t = np.linspace(0.001, 0.01, 50)
    numeric = (displacement(t + h) - 2 * displacement(t) + displacement(t - h)) / h**2
    got = cm.modal_site_acceleration(model, x, n, p, J, tau, t)
    assert np.abs(got - numeric).max() < 3e-5 * np.abs(got).max()
    # the voice weight reproduces it from the modal amplitudes
    c = gp / wd * half_sine_spectrum(wd, tau)
    w = cm.modal_weights(model, x, n)
    assert np.allclose((np.exp(np.multiply.outer(t, lam)) * (c * w)).imag.sum(axis=-1), got, rtol=1e-12)
    assert np.all(cm.modal_site_acceleration(model, x, n, p, J, tau, [-1e-3, -1e-6]) == 0.0)


def test_rod_struck_at_one_end_rigid_body_site_velocities():
    """A free rod (mass m, length L) struck across one end: that end's velocity jumps by 4 J/m,
    the other end's by -2 J/m (centre J/m, spin 6 J / (m L))."""
    m, L, J = 0.5, 0.4, 0.03
    inertia = np.diag([m * L * L / 12, m * L * L / 12, 1e-6])
    com = np.array([0.0, 0.0, 0.0])
    ends = np.array([[0, 0, L / 2], [0, 0, -L / 2]])
    dv, dw = cm.free_body_velocity_change(m, inertia, com, ends[0], [J, 0, 0])
    assert dv == pytest.approx([J / m, 0, 0])
    assert dw == pytest.approx([0, 6 * J / (m * L), 0])
    assert cm.site_velocity_change(dv, dw, com, ends[0], [1, 0, 0]) == pytest.approx(4 * J / m)
    assert cm.site_velocity_change(dv, dw, com, ends[1], [1, 0, 0]) == pytest.approx(-2 * J / m)
    assert cm.site_velocity_change(dv, dw, com, ends[1], [0, 1, 0]) == pytest.approx(0.0)
    with pytest.raises(ValueError, match="mass"):
        cm.free_body_velocity_change(0.0, inertia, com, ends[0], [J, 0, 0])


def test_site_pulse_renders_the_velocity_change():
    fs = 16000
    track = bl.PulseTrack(3, fs)
    track.add(cm.site_pulse(0.01, 3e-4, 2), 1.7)
    block = track.take(800)
    assert np.all(block[:2] == 0.0)
    assert block[2].sum() / fs == pytest.approx(1.7, rel=1e-9)
    # a 300 us half sine of area 1.7 m/s peaks near 1.7 pi / (2 tau) = 8.9 km/s^2 (band-limited: a bit less)
    assert 0.8 * 1.7 * math.pi / 6e-4 < block[2].max() < 1.001 * 1.7 * math.pi / 6e-4


def test_contact_microphone_validates_and_normalises():
    mic = cm.ContactMicrophone("contact_mic_finger", "finger", (0, 0, 0.01), (0, 0, 2.0))
    assert mic.axis == (0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="axis"):
        cm.ContactMicrophone("m", "b", (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="point"):
        cm.ContactMicrophone("m", "b", (0, float("nan"), 0), (0, 0, 1))
