"""`SampleClock`: physics steps -> sample ranges, exactly (the time-alignment rule).

Sample ``n`` belongs to simulation time ``n / fs``. The step that advances the simulation
from ``t_k`` to ``t_{k+1}`` owns exactly the samples with ``t_k <= n/fs < t_{k+1}``, i.e.
``n`` from ``ceil(t_k fs)`` to ``ceil(t_{k+1} fs) - 1``. The boundaries are computed in
exact integer arithmetic: the timestep and the start time are turned into fractions
(``Fraction.limit_denominator(10**9)``, which recovers 1/1000, 7/10000, 1/3000 ... exactly)
and ``t_k = t_start + k * dt`` is never accumulated in floating point, so the total over a
run of ``T`` seconds is ``ceil(T fs)`` (``= round(T fs)`` whenever ``T fs`` is an integer)
with no drift over hours. The state is one :data:`.records.CLOCK` record, which the step
kernel advances in numba with the same integer formulas.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .records import CLOCK

__all__ = ["SampleClock"]


class SampleClock:
    """Maps physics steps to sample ranges exactly (no floating-point drift).

    Parameters
    ----------
    sample_rate : int
        Samples per second (integer) [Hz].
    timestep : float
        Physics step [s].
    t_start : float
        Simulation time of the first step's start [s].
    """

    def __init__(self, sample_rate: int, timestep: float, t_start: float = 0.0):
        fs = int(sample_rate)
        if fs != sample_rate or fs <= 0:
            raise ValueError(f"sample_rate must be a positive integer, got {sample_rate}")
        #: the clock's record (``k`` is advanced in place by the step kernel)
        self.rec = np.zeros(1, CLOCK)
        self.rec[0]["fs"] = fs
        self.fs = fs
        self._k = self.rec["k"]  # (a plain int64 view of the field: fast to use in Python)
        self.anchor(timestep, t_start)

    @property
    def k(self) -> int:
        """Steps counted since the anchor."""
        return int(self._k[0])

    @property
    def n(self) -> int:
        """First sample of the next step (absolute)."""
        return self.sample_at(self.k)

    def anchor(self, timestep: float, t_start: float) -> None:
        """Restart counting from ``t_start`` with step ``timestep``."""
        if not (np.isfinite(timestep) and timestep > 0):
            raise ValueError(f"timestep must be positive, got {timestep}")
        r = self.rec[0]
        r["timestep"] = self.timestep = float(timestep)
        r["t_start"] = self.t_start = float(t_start)
        dt = Fraction(float(timestep)).limit_denominator(10**9)
        t0 = Fraction(float(t_start)).limit_denominator(10**9)
        den = dt.denominator * t0.denominator // math.gcd(dt.denominator, t0.denominator)
        self._den = den
        self._a0 = t0.numerator * (den // t0.denominator)
        self._b = dt.numerator * (den // dt.denominator)
        r["den"], r["a0"], r["b"], r["k"] = den, self._a0, self._b, 0
        # last step whose start time and first sample fit int64 exactly (a0 + k b < 2^53 and
        # (a0 + k b) fs < 2^62): the step kernel counts steps in int64 up to there
        self.k_max_int64 = (min(2**53, 2**62 // self.fs) - abs(self._a0)) // self._b - 1

    def sample_at(self, k: int) -> int:
        """First sample at or after ``t_start + k * timestep``: ``ceil(t fs)``."""
        num = (self._a0 + k * self._b) * self.fs
        return -((-num) // self._den)

    def time_at(self, k: int) -> float:
        """``t_start + k * timestep`` [s] (float, for reporting)."""
        return (self._a0 + k * self._b) / self._den  # int / int: correctly rounded, as float(Fraction)

    def span(self, steps: int) -> tuple[int, int, int]:
        """``(k, n0, n1)``: the steps counted now, and the samples ``n0 <= n < n1`` of the next
        ``steps`` steps (:meth:`sample_at` of ``k`` and ``k + steps``), without counting them."""
        k = int(self._k[0])
        a0, b, fs, den = self._a0, self._b, self.fs, self._den  # (sample_at's formula, written out: per env step)
        return k, -((-(a0 + k * b) * fs) // den), -((-(a0 + (k + steps) * b) * fs) // den)

    def advance(self, steps: int = 1) -> tuple[int, int]:
        """Count ``steps`` steps; returns ``(n0, n1)``, their samples ``n0 <= n < n1``."""
        k = self.k
        self._k[0] = k + steps
        return self.sample_at(k), self.sample_at(k + steps)
