"""The radiation efficiency bound (mjsound.modal.radiation_bound): a mode radiates at most
rho0 c omega sqrt(A_eff / 4 pi) at 1 m, with the radiation damping that goes with what it
radiates; the synthesizer hears the bounded weights."""

from __future__ import annotations

import numpy as np
import pytest

from mjsound import ModalModel, get_material
from mjsound.modal.radiation import AIR_DENSITY, SPEED_OF_SOUND, radiation_damping
from mjsound.modal.radiation_bound import bounded_radiation, radiation_limit


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


def test_modes_over_the_limit_are_capped_with_their_damping_and_the_rest_kept():
    limit = radiation_limit(plate_model([1.0, 1.0]))
    model = plate_model([0.5 * limit[0], 30.0 * limit[1]])  # (the second: 30 dB over, an under-resolved solve)
    rad, decay, n = bounded_radiation(model)
    assert n == 1
    assert rad[0] == model.radiation[0] and decay[0] == model.decay_per_s[0]
    assert rad[1] == pytest.approx(limit[1], rel=1e-12)
    w1 = 2 * np.pi * 3000.0
    mat = model.material
    assert decay[1] == pytest.approx(0.5 * (mat.alpha + mat.beta * w1**2) + radiation_damping(limit[1], w1), rel=1e-9)
    untouched = plate_model([0.5 * limit[0], 0.9 * limit[1]])
    r2, d2, n2 = bounded_radiation(untouched)
    assert n2 == 0 and np.array_equal(r2, untouched.radiation) and np.array_equal(d2, untouched.decay_per_s)


def test_a_model_without_its_area_is_left_as_it_is():
    model = plate_model([1e9, 1e9])
    model.info.pop("area_m2")
    assert radiation_limit(model) is None
    rad, decay, n = bounded_radiation(model)
    assert n == 0 and np.array_equal(rad, model.radiation)


def test_the_synthesizer_hears_the_bounded_mode():
    """A mode 30 times over the limit rings at the limit, and decays as fast as the limit's
    radiation damping says (not the over-estimate's)."""
    from mjsound.synth.synthesizer import Synthesizer

    limit = radiation_limit(plate_model([1.0, 1.0]))
    fs = 48000

    def peak_and_decay(model):
        syn = Synthesizer(fs, microphones=[[0, 0, 1.0]], dtype="float64", cull_db=None)
        syn.add_object("o", model)
        syn.impact("o", [0, 0, 0], [0, 0, 1e-3], 0.0, pulse_s=0.0)
        y = syn.render(fs // 2)[0]
        return np.abs(y).max()

    bounded = plate_model([0.5 * limit[0], limit[1]])
    over = plate_model([0.5 * limit[0], 30.0 * limit[1]])
    assert peak_and_decay(over) == pytest.approx(peak_and_decay(bounded), rel=1e-9)
