r"""A scene's mode budget shared by importance (``SoundScene.from_model(budget_modes=...)``).

Every object keeps at least a few modes (``max(1, min(8, budget // (2 n_objects)))``: none is
silently dropped); the rest go greedily to the loudest next-lowest mode of any object, ranked
by :func:`mode_loudness`, its pressure per unit impulse at 1 m,
``|radiation_i| rms(phi_i) / omega_i``.
"""

from __future__ import annotations

import heapq

import numpy as np

from ..modal.model import ModalModel

__all__ = ["share_budget", "mode_loudness"]


def share_budget(sounding: list, budget_modes: int | None) -> list:
    """Truncate the models of ``sounding`` (:class:`~mjsound.sim.scene.SoundingGeom`, in place)
    to ``budget_modes`` modes in all; returns one note per truncated object (and one when
    the floor of modes per object exceeds the budget). ``None``: no budget, nothing changes.
    """
    total = sum(s.model.n_modes for s in sounding)
    notes = []
    if budget_modes is None or total <= budget_modes or not sounding:
        return notes
    budget = int(budget_modes)
    n_geoms = len(sounding)
    floor = max(1, min(8, budget // (2 * n_geoms)))
    counts = [min(s.model.n_modes, floor) for s in sounding]
    scores = [mode_loudness(s.model) for s in sounding]
    left = budget - sum(counts)
    heap = [(-scores[i][counts[i]], i) for i in range(n_geoms) if counts[i] < len(scores[i])]
    heapq.heapify(heap)
    while left > 0 and heap:
        _, i = heapq.heappop(heap)
        counts[i] += 1
        left -= 1
        if counts[i] < len(scores[i]):
            heapq.heappush(heap, (-scores[i][counts[i]], i))
    for s, n in zip(sounding, counts):
        if n < s.model.n_modes:
            f_top = s.model.frequencies_hz[n - 1] if n else 0.0
            notes.append(
                f"{s.name}: {s.model.n_modes} -> {n} modes (budget {budget}; kept up to {f_top:.0f} Hz)"
            )
            s.model = s.model.truncated(n_modes=n)
    if sum(counts) > budget:
        notes.append(
            f"budget {budget} < {sum(counts)}: every sounding geom keeps at least {floor} modes"
        )
    return notes


def mode_loudness(mm: ModalModel) -> np.ndarray:
    """Pressure per unit impulse at 1 m of each mode (ranking only) [Pa / (N s)]."""
    if mm.n_modes == 0:
        return np.zeros(0)
    rms = np.sqrt(np.mean(np.sum(mm.shapes.astype(np.float64) ** 2, axis=1), axis=0))
    rad = np.abs(mm.radiation)
    if not np.any(rad > 0):
        rad = mm.omega**2  # plain modal acceleration
    return rms * rad / mm.omega
