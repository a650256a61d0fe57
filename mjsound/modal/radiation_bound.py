"""The most a mode can radiate: a vibrating surface's radiation efficiency is at most about 1.

A surface moving with normal velocity ``v_n`` radiates the power ``W = rho0 c sigma <v_n^2> A``
with a radiation efficiency ``sigma`` that rises from ``(k a)^2``-small for compact sources and
tends to 1 once the acoustic wavelength is short beside the surface's curvature and its
vibration's wavelength (Fahy and Gardonio, *Sound and Structural Vibration*, 2nd ed., 2007,
sec. 3.5-3.7; Cremer, Heckl and Petersson, *Structure-Borne Sound*, 3rd ed., 2005, ch. 7: the
efficiency of plates and shells peaks near 1, a little above it only at coincidence). A mode of
unit modal coordinate at ``omega`` has ``<v_n^2> A = omega^2 sum_p a_p (phi_p . n_p)^2 / 2``, so
its far-field RMS pressure at 1 m, ``ModalModel.radiation`` (``W = 2 pi R^2 / (rho0 c)``), is at
most::

    R_max = rho0 c omega sqrt(A_eff / (4 pi)),      A_eff = sum_p a_p (phi_p . n_p)^2

(``a_p`` the area of surface sample ``p``: the model's surface over its samples). The compact
estimate of :mod:`.analyze` is capped there when it is made; a boundary-element solve
(:mod:`.radiation`) whose elements do not resolve a mode's wavelength is not: the mode's shape,
sampled on elements wider than its own half-wavelength, leaves a net volume flow that the
mode does not have, and such modes come out 10 to 40 dB above ``R_max`` (the HalfCheetah
torso's modes above 3 kHz at draft quality: ``scripts/diagnose_levels.py``).
:func:`bounded_radiation` caps every mode at ``R_max`` and gives it the radiation damping that
goes with the capped value (:func:`.radiation.radiation_damping`), so that the mode still loses
what it radiates.
"""

from __future__ import annotations

import numpy as np

from .radiation import AIR_DENSITY, SPEED_OF_SOUND, radiation_damping

__all__ = ["radiation_limit", "bounded_radiation"]


def radiation_limit(model) -> np.ndarray | None:
    """``R_max`` [Pa m] per mode of ``model`` at radiation efficiency 1 (module docstring), or
    None when the model does not say its surface area (``model.info['area_m2']``) or has no
    surface samples.

    Parameters
    ----------
    model : ModalModel

    Returns
    -------
    (n_modes,) float64 | None
    """
    area = (getattr(model, "info", None) or {}).get("area_m2")
    points = np.asarray(model.points)
    if area is None or not np.isfinite(area) or area <= 0 or len(points) == 0:
        return None
    a = float(area) / len(points)
    un = np.einsum("pcn,pc->pn", np.asarray(model.shapes, np.float64), np.asarray(model.normals, np.float64))
    omega = 2 * np.pi * np.asarray(model.frequencies_hz, np.float64)
    return AIR_DENSITY * SPEED_OF_SOUND * omega * np.sqrt(a * np.einsum("pn,pn->n", un, un) / (4 * np.pi))


def bounded_radiation(model) -> tuple[np.ndarray, np.ndarray, int]:
    """``(radiation, decay, n_capped)``: the model's ``radiation`` [Pa m] capped at
    :func:`radiation_limit`, its ``decay_per_s`` [1/s] with each capped mode's radiation damping
    replaced by the capped value's, and how many modes were capped (the model's own values,
    and 0, when it does not say its area).

    Examples
    --------
    >>> rad, decay, n = bounded_radiation(model)  # doctest: +SKIP
    """
    rad = np.asarray(model.radiation, np.float64)
    decay = np.asarray(model.decay_per_s, np.float64)
    limit = radiation_limit(model)
    if limit is None:
        return rad, decay, 0
    over = rad > limit
    if not over.any():
        return rad, decay, 0
    omega = 2 * np.pi * np.asarray(model.frequencies_hz, np.float64)
    capped = np.where(over, limit, rad)
    with np.errstate(divide="ignore", invalid="ignore"):
        change = np.where(over, radiation_damping(capped, omega) - radiation_damping(rad, omega), 0.0)
    return capped, decay + change, int(over.sum())
