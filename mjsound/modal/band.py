"""The band an analysis covers: ``f_max`` from the sample rate, and where a material stops
ringing. (A light module: the scene asks it before deciding whether to analyse at all.)"""

from __future__ import annotations

import numpy as np

from ..materials import Material

__all__ = ["F_MIN_HZ", "MIN_Q", "default_f_max", "ringing_below"]

#: Modes below this are not audible and not returned [Hz].
F_MIN_HZ = 20.0


def default_f_max(sample_rate: float | None = None) -> float:
    """min(20 kHz, 0.45 fs) [Hz]."""
    return 20000.0 if sample_rate is None else min(20000.0, 0.45 * float(sample_rate))


#: Modes whose quality factor omega / (2 d) falls below this ring for less than a cycle:
#: the analysis stops at the frequency where Rayleigh damping reaches it.
MIN_Q = 2.0


def ringing_below(material: Material, q_min: float = MIN_Q) -> float:
    """Frequency [Hz] above which Rayleigh damping leaves every mode a quality factor < q_min.

    ``d = (alpha + beta w^2) / 2 = w / (2 Q)`` at ``w = (1/Q + sqrt(1/Q^2 - 4 alpha beta)) / (2 beta)``;
    inf without stiffness damping, 0 when no frequency reaches ``q_min``.
    """
    a, b = material.alpha, material.beta
    if b <= 0:
        return float("inf")
    disc = 1.0 / q_min**2 - 4 * a * b
    if disc < 0:
        return 0.0
    return float((1.0 / q_min + np.sqrt(disc)) / (2 * b) / (2 * np.pi))
