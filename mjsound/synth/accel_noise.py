"""Acceleration noise: the click a rigid body radiates when an impact accelerates it.

During an impact a body's velocity changes by ``dv = J / m`` (impulse ``J`` [N s], mass
``m``) within the contact time ``tau`` (Hertz, :mod:`.pulse`: the same ``tau`` that shapes
the modal excitation). The sudden rigid-body acceleration pushes the air; for small stiff
objects, whose modes lie high or above the band, this *acceleration noise* is most of what
is heard (Chadwick, Zheng and James, "Precomputed acceleration noise for improved rigid-body
sound", ACM Trans. Graph. 31(4), 2012, who model the acceleration as the same half-sine
pulse and precompute each shape's radiation).

Rigid sphere (the closed form)
------------------------------
A rigid sphere of radius ``a`` translating along z with acceleration ``A(w)`` (``e^{jwt}``,
``s = jw``, ``k = w / c``) radiates the dipole field (Morse and Ingard, *Theoretical
Acoustics*, 1968, sec. 7.2; Pierce, *Acoustics*, 1981, ch. 4, the oscillating rigid sphere)::

    p(r, theta, w) = -j rho c U cos(theta) h1(kr) / h1'(ka),   U = A / s,  h1 = j1 - j y1

and with ``h1(x) = j e^{-jx}(1 + jx) / x^2`` this is the rational form used here::

    p = rho a^3 cos(theta) / (2 r^2) * A(w) * (1 + s r/c) / (1 + s a/c + (s a/c)^2 / 2)
        * e^{-s (r - a)/c}

* ``r >> a`` and ``ka << 1`` (compact): ``p = rho a^3 cos(theta) / (2 c r) * dA/dt(t - r/c)``:
  the far field follows the *jerk*; the ``1/r^2`` term (kept) is the near field.
* ``ka >> 1``: ``|p| -> rho c |U| a cos(theta) / r``: above ``c / (2 pi a)`` the sphere
  no longer gains with frequency (its two poles ``s = (-1 +- j) c / a``).
* ``2 pi rho a^3 = (m_air + m_added) = 1.5 rho V``: the dipole strength is the displaced plus
  the added mass of air times the acceleration.

Other shapes
------------
Shape enters through an equivalent ellipsoid: the uniform solid ellipsoid with the body's
mass and principal moments of inertia (``a_i^2 = 5 (I_j + I_k - I_i) / (2 m)``, so every
dynamic body has one, sounding or not; a box of half-sides ``h_i`` gets ``a_i = 1.29 h_i``).
Translating along its principal axis ``i`` it carries the dipole mass (Lamb, *Hydrodynamics*,
1932, sec. 114-115)::

    M_i = rho V (1 + alpha_i / (2 - alpha_i)) = 2 rho V / (2 - alpha_i),
    alpha_i = a1 a2 a3 int_0^inf dl / ((a_i^2 + l) D(l)),  D = sqrt(prod (a_k^2 + l))
            = (2/3) a1 a2 a3 R_D(a_j^2, a_k^2, a_i^2)       (Carlson's elliptic integral)

(a sphere: ``alpha = 2/3``, ``M = 1.5 rho V``; a thin rod along its axis: ``alpha -> 0``,
``M -> rho V``; across it ``alpha -> 1``, ``M -> 2 rho V``). The click at a microphone in
direction ``x_hat`` at distance ``r`` from the body's centre of mass is the sphere formula with
``rho a^3 cos(theta) / 2 -> x_hat . (R diag(M_i) R^T dv_hat) / (4 pi)`` and the frequency
roll-off of the sphere of the same volume, ``a_eq = (a1 a2 a3)^(1/3)``: exact for a sphere,
the compact ellipsoid dipole at low frequency. Rotation is left out: a rotating compact body
radiates as a quadrupole, weaker by another factor ``ka``. A microphone closer than ``a_eq`` is
treated as at ``a_eq``.

Rendering: each click at each microphone is one pulse of :mod:`.bandlimited` with
``b0 = K / r^2``, ``b1 = K / (r c)``, ``d1 = a/c``, ``d2 = a^2 / (2 c^2)``, arrival
``t_e + (r - a)/c``, ``K = x_hat . D / (4 pi)`` per unit ``|dv|``; nothing runs between
impacts.
"""

from __future__ import annotations

import math

import numpy as np

from .bandlimited import PULSE_DTYPE

__all__ = ["carlson_rd", "RHO_AIR", "SPEED_OF_SOUND", "ellipsoid_from_inertia", "ellipsoid_alphas", "dipole_masses",
           "equivalent_radius", "click_pulses", "dipole_pulses"]

#: Air density [kg/m^3].
RHO_AIR = 1.2
#: Speed of sound [m/s].
SPEED_OF_SOUND = 343.0


def ellipsoid_from_inertia(mass, principal_inertia) -> np.ndarray:
    """Semi-axes [m] of the uniform solid ellipsoid with this mass and principal inertia.

    ``I_1 = m (a_2^2 + a_3^2) / 5`` (cyclic), so ``a_i^2 = 5 (I_j + I_k - I_i) / (2 m)``.

    Parameters
    ----------
    mass : float
        [kg], > 0.
    principal_inertia : (3,) array_like
        Principal moments about the centre of mass [kg m^2] (MuJoCo's ``body_inertia``).

    Returns
    -------
    (3,) float64 array of semi-axes [m], each at least 1e-3 of the largest (a point-like or
    degenerate inertia, e.g. a slender rod's zero moment, gives a thin but finite ellipsoid).

    Raises
    ------
    ValueError
        For a non-positive or non-finite mass, a negative or non-finite moment, or moments that
        are all zero.
    """
    m = float(mass)
    inertia = np.asarray(principal_inertia, dtype=np.float64).reshape(-1)
    if not (math.isfinite(m) and m > 0):
        raise ValueError(f"mass={mass!r} must be a positive mass in kg")
    if inertia.shape != (3,) or not np.all(np.isfinite(inertia)) or np.any(inertia < 0) or not inertia.any():
        raise ValueError(f"principal_inertia={principal_inertia!r} must be 3 non-negative moments in kg m^2, not all 0")
    sq = 5.0 * (inertia.sum() - 2.0 * inertia) / (2.0 * m)
    axes = np.sqrt(np.maximum(sq, 0.0))
    return np.maximum(axes, 1e-3 * axes.max())


def ellipsoid_alphas(semi_axes) -> np.ndarray:
    """Lamb's ``alpha_i`` (dimensionless, summing to 2) of an ellipsoid with these semi-axes [m].

    ``alpha_i = (2/3) a1 a2 a3 R_D(a_j^2, a_k^2, a_i^2)``.
    """
    a = _semi_axes(semi_axes)
    a2 = a * a
    prod = a[0] * a[1] * a[2]
    return np.array([2.0 / 3.0 * prod * carlson_rd(a2[(i + 1) % 3], a2[(i + 2) % 3], a2[i]) for i in range(3)])


def carlson_rd(x: float, y: float, z: float) -> float:
    """Carlson's symmetric elliptic integral of the second kind,
    ``R_D(x, y, z) = (3/2) int_0^inf dt / ((t + x)^(1/2) (t + y)^(1/2) (t + z)^(3/2))``,
    for ``x, y >= 0`` (at most one zero), ``z > 0``.

    Carlson's duplication (Carlson, *Numer. Algorithms* 10, 13-26, 1995): with
    ``lambda = sqrt(x y) + sqrt(y z) + sqrt(z x)``, ``R_D(x, y, z) = 3 / (sqrt(z) (z + lambda))
    + (1/4) R_D((x + lambda)/4, (y + lambda)/4, (z + lambda)/4)``; the arguments close in on their
    weighted mean ``mu = (x + y + 3 z)/5`` fourfold per step, and once their relative spread
    ``d`` is below 1e-3 a fifth-order series in ``d`` ends it (relative error ~ d^6 < 1e-17).
    (scipy.special.elliprd gives the same; importing scipy.special would lengthen every start-up.)
    """
    x, y, z = float(x), float(y), float(z)
    if not (x >= 0 and y >= 0 and z > 0 and x + y > 0):
        raise ValueError(f"R_D({x}, {y}, {z}): needs x, y >= 0 (not both 0) and z > 0")
    total, fac = 0.0, 1.0
    while True:
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * (sy + sz) + sy * sz
        total += fac / (sz * (z + lam))
        fac *= 0.25
        x, y, z = 0.25 * (x + lam), 0.25 * (y + lam), 0.25 * (z + lam)
        mu = 0.2 * (x + y + 3.0 * z)
        dx, dy, dz = (mu - x) / mu, (mu - y) / mu, (mu - z) / mu
        if max(abs(dx), abs(dy), abs(dz)) < 1e-3:
            break
    ea, eb = dx * dy, dz * dz
    ec, ed = ea - eb, ea - 6.0 * eb
    ee = ed + 2.0 * ec
    c1, c2, c3, c4 = 3.0 / 14.0, 1.0 / 6.0, 9.0 / 22.0, 3.0 / 26.0
    series = 1.0 + ed * (-c1 + 0.25 * c3 * ed - 1.5 * c4 * dz * ee) + dz * (c2 * ee + dz * (-c3 * ec + dz * c4 * ea))
    return 3.0 * total + fac * series / (mu * math.sqrt(mu))


def dipole_masses(semi_axes, rho_air: float = RHO_AIR) -> np.ndarray:
    """Displaced plus added air mass [kg] for translation along each semi-axis:
    ``2 rho V / (2 - alpha_i)`` (``1.5 rho V`` for a sphere)."""
    a = _semi_axes(semi_axes)
    volume = 4.0 / 3.0 * math.pi * a[0] * a[1] * a[2]
    return 2.0 * float(rho_air) * volume / (2.0 - ellipsoid_alphas(a))


def equivalent_radius(semi_axes) -> float:
    """Radius of the sphere with the ellipsoid's volume, ``(a1 a2 a3)^(1/3)`` [m]."""
    a = _semi_axes(semi_axes)
    return float(np.cbrt(a[0] * a[1] * a[2]))


def _semi_axes(semi_axes) -> np.ndarray:
    a = np.asarray(semi_axes, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"semi_axes={semi_axes!r} must be 3 positive lengths in metres")
    return a


def click_pulses(centre, rotation, semi_axes, direction, microphones, time_s, tau_s, *,
                 speed_of_sound: float = SPEED_OF_SOUND, rho_air: float = RHO_AIR, channel0: int = 0) -> np.ndarray:
    """The click of one impact on one body at every microphone, as :mod:`.bandlimited` pulses.

    Parameters
    ----------
    centre : (3,) array_like
        The body's centre of mass (world) [m].
    rotation : (3, 3) array_like
        Principal-axes-to-world rotation (columns are the ellipsoid's axes).
    semi_axes : (3,) array_like
        The equivalent ellipsoid's semi-axes [m] (:func:`ellipsoid_from_inertia`).
    direction : (3,) array_like
        Direction of the velocity change (world); normalised here. Scale the pulses by
        ``|dv|`` [m/s] when rendering.
    microphones : (m, 3) array_like
        Microphone positions (world) [m].
    time_s : float
        Impact time (start of the contact pulse) [s].
    tau_s : float
        Contact time [s].
    speed_of_sound, rho_air : float
        ``c`` [m/s] and air density [kg/m^3].
    channel0 : int
        Channel of the first microphone.

    Returns
    -------
    (m,) PULSE_DTYPE array: ``b0`` [Pa / (m/s)], ``b1`` [Pa s / (m/s)], ``d1``, ``d2`` and
    the arrival ``time_s + (r - a_eq) / c`` per microphone.
    """
    c = float(speed_of_sound)
    if not (math.isfinite(c) and c > 0):
        raise ValueError(f"speed_of_sound={speed_of_sound!r} must be a positive speed in m/s")
    centre = np.asarray(centre, dtype=np.float64).reshape(3)
    R = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    norm = float(np.linalg.norm(d))
    if not norm > 0 or not math.isfinite(norm):
        raise ValueError(f"direction={direction!r} must be a non-zero finite vector")
    mics = np.asarray(microphones, dtype=np.float64).reshape(-1, 3)
    return dipole_pulses(centre, R, dipole_masses(semi_axes, rho_air), equivalent_radius(semi_axes), d / norm, mics,
                         time_s, tau_s, c, channel0)


def dipole_pulses(centre, rotation, masses, radius, unit, mics, time_s, tau_s, c, channel0=0) -> np.ndarray:
    """:func:`click_pulses` from precomputed principal dipole ``masses`` (3,) [kg] and
    equivalent ``radius`` [m], a unit direction ``unit`` and (m, 3) ``mics`` (no checks)."""
    R = rotation
    a = radius
    dipole = R @ (masses * (R.T @ unit))  # kg, per m/s of dv
    rel = mics - centre
    dist = np.linalg.norm(rel, axis=1)
    xhat = rel / np.where(dist > 0, dist, 1.0)[:, None]  # a microphone at the centre hears nothing
    r = np.maximum(dist, a)
    k = xhat @ dipole / (4.0 * math.pi)  # Pa m^2 / (m/s^2)
    out = np.zeros(len(mics), PULSE_DTYPE)
    out["time_s"] = float(time_s) + (r - a) / c
    out["tau_s"] = float(tau_s)
    out["b0"] = k / r**2
    out["b1"] = k / (r * c)
    out["d1"] = a / c
    out["d2"] = a * a / (2.0 * c * c)
    out["channel"] = channel0 + np.arange(len(mics))
    return out

