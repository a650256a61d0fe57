"""The most vibration energy one impact can give the objects: the energy the collision takes
from the approach.

Two bodies approach along the contact normal at ``v`` [m/s] with the effective mass ``m*``
(for several contact points, the contact-space inverse inertia ``A``). An impact with
restitution ``e`` leaves them separating at ``e v``, with the impulse ``J = m* (1 + e) v``
(``lambda = A^+ (1 + e) v``), so it takes from their relative motion

    E_lost = m* v^2 (1 - e^2) / 2 = |J| v (1 - e) / 2            [J]

(for several points, ``(1 - e^2) v^T A^+ v / 2 = (1 - e) sum_r lambda_r v_r / 2``: one
``|J_r| v_r (1 - e) / 2`` per point sums to it). The vibration of both objects, the contact's
plastic work and heat all come out of ``E_lost``, so no impact gives the modes more (the energy
bound of :func:`.kernels.impacts_to_queue`). The work of the whole impulse, ``|J| v / 2 =
(1 + e) m* v^2 / 2``, exceeds even the approach's kinetic energy ``m* v^2 / 2`` for any
``e > 0``: that bound let a 4 kg limb striking the floor at 3.6 m/s (``e = 0.55``) ring
with 1.5 times the collision's kinetic energy.
"""

from __future__ import annotations

import math

from ..jit import njit

__all__ = ["lost_energy", "collision_mass"]


@njit(cache=True)
def lost_energy(impulse, speed, restitution):
    """``|J| v (1 - e) / 2`` [J]: the energy an impact of impulse ``J`` [N s] at the approach
    speed ``v`` [m/s] with restitution ``e`` takes from the approach (module docstring); ``inf``
    (no bound) when ``v`` is not positive or not finite; ``e`` outside [0, 1] (or NaN) is taken
    as 0, the plastic hit (the bound ``|J| v / 2``, the loosest).

    Examples
    --------
    >>> lost_energy(10.0, 2.0, 0.5)   # m* = 10 / (1.5 * 2) kg: m* v^2 (1 - e^2) / 2 = 5 J
    5.0
    """
    if not (speed > 0) or math.isinf(speed):
        return math.inf
    e = restitution if 0.0 <= restitution <= 1.0 else 0.0
    return 0.5 * abs(impulse * speed) * (1.0 - e)


@njit(cache=True)
def collision_mass(impulse, speed, restitution):
    """The collision's effective mass ``m* = |J| / ((1 + e) v)`` [kg] along the normal, from
    the impulse ``J`` [N s] it was given at the approach speed ``v`` [m/s] with restitution
    ``e`` (``J = m* (1 + e) v``; ``e`` outside [0, 1] or NaN taken as 0, as
    :func:`lost_energy` does); 0 (unknown) when ``v`` is not positive and finite or ``J`` is not
    finite. The mass the struck object's modes are coupled to
    (:mod:`.contact_coupling`).

    Examples
    --------
    >>> collision_mass(10.0, 2.0, 0.25)   # 10 / (1.25 * 2)
    4.0
    """
    if not (speed > 0) or math.isinf(speed) or not math.isfinite(impulse):
        return 0.0
    e = restitution if 0.0 <= restitution <= 1.0 else 0.0
    return abs(impulse) / ((1.0 + e) * speed)
