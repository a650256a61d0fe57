"""The nearest surface sample of the per-step kernels (``streams.nearest_sorted``, over rows
sorted along one axis) against the brute-force scan it replaces (``nearest_one`` below)."""

from __future__ import annotations

import numpy as np
import pytest

from numba import njit

from mjsound.jit import call_inner
from mjsound.synth.streams import nearest_sorted


@njit(cache=True)
def nearest_one(points, x, y, z):
    """Index of the row of ``points`` (p, 3) nearest to ``(x, y, z)``, the first of equally
    near rows (the brute-force scan the kernels used before ``nearest_sorted``)."""
    best = np.inf
    bi = 0
    for i in range(points.shape[0]):
        dx = points[i, 0] - x
        dy = points[i, 1] - y
        dz = points[i, 2] - z
        d = dx * dx + dy * dy + dz * dz
        if d < best:
            best = d
            bi = i
    return bi


def _sorted(points):
    """The rows along their longest axis (as ``objects.build_layout`` lays them out)."""
    axis = int(np.argmax(np.ptp(points, axis=0)))
    order = np.argsort(points[:, axis], kind="stable")
    return np.ascontiguousarray(points[order]), order.astype(np.int64), axis


@pytest.mark.parametrize("kind", ["random", "grid_with_duplicates", "capsule"])
def test_nearest_sorted_is_the_brute_force_answer_ties_included(kind):
    rng = np.random.default_rng(7)
    if kind == "random":
        points = rng.normal(size=(1000, 3)) * [0.3, 0.05, 0.02]
    elif kind == "grid_with_duplicates":  # equal distances everywhere: the lowest index must win
        g = np.arange(-3, 4) * 0.01
        points = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T
        points = np.concatenate([points, points[::-1], points[:50]])
    else:  # a capsule's surface samples along z
        t = rng.uniform(0, 2 * np.pi, 1024)
        zc = rng.uniform(-0.2, 0.2, 1024)
        points = np.stack([0.03 * np.cos(t), 0.03 * np.sin(t), zc], axis=1)
    pts, index, axis = _sorted(points)
    queries = np.concatenate([rng.normal(size=(300, 3)) * 0.2, points[rng.integers(0, len(points), 100)],
                              np.round(rng.normal(size=(100, 3)) * 0.02, 2) + 0.005])
    for x, y, z in queries:
        assert call_inner(nearest_sorted, pts, index, axis, x, y, z) == nearest_one(points, x, y, z)


def test_nearest_sorted_of_a_non_finite_point_or_no_rows_is_zero_as_the_brute_force():
    points = np.array([[0.0, 0.0, 1.0], [1.0, 2.0, 3.0], [-1.0, 0.5, 0.0]])
    pts, index, axis = _sorted(points)
    for q in ([np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [-np.inf, 0.0, np.nan]):
        assert call_inner(nearest_sorted, pts, index, axis, *q) == nearest_one(points, *q) == 0
    assert call_inner(nearest_sorted, np.zeros((0, 3)), np.zeros(0, np.int64), 0, 0.0, 0.0, 0.0) == 0
