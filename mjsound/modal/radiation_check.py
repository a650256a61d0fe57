"""Comparing far-field patterns of the same modes: per mode (degenerate groups summed) and per
direction, as the tests and the accuracy report do against the converged references
(``scripts/reference_radiation.py``)."""

from __future__ import annotations

import numpy as np

__all__ = ["LEVEL_OBJECTS", "REFERENCE_DEGREE", "degenerate_groups", "pattern_errors"]

#: the four objects whose levels are checked against converged references (issue "levels"):
#: name -> (mesh, material, analyze keywords). The references live in
#: ``tests/data/radiation_<name>.npz`` (``scripts/reference_radiation.py``).
LEVEL_OBJECTS = {
    "plate": ("box:0.2,0.2,0.002", "aluminium", dict(f_max=1000.0)),
    "bar": ("box:0.3,0.02,0.02", "aluminium", dict(f_max=6000.0)),
    "bowl": ("bowl:0.05,0.004", "ceramic", dict(f_max=9000.0)),
    "can": ("cylinder:0.033,0.12", "steel", dict(f_max=4500.0, wall=0.002, method="facet")),
}
#: the references' far fields are stored on this degree's quadrature (242 directions)
REFERENCE_DEGREE = 10


def degenerate_groups(frequencies_hz, rel: float = 0.01) -> np.ndarray:
    """Group number of each mode (ascending frequencies): modes within ``rel`` of the
    previous one share a group, since any rotation within a degenerate pair is as valid."""
    f = np.asarray(frequencies_hz, float)
    if len(f) == 0:
        return np.zeros(0, int)
    return np.cumsum(np.r_[True, np.diff(f) > rel * f[1:]]) - 1


def pattern_errors(F, F_ref, weights, groups, floor_db: float = 20.0):
    """Level errors of far fields ``F`` against ``F_ref`` (both (n_dirs, n_modes) on a
    quadrature with ``weights``), per degenerate group.

    Returns
    -------
    power_db : (n_groups,) error of the radiated power, ``10 log10(W / W_ref)`` [dB]
    direction_db : (n_groups,) the largest error of ``sum |F|^2`` over the group's modes
        among the directions where the reference is within ``floor_db`` of its maximum [dB]
    """
    P = np.abs(np.asarray(F)) ** 2
    Pr = np.abs(np.asarray(F_ref)) ** 2
    n = int(groups.max()) + 1 if len(groups) else 0
    power, direction = np.zeros(n), np.zeros(n)
    for g in range(n):
        cols = groups == g
        pg, pr = P[:, cols].sum(axis=1), Pr[:, cols].sum(axis=1)
        power[g] = 10 * np.log10((weights @ pg) / (weights @ pr))
        loud = pr >= pr.max() * 10 ** (-floor_db / 10)
        direction[g] = np.max(np.abs(10 * np.log10(pg[loud] / pr[loud])))
    return power, direction
