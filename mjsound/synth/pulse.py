"""Contact force pulses: Hertz contact time and the half-sine pulse spectrum.

A real impact between two bodies is not a Dirac impulse: the contact force rises and falls
over the *contact time* tau, which for two elastic bodies follows Hertz's theory
(Johnson, *Contact Mechanics*, 1985, sec. 11.4)::

    tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5)

    1/m* = 1/m1 + 1/m2                      effective mass [kg]
    1/R* = 1/R1 + 1/R2                      effective radius of curvature [m]
    1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2  effective modulus [Pa]
    v                                       normal approach speed [m/s]

Steel on steel at 1 m/s (m* ~ 0.1 kg, R* ~ 1 cm) gives tens of microseconds: bright. Rubber
gives milliseconds: a dull thud. The force is modelled as a half sine of length tau and unit
area (total impulse J), whose spectrum (including the pulse's own delay) is::

    S(w) = (1 + e^{-j w tau}) / (2 (1 - (w tau / pi)^2))

so S(0) = 1 (a short pulse is an ideal impulse), S -> -j pi / 4 at w tau = pi (a removable
singularity, evaluated here with a series-stable form), and |S| falls as 1/(w tau)^2 above.

A thin hollow shell (wall ``t`` much thinner than its radius of curvature ``R``) is struck
through the bending of its wall, not through Hertz's local compression of a solid: a point load
on a closed spherical shell deflects it linearly, with stiffness (Reissner, *J. Math. Phys.* 25,
1946, shallow spherical shells; valid while ``t / R`` is small)::

    k = 4 E t^2 / (R sqrt(3 (1 - nu^2)))       [N/m]

and the struck mass on that spring touches for half its period,
``tau_shell = pi sqrt(m* (1/k1 + 1/k2))`` (two shells: springs in series;
:func:`shell_compliance`, :func:`shell_contact_time`). A 2.7 g table-tennis ball of ABS (radius
20 mm, a wall of 0.5 mm) gives 0.6 ms on a rigid floor, against 90 us (at 1 m/s) of Hertz for a
solid ball of its mass, radius and material; a measured ball touches a hard surface for about
1 ms (the ball's wall flattens and buckles inward, softening as it goes: the linear spring is
the stiff end of it).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, njit_inner

__all__ = ["hertz_contact_time", "hertz_coefficient", "compliance", "contact_time", "shell_compliance",
           "shell_contact_time", "half_sine_spectrum", "half_sine", "half_sine_rotated", "effective", "hertz_coef", "TAU_MIN_S", "TAU_MAX_S"]

#: Contact times are clamped to [TAU_MIN_S, TAU_MAX_S] seconds. The lower bound is far below
#: any audible period (a 1 us pulse is flat to 100 kHz); the upper bound keeps a near-zero
#: approach speed from producing an infinite pulse (such a pulse is inaudible anyway).
TAU_MIN_S = 1e-7
TAU_MAX_S = 1.0


@njit(cache=True)
def effective(a, b):
    """Harmonic combination ``1 / (1/a + 1/b)`` with ``inf`` meaning "absent" (rigid/huge).

    Returns ``inf`` when both are infinite, and 0 when either is 0 (the limit: a massless body
    welded to a moving one has no subtree mass; its Hertz time is then the shortest). numba:
    the one home of this formula, called from Python and from the per-step kernels (the modes'
    and the clicks' Hertz times).
    """
    if math.isinf(a):
        return b
    if math.isinf(b):
        return a
    if a == 0.0 or b == 0.0:
        return 0.0
    return 1.0 / (1.0 / a + 1.0 / b)


def compliance(mat) -> float:
    """(1 - nu^2) / E [1/Pa]; 0 for a rigid body (``mat is None``)."""
    if mat is None:
        return 0.0
    return (1.0 - float(mat.nu) ** 2) / float(mat.E)


def hertz_contact_time(m1, m2, R1, R2, mat1, mat2, v) -> float:
    """Hertz contact duration of an elastic impact [s].

    Parameters
    ----------
    m1, m2 : float
        Masses of the two bodies [kg]; ``np.inf`` for an immovable body.
    R1, R2 : float
        Radii of curvature at the contact [m]; ``np.inf`` for a flat surface.
    mat1, mat2 : Material or None
        Materials (``E`` [Pa] and ``nu`` used); ``None`` is a rigid body (infinite E).
    v : float
        Normal approach speed [m/s] (its absolute value is used).

    Returns
    -------
    float
        ``tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5)`` clamped to [``TAU_MIN_S``, ``TAU_MAX_S``].
        If both masses are infinite, both radii infinite or both bodies rigid the contact is
        infinitely hard/short and ``TAU_MIN_S`` is returned; ``v == 0`` gives ``TAU_MAX_S``.

    Raises
    ------
    ValueError
        For a NaN or negative mass/radius or a NaN speed.
    """
    vals = {"m1": m1, "m2": m2, "R1": R1, "R2": R2}
    for k, x in vals.items():
        x = float(x)
        if math.isnan(x) or x <= 0:
            raise ValueError(f"hertz_contact_time: {k}={x!r} must be positive (np.inf for 'infinite')")
    v = abs(float(v))
    if math.isnan(v):
        raise ValueError("hertz_contact_time: speed v is NaN; give the normal approach speed in m/s")
    m = effective(float(m1), float(m2))
    return contact_time(hertz_coefficient(m, effective(float(R1), float(R2)), mat1, mat2), v)


def hertz_coefficient(m, R, mat1, mat2) -> float:
    """``coef`` [s (m/s)^(1/5)] of ``tau = coef v^(-1/5)`` for effective mass ``m`` [kg] and
    radius ``R`` [m] (``inf``: immovable / flat) between ``mat1`` and ``mat2`` (``None``:
    rigid); 0 when the contact is infinitely hard (see :func:`contact_time`).
    :func:`hertz_coef` with the materials' compliances summed."""
    return hertz_coef(float(m), float(R), compliance(mat1) + compliance(mat2))


@njit(cache=True)
def hertz_coef(m, R, c):
    """``coef = 2.87 (m^2 / (R E*^2))^(1/5)`` [s (m/s)^(1/5)] of ``tau = coef v^(-1/5)`` for
    effective mass ``m`` [kg], effective radius ``R`` [m] and ``c = 1 / E*``, the sum of the two
    materials' compliances ``(1 - nu^2) / E`` [1/Pa]; 0 (infinitely hard: :func:`contact_time`
    gives ``TAU_MIN_S``) when ``m`` or ``R`` is infinite or ``c`` is 0. numba: the one home of
    Hertz's formula, for the modes' pulses (:func:`mjsound.sim.drive.impact_sides`), the clicks
    (:func:`mjsound.sim.click_kernels.hertz_coefficient`) and Python (:func:`hertz_coefficient`)."""
    if math.isinf(m) or math.isinf(R) or c == 0.0:
        return 0.0
    E = 1.0 / c
    return 2.87 * (m * m / (R * E * E)) ** 0.2


@njit(cache=True)
def contact_time(coef, v):
    """``coef |v|^(-1/5)`` clamped to [``TAU_MIN_S``, ``TAU_MAX_S``] [s]; ``coef == 0``
    (infinitely hard) gives ``TAU_MIN_S``, ``v == 0`` ``TAU_MAX_S``. (numba: also called
    from the per-step kernels.)"""
    v = abs(v)
    if coef == 0.0:
        return TAU_MIN_S
    if not v > 0:
        return TAU_MAX_S
    return min(max(coef * v**-0.2, TAU_MIN_S), TAU_MAX_S)


def shell_compliance(mat, wall, radius) -> float:
    """Point-load compliance ``1 / k`` [m/N] of a thin closed shell of ``mat``: Reissner's
    ``k = 4 E t^2 / (R sqrt(3 (1 - nu^2)))`` (see the module docstring).

    Parameters
    ----------
    mat : Material
        ``E`` [Pa] and ``nu`` used.
    wall : float
        Wall thickness ``t`` [m], > 0.
    radius : float
        Radius of curvature ``R`` of the wall at the load [m], > 0 and finite.

    Returns
    -------
    float : ``R sqrt(3 (1 - nu^2)) / (4 E t^2)`` [m/N]; 0 (not a shell: infinitely stiff) for
    a non-positive or non-finite wall or radius.
    """
    t, R = float(wall), float(radius)
    if not (math.isfinite(t) and t > 0 and math.isfinite(R) and R > 0):
        return 0.0
    nu = float(mat.nu)
    return R * math.sqrt(3.0 * (1.0 - nu * nu)) / (4.0 * float(mat.E) * t * t)


@njit(cache=True)
def shell_contact_time(mass, shell_compliance_1, shell_compliance_2):
    """Contact time [s] of a mass on the two walls' point-load springs in series, half the
    period: ``pi sqrt(mass (s1 + s2))``, clamped to [``TAU_MIN_S``, ``TAU_MAX_S``]. (numba:
    called from the impact kernel, :func:`mjsound.sim.click_kernels.pair_contact_time`.)

    Parameters
    ----------
    mass : float
        Effective mass ``m*`` of the impact [kg] (``1/m* = 1/m1 + 1/m2``; inf: immovable).
    shell_compliance_1, shell_compliance_2 : float
        Each side's :func:`shell_compliance` ``s = 1/k`` [m/N]; 0 for a solid.

    Returns
    -------
    float : [s]; 0 when neither side is a shell or the mass is infinite, not positive or NaN
    (the contact is then Hertz's alone).
    """
    s = shell_compliance_1 + shell_compliance_2
    if not (s > 0 and mass > 0) or math.isinf(mass):
        return 0.0
    return min(max(math.pi * math.sqrt(mass * s), TAU_MIN_S), TAU_MAX_S)


def half_sine_spectrum(omega, tau) -> np.ndarray:
    """Spectrum of a unit-area half-sine force pulse of length ``tau``.

    ``S(w) = (1 + e^{-j w tau}) / (2 (1 - (w tau / pi)^2))``.

    Parameters
    ----------
    omega : array_like
        Angular frequencies [rad/s] (any shape).
    tau : float or array_like
        Pulse length [s], broadcast against ``omega``; ``0`` gives the ideal impulse (S = 1).

    Returns
    -------
    complex128 ndarray, shape of ``broadcast(omega, tau)``.

    Notes
    -----
    Near ``x = w tau = pi`` both numerator and denominator vanish. With ``u = x - pi``,
    ``1 + e^{-jx} = -expm1(-j u)`` and ``2 (1 - (x/pi)^2) = -2 u (2 pi + u) / pi^2``, so
    ``S = pi^2 expm1(-j u) / (2 u (2 pi + u))``, which is accurate for small ``u`` and tends
    to ``-j pi / 4``.
    """
    x = np.asarray(np.asarray(omega, dtype=np.float64) * np.asarray(tau, dtype=np.float64))
    return _half_sine_many(x.ravel()).reshape(x.shape)[()]


@njit_inner(cache=True)
def half_sine(x):
    """:func:`half_sine_spectrum` at one ``x = w tau`` (numba: the synthesizer's kernels call it)."""
    return half_sine_rotated(x, np.exp(-1j * x))


@njit_inner(cache=True)
def half_sine_rotated(x, end):
    """:func:`half_sine` at ``x`` given ``end = e^{-j x}`` (the pulse's end as a phase factor,
    which a caller stepping along a frequency grid has by rotation)."""
    u = x - np.pi
    if abs(u) >= 0.25:
        return (1.0 + end) / (2.0 * (1.0 - (x / np.pi) ** 2))
    if u == 0.0:
        return -1j * np.pi / 4.0
    # expm1(-j u) without cancellation: cos(u) - 1 = -2 sin^2(u / 2)
    s = np.sin(0.5 * u)
    em1 = -2.0 * s * s - 1j * np.sin(u)
    return np.pi**2 * em1 / (2.0 * u * (2.0 * np.pi + u))


@njit(cache=True)
def _half_sine_many(x):
    out = np.empty(x.shape[0], np.complex128)
    for i in range(x.shape[0]):
        out[i] = half_sine(x[i])
    return out
