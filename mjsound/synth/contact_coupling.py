"""The struck object's modes coupled to the contact that excites them.

The modes of an impact (:func:`.kernels.impacts_to_queue`) were driven by a prescribed force:
the half-sine pulse of Hertz's contact time ``tau`` carrying the impulse ``J`` of the
rigid-body collision (:mod:`.pulse`), ``c_m = phi_m(x).J S(w_m tau) / w_m``. That is the first
term of a coupled problem: while the bodies touch, the struck surface moves with the modes it
excites and pushes back on the contact, so the force is lower and lasts longer than the rigid
bodies' pulse. Prescribing the force is right while the modes take a small share of the
collision and wrong where they do not: HalfCheetah's 6.6 kg aluminium torso landing at
1.3 m/s asks for modal energy 9 times the collision's kinetic energy, SO-101's 0.08 kg gripper
at 3.2 m/s 25 times, which no impact can give; the energy bound (:mod:`.impact_energy`) then
handed the modes the whole energy the collision loses (``scripts/diagnose_levels.py``).

Model (Chaigne and Doutaut, "Numerical simulations of xylophones. I. Time-domain modeling of
the vibrating bars", J. Acoust. Soc. Am. 101(1), 1997: a mallet on a modal bar through Hertz's
contact law; Avanzini and Rocchesso, "Modeling collision sounds: non-linear contact force",
Proc. DAFx 2001, the same in modal sound synthesis). Along the impulse's direction ``n`` the
two bodies close at ``v`` with the collision's effective mass ``m*`` (the impulse prediction's
``|J| / ((1 + e) v)``, :mod:`mjsound.sim.impulses`: the articulated chain included), their
relative displacement ``y``; the struck surface point moves with the modes,
``u = sum_m g_m q_m`` (``g_m = phi_m(x).n`` [1/sqrt(kg)], mass-normalised modes, poles
``lambda_m = -d_m + j w_m``); the contact is Hertz's (Johnson, *Contact Mechanics*, 1985,
sec. 11.4), with the constant ``K`` that gives the rigid bodies the contact time ``tau`` the
rest of mjsound uses (the deepest approach ``tau v / 2.9432``, where the kinetic energy
``m* v^2 / 2`` is ``2 K d^(5/2) / 5``)::

    F = K max(0, y - u)^(3/2)                 (the contact pushes, never pulls)
    m* y'' = -F,                              y(0) = 0, y'(0) = v
    q_m'' + 2 d_m q_m' + |lambda_m|^2 q_m = g_m F

The elastic system conserves ``m* v^2 / 2`` (less the modes' damping), so the modes never take
more than the collision has however light the struck point is, and the slow modes of a long
body may meet the receding body again and give energy back (the micro-collisions of bars
dropped on a floor: Stoianovici and Hurmuzlu, "A critical study of the applicability of
rigid-body collision theory", J. Appl. Mech. 63(2), 1996). The restitution's loss is the
contact's plastic work, which scales the force and keeps its shape (as :mod:`.pulse` assumes):
the result is scaled by ``|J| / (2 m* v)``. :func:`coupled_response` gives each mode's complex
amplitude when the contact is over (the last re-contact included), at ``T`` after its start,
and the impact's modes are queued from then on (:func:`.kernels.impacts_to_queue`: during the
contact the modes are forced, not ringing; referring the amplitude back to the start would
multiply a strongly damped mode by ``e^{d T}``). Weakly coupled modes hear Hertz's own pulse:
the half sine's impulse below ``w tau = 1`` and a little more above (Hertz's pulse, of the
same length, is more peaked). An impact whose modes do not push back at all (every ``g_m = 0``)
or that has no contact time keeps the half sine's closed form. The energy bound stays as a
check.

Numerics: each mode is advanced exactly over a step ``h`` under the force held at its midpoint
value; that force is solved for with the give of the rigid motion and of every mode to it over
the half step (the contact in series with them: stable however light the struck point is);
the rigid motion is the half sine's ``y0`` plus its own correction. ``h`` is at most
``tau / 32`` and half the inverse loop frequency ``(pi / tau) sqrt(1 + m* sum g^2)``
(the contact against the struck point's modal masses), at least ``MAX_CONTACTS_TAU tau /
MAX_STEPS``. The run ends when the bodies are further apart than the struck point's free modes
can reach (no re-contact can follow), or at ``MAX_CONTACTS_TAU`` contact times: 40 to 230 steps
for the stock envs' impacts (``tests/test_contact_coupling.py`` checks the result against a
converged integration).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit

__all__ = ["coupled_response", "MAX_STEPS", "MAX_CONTACTS_TAU", "HERTZ_TIME"]

#: Most integration steps of one impact (``h`` is raised to ``MAX_CONTACTS_TAU tau / MAX_STEPS``
#: above that: a struck point so light that the loop frequency asks for more).
MAX_STEPS = 4096
#: Hertz's contact time over ``d_max / v`` (the deepest approach over the approach speed):
#: ``tau = 2.9432 d_max / v`` (Johnson, *Contact Mechanics*, 1985, sec. 11.4).
HERTZ_TIME = 2.9432
#: The longest the coupled contact is followed, in contact times ``tau``.
MAX_CONTACTS_TAU = 32.0


@njit(cache=True)
def coupled_response(g, lam, tau, mass, out, resolution=1.0):
    """The modes' ringing after a contact they are coupled to, per unit impulse.

    Parameters
    ----------
    g : (n,) float64
        Each mode's coupling ``phi_m(x) . n`` at the struck point along the impulse's unit
        direction ``n`` [1/sqrt(kg)].
    lam : (n,) complex128
        Poles ``-d_m + j w_m`` [1/s] (``w_m > 0``).
    tau : float
        Hertz's contact time of the rigid bodies [s] (> 0).
    mass : float
        Effective mass ``m*`` of the collision along ``n`` [kg] (> 0, finite).
    out : (n,) complex128
        Receives ``C_m`` [m sqrt(kg) / (N s)]: mode ``m`` rings as
        ``q_m(t) = |J| Im(C_m e^{lambda_m (t - T)})`` from the end ``T`` of the contact on
        (module docstring), for the impulse ``|J|``. 0 where nothing was integrated.
    resolution : float
        Divides the integration step (1: the step of the module docstring; larger for a
        convergence check).

    Returns
    -------
    (steps, T) : (int, float)
        Integration steps taken and the time from the contact's start to its end [s]
        (``(0, 0.0)`` when nothing was integrated: no contact time or mass, or every
        ``g_m = 0``; the half sine's closed form is then the whole answer).

    Raises
    ------
    ValueError
        When ``g``, ``lam`` and ``out`` differ in length.

    Examples
    --------
    >>> import numpy as np
    >>> out = np.zeros(1, np.complex128)
    >>> coupled_response(np.zeros(1), np.array([-1 + 2j * np.pi * 1000]), 1e-4, 1.0, out)
    (0, 0.0)
    """
    n = g.shape[0]
    if lam.shape[0] != n or out.shape[0] != n:
        raise ValueError("coupled_response: g, lam and out must have one entry per mode")
    for m in range(n):
        out[m] = 0.0
    if not (tau > 0 and mass > 0 and math.isfinite(tau) and math.isfinite(mass)):
        return 0, 0.0
    sg2 = 0.0
    for m in range(n):
        sg2 += g[m] * g[m]
    if sg2 == 0.0 or not math.isfinite(sg2):
        return 0, 0.0
    omega = math.pi / tau
    k = mass * omega * omega  # (the half sine's linear spring: the reference rigid motion y0)
    d_max = tau / HERTZ_TIME  # Hertz's deepest approach at unit speed, and his constant K
    hertz = 1.25 * mass / d_max**2.5
    loop = omega * math.sqrt(1.0 + mass * sg2)
    h = min(tau / 32.0, 0.5 / loop) / resolution
    t_max = MAX_CONTACTS_TAU * tau
    if t_max / h > MAX_STEPS:
        h = t_max / MAX_STEPS
    # per mode: the step's propagator e^{lambda h}, 1 / |lambda|^2 and 1 / w
    prop = np.empty(n, np.complex128)
    inv_w0sq = np.empty(n)
    inv_w = np.empty(n)
    for m in range(n):
        prop[m] = np.exp(lam[m] * h)
        inv_w0sq[m] = 1.0 / (lam[m].real * lam[m].real + lam[m].imag * lam[m].imag)
        inv_w[m] = 1.0 / lam[m].imag
    q = np.zeros(n)
    qd = np.zeros(n)
    eta = 0.0  # the bodies' relative displacement less y0's, the half sine's (unit approach speed)
    etad = 0.0
    t = 0.0
    steps = 0
    # the midpoint's give under a force held from the step's start: rigid h^2 / (8 m*), each
    # mode g^2 (1 - cos(w h / 2)) / |lambda|^2 [m/N] (the force is solved for with it: stable
    # however light the struck point)
    give = 0.125 * h * h / mass
    for m in range(n):
        give += g[m] * g[m] * (1.0 - math.cos(0.5 * h * lam[m].imag)) * inv_w0sq[m]
    while t < t_max:
        tm = t + 0.5 * h
        y0 = math.sin(omega * tm) / omega if tm < tau else -(tm - tau)
        f0 = k * y0 if y0 > 0 else 0.0
        u = 0.0
        for m in range(n):
            u += g[m] * (q[m] + 0.5 * h * qd[m])
        gap = y0 + eta + 0.5 * h * etad + 0.125 * h * h * f0 / mass - u  # (with no force this step)
        f = _hertz_force(hertz, gap, give)
        for m in range(n):
            qs = g[m] * f * inv_w0sq[m]  # static response to the step's force
            a = q[m] - qs
            c = ((qd[m] - lam[m].real * a) * inv_w[m] + 1j * a) * prop[m]
            q[m] = c.imag + qs
            qd[m] = lam[m].real * c.imag + lam[m].imag * c.real
        df = f - f0
        eta += h * etad - 0.5 * h * h * df / mass
        etad -= h * df / mass
        t += h
        steps += 1
        if f == 0.0 and t > tau and (steps & 7) == 0 and _apart(g, lam, q, qd, -(t - tau) + eta, etad - 1.0):
            break
    scale = 1.0 / (2.0 * mass)  # per unit impulse: the elastic pulse's is 2 m* (unit speed)
    for m in range(n):
        out[m] = ((qd[m] - lam[m].real * q[m]) * inv_w[m] + 1j * q[m]) * scale
    return steps, t


@njit(cache=True)
def _hertz_force(hertz, gap, give):
    """The force ``F`` [N] with ``F = K max(0, gap - give F)^(3/2)`` (Hertz's law on the gap
    left once the bodies and modes give ``give F`` [m] to it): the root of a monotone function
    by safeguarded Newton steps; 0 when ``gap <= 0``."""
    if not gap > 0:
        return 0.0
    hi = hertz * gap**1.5
    if give > 0 and gap / give < hi:
        hi = gap / give
    lo = 0.0
    x = hi
    for _ in range(40):
        r = gap - give * x
        if r <= 0:
            phi = x
            dphi = 1.0
        else:
            sr = math.sqrt(r)
            phi = x - hertz * r * sr
            dphi = 1.0 + 1.5 * hertz * sr * give
        if phi > 0:
            hi = x
        else:
            lo = x
        nxt = x - phi / dphi
        if not (lo < nxt < hi):
            nxt = 0.5 * (lo + hi)
        if abs(nxt - x) <= 1e-12 * hi:
            return nxt
        x = nxt
    return x


@njit(cache=True)
def _apart(g, lam, q, qd, y, yd):
    """Whether a contact is over for good: the bodies separate (``yd <= 0``) and are further
    apart than the struck point can ever reach, ``y < -sum_m |g_m| |C_m|`` (``C_m`` the free
    modes' complex amplitudes, which only decay): no re-contact can follow."""
    if yd > 0:
        return False
    reach = 0.0
    for m in range(g.shape[0]):
        d = -lam[m].real
        w = lam[m].imag
        a = (qd[m] + d * q[m]) / w
        reach += abs(g[m]) * math.sqrt(a * a + q[m] * q[m])
    return y < -reach
