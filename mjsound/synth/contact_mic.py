"""Contact microphones: the structure-borne vibration at a point of a body's surface.

A contact microphone (a piezo disc or accelerometer glued to a gripper finger or an object)
reads its body, not the air. Its output here is the **surface acceleration along the sensor's
axis** ``n`` at its site ``x`` [m/s^2]:

* it is what these sensors measure: a piezo element loaded by its own mass (or the structure's)
  gives a charge proportional to force, so to acceleration, below its mounted resonance, and it
  is AC-coupled: a body resting on a table reads 0, not g;
* an impact's rigid-body part is then a pulse of finite length whose integral is the velocity
  change (velocity would be a step that never returns to zero, displacement a ramp).

Two parts, each from the forces on the sensor's own body only (an impact elsewhere that does
not touch the body is not heard at all):

**Modal.** Mode i moves the surface by ``phi_i(x) q_i(t)``, and an impulse ``J`` at ``p`` rings
``q_i = Im(c_i e^{lambda_i t})``, ``c_i = (phi_i(p) . J) / w_i S_i`` (see
:mod:`.synthesizer`), so the sensor reads::

    a_n(t) = sum_i (phi_i(x) . n) Im(c_i lambda_i^2 e^{lambda_i t}),   lambda_i = -d_i + j w_i

i.e. a voice of the modal bank whose complex weight is ``(phi_i(x) . n) lambda_i^2``
[1/(sqrt(kg) s^2)] (:func:`modal_weights`) instead of an air microphone's radiation / r, with
no propagation delay. ``phi_i(x)`` is the mode shape at the surface sample nearest the site
(:meth:`ModalModel.gains`). Sliding and rolling noise drive the same modes, so the sensor
hears an object scraping along its body.

**Rigid body.** An impulse ``J`` at ``p`` on a free body (mass ``m``, world inertia ``I``
about its centre of mass ``o``) changes its velocity by ``dv = J / m`` and its angular
velocity by ``dw = I^-1 ((p - o) x J)``; the site's velocity changes by
``(dv + dw x (x - o)) . n`` (:func:`site_velocity_change`) within the contact time ``tau``, a
half-sine acceleration pulse of that area rendered band-limited by :mod:`.bandlimited`
(:func:`site_pulse`). Sliding and rolling noise reach the sensor through the modes only (their
rigid-body share, a force fluctuation over the body's mass, is left out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..modal.model import ModalModel
from .bandlimited import PULSE_DTYPE
from .pulse import half_sine_spectrum

__all__ = ["DEFAULT_CONTACT_FULL_SCALE", "check_contact_full_scale", "ContactMicrophone", "modal_weights",
           "modal_site_acceleration", "free_body_velocity_change", "site_velocity_change", "site_pulse"]

#: Acceleration written as full scale on a contact channel (files, observations) [m/s^2]:
#: about 100 g, where a piezo contact microphone on a struck metal part peaks.
DEFAULT_CONTACT_FULL_SCALE = 1000.0


def check_contact_full_scale(value=None) -> float:
    """The contact channels' full scale [m/s^2]: ``value`` (None:
    :data:`DEFAULT_CONTACT_FULL_SCALE`), which must be positive and finite."""
    fsc = DEFAULT_CONTACT_FULL_SCALE if value is None else float(value)
    if not (np.isfinite(fsc) and fsc > 0):
        raise ValueError(f"contact_full_scale={value!r} must be a positive acceleration in m/s^2 (e.g. 1000)")
    return fsc


@dataclass(frozen=True)
class ContactMicrophone:
    """A contact microphone: a sensor at ``point`` on a body, reading acceleration along ``axis``.

    Attributes
    ----------
    name : str
        Channel name.
    body : str
        The body it is glued to.
    point : (3,) tuple of float
        Site in the body frame [m].
    axis : (3,) tuple of float
        Unit sensing axis in the body frame.
    """

    name: str
    body: str
    point: tuple
    axis: tuple

    def __post_init__(self):
        p = np.asarray(self.point, dtype=np.float64).reshape(-1)
        a = np.asarray(self.axis, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"contact microphone {self.name!r}: point must be 3 finite coordinates in metres")
        norm = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
        if not (np.isfinite(norm) and norm > 0):
            raise ValueError(f"contact microphone {self.name!r}: axis must be a non-zero 3-vector")
        object.__setattr__(self, "point", tuple(p))
        object.__setattr__(self, "axis", tuple(a / norm))


def _poles(model: ModalModel) -> np.ndarray:
    """``lambda_i = -d_i + j w_d,i`` [1/s] of every mode."""
    return -model.decay_per_s + 2j * np.pi * model.damped_frequencies_hz


def modal_weights(model: ModalModel, point, axis) -> np.ndarray:
    """Complex weight per mode, ``(phi_i(x) . n) lambda_i^2`` [1/(sqrt(kg) s^2)]: times the
    modal amplitude ``c_i`` [m sqrt(kg)] it gives the mode's acceleration at the site [m/s^2].

    Parameters
    ----------
    model : ModalModel
    point : (3,) array_like
        Site in the model frame [m] (snapped to the nearest surface sample).
    axis : (3,) array_like
        Unit sensing axis in the model frame.

    Returns
    -------
    (n_modes,) complex128 array.
    """
    g = model.gains(np.reshape(point, (1, 3)), np.reshape(axis, (1, 3)))[0]
    return g * _poles(model) ** 2


def modal_site_acceleration(model: ModalModel, point, axis, hit_point, impulse, tau_s, times) -> np.ndarray:
    """Closed form: acceleration along ``axis`` at ``point`` [m/s^2] at ``times`` [s] after an
    impulse ``impulse`` [N s] (model frame) at ``hit_point`` with a half-sine pulse of
    ``tau_s`` [s] (0 before the impact at t = 0)::

        a_n(t) = sum_i (phi_i(x).n) Im((phi_i(p).J) / w_i S(w_i tau) lambda_i^2 e^{lambda_i t})
    """
    t = np.asarray(times, dtype=np.float64)
    wd = 2 * np.pi * model.damped_frequencies_hz
    ok = wd > 0
    lam = _poles(model)[ok]
    gx = model.gains(np.reshape(point, (1, 3)), np.reshape(axis, (1, 3)))[0][ok]
    gp = model.gains(np.reshape(hit_point, (1, 3)), np.reshape(impulse, (1, 3)))[0][ok]
    c = gp / wd[ok] * half_sine_spectrum(wd[ok], tau_s)
    z = np.exp(np.multiply.outer(np.maximum(t, 0.0), lam))
    return np.where(t >= 0, (z * (gx * c * lam**2)).imag.sum(axis=-1), 0.0)


def free_body_velocity_change(mass, inertia_world, com, point, impulse) -> tuple[np.ndarray, np.ndarray]:
    """``(dv, dw)``: a free rigid body's change of velocity [m/s] and angular velocity [rad/s]
    under an impulse ``impulse`` [N s] at ``point`` [m] (world): ``dv = J / m``,
    ``dw = I^-1 ((p - o) x J)`` with ``I`` (3, 3) [kg m^2] about the centre of mass ``o``."""
    m = float(mass)
    if not (np.isfinite(m) and m > 0):
        raise ValueError(f"mass={mass!r} must be a positive mass in kg")
    J = np.asarray(impulse, dtype=np.float64).reshape(3)
    arm = np.asarray(point, dtype=np.float64).reshape(3) - np.asarray(com, dtype=np.float64).reshape(3)
    dw = np.linalg.solve(np.asarray(inertia_world, dtype=np.float64).reshape(3, 3), np.cross(arm, J))
    return J / m, dw


def site_velocity_change(dv, dw, com, site, axis) -> float:
    """``(dv + dw x (x - o)) . n`` [m/s]: the site's velocity change along its axis."""
    arm = np.asarray(site, dtype=np.float64).reshape(3) - np.asarray(com, dtype=np.float64).reshape(3)
    v = np.asarray(dv, dtype=np.float64).reshape(3) + np.cross(np.asarray(dw, dtype=np.float64).reshape(3), arm)
    return float(v @ np.asarray(axis, dtype=np.float64).reshape(3))


def site_pulse(time_s: float, tau_s: float, channel: int) -> np.ndarray:
    """The rigid-body acceleration pulse at a contact microphone (one PULSE_DTYPE record, unit
    transfer, no delay): render it scaled by :func:`site_velocity_change` [m/s]."""
    p = np.zeros(1, PULSE_DTYPE)
    p["time_s"], p["tau_s"], p["b0"], p["channel"] = float(time_s), float(tau_s), 1.0, int(channel)
    return p
