"""What :class:`mjsound.sim.contacts.ContactReader` hands out as objects (diagnostics, tests
and users who read contacts and impacts): a step's contacts, its impact and sustained-contact
events, and an impact event's record (the predicted impulse next to MuJoCo's).

The per-step path does not make them: the step kernel writes rows of the records in
:mod:`.records`, and the reader turns them into these objects when they are read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ContactFrame", "ImpactEvent", "ContactEvent", "ImpactRecord"]


@dataclass
class ContactFrame:
    """All contacts of one step, as arrays over the ``n`` contacts (world frame, SI).

    Attributes
    ----------
    geom : (n, 2) int
        ``geom[:, 0]``, ``geom[:, 1]``; the normal points from the first to the second.
    pos : (n, 3) contact point [m].
    normal : (n, 3) unit normal.
    dist : (n,) signed distance [m] (negative: penetration).
    force_n : (n,) normal force on geom 1 along ``normal`` [N] (clamped, finite).
    force : (n, 3) world force on geom 1 [N] (geom 0 gets the opposite).
    vel_rel : (n, 3) velocity of geom 1's material point minus geom 0's at ``pos`` [m/s].
    v_approach : (n,) ``-(vel_rel . normal)``; positive when closing [m/s].
    v_slip : (n,) tangential slip speed [m/s].
    v_roll : (n,) rolling speed ``|omega_rel,t| r`` [m/s].
    local : (n, 2, 3) contact point in each geom's frame [m] (computed on demand).
    """

    geom: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    dist: np.ndarray
    force_n: np.ndarray
    force: np.ndarray
    vel_rel: np.ndarray
    v_approach: np.ndarray
    v_slip: np.ndarray
    v_roll: np.ndarray
    local: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.geom)


@dataclass
class ImpactEvent:
    """One impact at one contact point.

    ``impulse`` [N s] acts on ``geom2`` along ``normal`` (``geom1`` gets ``-impulse``).
    """

    time: float
    geom1: int
    geom2: int
    point: np.ndarray
    normal: np.ndarray
    impulse: float
    speed: float
    effective_mass: float


@dataclass
class ContactEvent:
    """Sustained contact of a pair over ``[t0, t1)``: ``kind`` is ``"slide"`` or ``"roll"``."""

    kind: str
    t0: float
    t1: float
    geom1: int
    geom2: int
    point: np.ndarray
    normal: np.ndarray
    force_n: float
    speed: float


@dataclass
class ImpactRecord:
    """Predicted and simulated impulse of one impact event (diagnostics).

    Attributes
    ----------
    time : onset time [s].
    geom1, geom2 : geom ids.
    speed : largest pre-contact approach speed [m/s].
    impulse_pred : emitted ``sum lambda = sum A^+ (1+e) v`` [N s].
    impulse_sim : MuJoCo's ``sum F_n dt`` over the event [N s].
    restitution : ``e`` used.
    effective_mass : ``impulse_pred / ((1+e) speed)`` [kg].
    duration : event length [s]; ``steps`` physics steps.
    """

    time: float
    geom1: int
    geom2: int
    speed: float
    impulse_pred: float
    impulse_sim: float
    restitution: float
    effective_mass: float
    duration: float = 0.0
    steps: int = 0
    open: bool = True
