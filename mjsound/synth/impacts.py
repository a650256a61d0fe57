"""Impacts on the synthesizer's objects (``Synthesizer.impact``, ``impacts`` and the per-step
driver's batched path).

An impulse ``J`` [N s] at surface point x at time ``t_e`` adds the complex modal amplitude
``c_i = (phi_i(x) . J) / w_i * S_i`` with ``S_i`` the half-sine contact pulse spectrum of the
Hertz contact time ``tau = coef v^(-1/5)`` (:mod:`.pulse`); the events are queued per
microphone (:mod:`.queue`, :func:`.kernels.impacts_to_queue`).
"""

from __future__ import annotations

import math

import numpy as np

from . import kernels
from .constants import MAX_AMPLITUDE
from .impact_energy import lost_energy
from .objects import finite_array
from .pulse import compliance, contact_time, effective, hertz_coef

__all__ = ["ImpactMethods"]


class ImpactMethods:
    """The impact methods of :class:`mjsound.synth.Synthesizer` (a mixin: it uses the
    synthesizer's objects, event queue ``_ev`` and kernel state)."""

    def impact(self, name, point, impulse, time, *, pulse_s=None, other_material=None, other_mass_kg=np.inf,
               other_radius_m=np.inf, speed=None, radius_m=None, effective_mass_kg=None) -> None:
        """One impact: impulse ``J`` [N s] (world vector) at world ``point`` [m] at ``time`` [s].

        Parameters
        ----------
        name : str
            Object struck.
        point : (3,) array_like
            Contact point in world coordinates [m] (snapped to the nearest surface sample).
        impulse : (3,) array_like
            Impulse vector on this object in world coordinates [N s].
        time : float
            Simulation time of the impact [s], not before :attr:`time` (minus 1 us tolerance).
        pulse_s : float, optional
            Contact time [s]; overrides Hertz (0 = ideal impulse).
        other_material : Material, optional
            Material of the other body; ``None`` means a rigid partner (infinite E).
        other_mass_kg, other_radius_m : float
            Other body's mass [kg] and radius of curvature at the contact [m] (inf: immovable / flat).
        speed : float, optional
            Normal approach speed [m/s]; default ``|J| / (m* (1 + e))`` with m* the effective
            mass and e the restitution (the smaller of the two materials'). Given, it also bounds
            the vibration energy the impact gives the object by ``|J| speed (1 - e) / 2``, the
            energy the collision takes from the approach (:mod:`.impact_energy`; the energy bound
            of :func:`.kernels.impacts_to_queue`, which the per-step driver always applies).
        radius_m : float, optional
            This object's radius of curvature at the contact [m]; default half its size.
        effective_mass_kg : float, optional
            The collision's effective mass along the normal [kg] (``|J| / ((1 + e) v)``, as the
            per-step driver gives it). Given, the object's modes are coupled to the contact
            that drives them (:mod:`.contact_coupling`; needs a contact time > 0): they take no
            more than the collision has. Default: the half-sine force alone.

        Notes
        -----
        ``tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5)`` (see :mod:`.pulse`); an object whose model
        has no mass, struck by an immovable body, gets an ideal impulse. Raises ``ValueError``
        (with the state unchanged) for an unknown object or NaN / Inf / out-of-range input.
        """
        self.impacts(name, np.reshape(np.asarray(point, dtype=np.float64), (1, -1)) if np.size(point) == 3 else point,
                     np.reshape(np.asarray(impulse, dtype=np.float64), (1, -1)) if np.size(impulse) == 3 else impulse,
                     np.atleast_1d(np.asarray(time, dtype=np.float64)) if np.size(time) == 1 else time,
                     pulse_s=pulse_s, other_material=other_material, other_mass_kg=other_mass_kg,
                     other_radius_m=other_radius_m, speed=speed, radius_m=radius_m,
                     effective_mass_kg=effective_mass_kg)

    def impacts(self, name, points, impulses, times, *, pulse_s=None, other_material=None,
                other_mass_kg=np.inf, other_radius_m=np.inf, speed=None, radius_m=None,
                effective_mass_kg=None) -> None:
        """Many impacts on one object at once (vectorised :meth:`impact`).

        ``points`` (k, 3) [m], ``impulses`` (k, 3) [N s], ``times`` (k,) [s]; ``pulse_s`` and
        ``speed`` and ``effective_mass_kg`` may be scalars or (k,) arrays. Much faster than k
        calls of :meth:`impact`.
        """
        ob = self._get(name)
        P = finite_array(points, "point", "give world coordinates in metres")
        J = finite_array(impulses, "impulse", "give a finite impulse vector in N s")
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"point must be (3,) or (k, 3) world coordinates, got shape {P.shape}")
        if J.shape != P.shape:
            raise ValueError(f"impulse must be a 3-vector per point (shape {P.shape}), got shape {J.shape}")
        k = len(P)
        if np.size(times) not in (1, k):
            raise ValueError(f"times must have one value per impact ({k}), got {np.size(times)}")
        t = finite_array(times, "time", "give simulation time in seconds").reshape(-1)
        t = self._check_time(np.broadcast_to(t, (k,)), "time")
        v = self._speeds(speed, k)
        # ---- pulse length
        if pulse_s is not None:
            tau = finite_array(pulse_s, "pulse_s", "give the contact time in seconds (>= 0)")
            if np.any(tau < 0):
                raise ValueError("pulse_s must be >= 0 seconds")
            tau = np.broadcast_to(tau, (k,)).astype(np.float64)
        else:
            m2 = float(other_mass_kg)
            R2 = float(other_radius_m)
            if math.isnan(m2) or m2 <= 0 or math.isnan(R2) or R2 <= 0:
                raise ValueError("other_mass_kg and other_radius_m must be positive (np.inf for immovable / flat)")
            if radius_m is not None:
                R1 = float(radius_m)
                if math.isnan(R1) or R1 <= 0:
                    raise ValueError(f"radius_m={radius_m!r} must be a positive radius in metres")
            tau = self._hertz_tau(ob, J, other_material, m2, R2, v, radius_m)
        if v is None:
            budget = np.full(k, np.inf)
        else:  # (the energy the collision takes from the approach, .impact_energy)
            e = self._restitution(ob, other_material)
            budget = np.array([lost_energy(j, vi, e) for j, vi in zip(np.sqrt(np.einsum("kc,kc->k", J, J)).tolist(),
                                                                       v.tolist())])
        mass = None
        if effective_mass_kg is not None:
            mass = finite_array(effective_mass_kg, "effective_mass_kg", "give the collision's effective mass in kg")
            if np.any(mass <= 0):
                raise ValueError("effective_mass_kg must be a positive mass in kg (leave it out for the half-sine "
                                 "force alone)")
            mass = np.broadcast_to(mass.reshape(-1), (k,)).astype(np.float64)
        if len(ob.keep) == 0 or k == 0:
            return
        self._impact_rows(np.full(k, ob.index, np.int64), P, J, t, tau, budget, mass)

    @staticmethod
    def _speeds(speed, k):
        """``speed`` as (k,) approach speeds [m/s], or None."""
        if speed is None:
            return None
        v = np.abs(finite_array(speed, "speed", "give the normal approach speed in m/s"))
        return np.broadcast_to(v, (k,)).astype(np.float64)

    def _hertz_coef(self, ob, other_material, m2, R2, radius_m):
        """``(coef, e)``: :func:`.pulse.hertz_coefficient` of ``ob`` against the other body
        (mass ``m2``, radius ``R2``; ``radius_m`` None: half the object's size) and the
        restitution of the pair."""
        m1, R1, c1 = self._struck_terms(ob, radius_m)
        e = self._restitution(ob, other_material)
        return hertz_coef(effective(m1, m2), effective(R1, R2), c1 + compliance(other_material)), e

    @staticmethod
    def _restitution(ob, other_material) -> float:
        """The restitution of ``ob`` struck by ``other_material`` (None: a rigid partner): the
        smaller of the two materials'."""
        e = ob.model.material.restitution
        return e if other_material is None else min(e, other_material.restitution)

    @staticmethod
    def _struck_terms(ob, radius_m):
        """``(mass [kg], radius [m], compliance [1/Pa])`` of object ``ob`` struck, for
        :func:`.pulse.hertz_coef`: its mass (inf: unknown), ``radius_m`` (None: half the
        object's size, inf when it has none) and its material's ``(1 - nu^2) / E``."""
        if radius_m is None:
            R1 = ob.model.size_m / 2 if ob.model.size_m > 0 else np.inf
        else:
            R1 = float(radius_m)
        return float(ob.mass), float(R1), compliance(ob.model.material)

    def hertz_terms(self, name, radius_m=None) -> tuple[float, float, float]:
        """What Hertz's contact time (:func:`.pulse.hertz_coef`) takes of object ``name`` when
        it is struck: ``(mass [kg], radius of curvature [m], compliance (1 - nu^2) / E
        [1/Pa])``; ``radius_m`` None: half the object's size (inf when it has none)."""
        return self._struck_terms(self._get(name), radius_m)

    def _hertz_tau(self, ob, J, other_material, m2, R2, v, radius_m):
        """Hertz contact time per impact (see :mod:`.pulse`); ``v`` None: from |J| / (m*(1+e))."""
        coef, e = self._hertz_coef(ob, other_material, m2, R2, radius_m)
        if v is None:
            mstar = effective(ob.mass, m2)
            v = np.sqrt(np.einsum("kc,kc->k", J, J)) / (mstar * (1 + e)) if not math.isinf(mstar) else np.zeros(len(J))
        return np.array([contact_time(coef, vi) for vi in np.asarray(v, np.float64).reshape(-1).tolist()])

    def _impact_rows(self, obj, P, J, t, tau, budget=None, mass=None) -> None:
        """Impacts in one numba call (:func:`.kernels.impacts_to_queue`; the per-step driver
        queues its own in numba: :func:`mjsound.sim.drive.queue_impacts`): impact ``i``
        strikes object index ``obj[i]`` at world ``P[i]`` with impulse ``J[i]`` [N s] at synth
        time ``t[i]`` >= :attr:`time` [s], pulse length ``tau[i]`` [s], at most the vibration
        energy ``budget[i]`` [J] (None: unbounded; rows with non-finite values are skipped),
        the modes coupled to a contact of effective mass ``mass[i]`` [kg] (None or 0: the
        half-sine force alone; :mod:`.contact_coupling`). State is unchanged on error."""
        self.reserve_impacts(len(obj))
        f64 = np.float64
        count, used, nxt, amax = kernels.impacts_to_queue(
            self.kernel_state(), obj, np.ascontiguousarray(P, f64), np.ascontiguousarray(J, f64),
            np.ascontiguousarray(t, f64), np.ascontiguousarray(tau, f64),
            np.full(len(obj), np.inf) if budget is None else np.ascontiguousarray(budget, f64),
            np.zeros(len(obj)) if mass is None else np.ascontiguousarray(mass, f64))
        if not (amax <= MAX_AMPLITUDE):  # also catches NaN
            raise self.amplitude_error(obj)
        kernels.commit_queued(self._ev.state, count, used, nxt)

    def reserve_impacts(self, k: int) -> None:
        """Room in the event queue for ``k`` more impacts (each at every microphone)."""
        if self._dirty:
            self._rebuild()
        M = self.n_channels
        self._ev.reserve(M * k, M * k * self._nmax)

    def amplitude_error(self, struck) -> ValueError:
        """The error for impacts on object indices ``struck`` whose modal amplitude is out of
        range (nothing of them was queued)."""
        names = sorted({self._by_index[int(o)].name for o in np.asarray(struck).tolist() if int(o) in self._by_index})
        return ValueError(
            f"impulse on {', '.join(map(repr, names))} gives a modal amplitude above {MAX_AMPLITUDE:g} Pa; "
            "check the impulse units (N s) and magnitude"
        )

    def object_index(self, name) -> int:
        """Index of object ``name`` in :meth:`kernel_state`'s tables (stable while it exists)."""
        return self._get(name).index

    def hertz_coefficient(self, name, other_material, other_mass_kg, other_radius_m, radius_m=None) -> float:
        """``coef`` [s (m/s)^(1/5)] of ``tau = coef v^(-1/5)`` for ``name`` struck by a body of
        ``other_material`` (None: rigid), mass and radius of curvature at the contact (inf:
        immovable / flat); ``radius_m`` None: half the object's size (:mod:`.pulse`)."""
        return self._hertz_coef(self._get(name), other_material, float(other_mass_kg), float(other_radius_m),
                                radius_m)[0]
