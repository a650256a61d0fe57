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

(``a_p`` the area of surface sample ``p``: the model's surface over its samples).

A boundary-element solve (:mod:`.radiation`) whose elements do not resolve a mode's wavelength
samples the mode's shape on elements wider than its own half-wavelength, which leaves a net
volume flow that the mode does not have: such modes came out 10 to 40 dB above ``R_max`` (the
HalfCheetah torso's modes above 3 kHz at draft quality, ``scripts/diagnose_levels.py``). The
analysis (:func:`mjsound.analyze`) therefore caps every mode's pattern at ``R_max`` where it
makes the model (:func:`cap_radiation`: the whole pattern scaled, so its shape is kept and its
RMS is ``R_max``), before the radiation damping is derived from it, and records by how much
(``info['radiation']['capped_db']``); the stored pattern, ``ModalModel.radiation`` and the
decay rates agree, and the synthesizer reads them as they are.
"""

from __future__ import annotations

import numpy as np

from .radiation import AIR_DENSITY, SPEED_OF_SOUND

__all__ = ["efficiency_limit", "radiation_limit", "cap_radiation"]


def efficiency_limit(points, normals, shapes, area_m2: float, omega) -> np.ndarray:
    """``R_max`` [Pa m] per mode at radiation efficiency 1 (module docstring).

    Parameters
    ----------
    points : (p, 3) surface samples [m], equal shares of the surface
    normals : (p, 3) their outward unit normals
    shapes : (p, 3, n) mass-normalised mode shapes at the samples [1/sqrt(kg)]
    area_m2 : float
        The surface's area [m^2]; each sample stands for ``area_m2 / p``.
    omega : (n,) angular frequencies [rad/s]

    Returns
    -------
    (n,) float64

    Examples
    --------
    >>> efficiency_limit(np.zeros((1, 3)), [[0, 0, 1.0]], np.ones((1, 3, 1)), 1.0, [1.0])  # doctest: +ELLIPSIS
    array([116.1...])
    """
    p = len(points)
    un = np.einsum("pcn,pc->pn", np.asarray(shapes, np.float64), np.asarray(normals, np.float64))
    a = float(area_m2) / max(p, 1)
    return AIR_DENSITY * SPEED_OF_SOUND * np.asarray(omega, np.float64) * np.sqrt(
        a * np.einsum("pn,pn->n", un, un) / (4 * np.pi))


def radiation_limit(model) -> np.ndarray | None:
    """:func:`efficiency_limit` of a :class:`~mjsound.modal.model.ModalModel`'s modes, or None
    when the model does not say its surface area (``model.info['area_m2']``) or has no surface
    samples.

    Returns
    -------
    (n_modes,) float64 | None
    """
    area = (getattr(model, "info", None) or {}).get("area_m2")
    points = np.asarray(model.points)
    if area is None or not np.isfinite(area) or area <= 0 or len(points) == 0:
        return None
    omega = 2 * np.pi * np.asarray(model.frequencies_hz, np.float64)
    return efficiency_limit(points, model.normals, model.shapes, float(area), omega)


def cap_radiation(rms, coefficients, limit):
    """Modes' patterns capped at ``limit``: ``(rms, coefficients, over_db)``.

    A mode whose RMS ``R`` exceeds ``R_max`` has its whole pattern (``coefficients``, its
    spherical-harmonic coefficients, one row per mode) scaled by ``R_max / R``, so that its
    directions keep their proportions and the RMS over them is ``R_max``.

    Parameters
    ----------
    rms : (n,) RMS of each pattern over directions [Pa m]
    coefficients : (n, m) complex, the patterns' coefficients
    limit : (n,) ``R_max`` [Pa m] (:func:`efficiency_limit`)

    Returns
    -------
    rms : (n,) float64, ``min(R, R_max)``
    coefficients : (n, m) complex, scaled rows where capped
    over_db : (n,) float64, ``20 log10(R / R_max)`` where capped, else 0 [dB]

    Examples
    --------
    >>> r, c, over = cap_radiation([1.0, 10.0], np.ones((2, 1)), [2.0, 1.0])
    >>> r.tolist(), c[:, 0].real.tolist(), over.round(1).tolist()
    ([1.0, 1.0], [1.0, 0.1], [0.0, 20.0])
    """
    rms = np.asarray(rms, np.float64)
    limit = np.asarray(limit, np.float64)
    over = rms > limit
    safe_rms = np.where(over, rms, 1.0)
    scale = np.where(over, limit / safe_rms, 1.0)
    # (a mode with no normal motion at the samples has R_max = 0: over by "600 dB", not inf)
    over_db = np.where(over, 20 * np.log10(safe_rms / np.maximum(np.where(over, limit, 1.0), 1e-30 * safe_rms)), 0.0)
    return np.where(over, limit, rms), np.asarray(coefficients) * scale[:, None], over_db
