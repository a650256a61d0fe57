r"""The analysis's frequency error estimate: a Richardson extrapolation from a coarser solve.

With convergence ``f(h) = f* + C h^p`` in the element size ``h``, the fine solve's error is
``(f(r h) - f(h)) / (r^p - 1)`` for a coarser solve at ``r h``. This module holds the ratio
``r`` (:func:`coarse_ratio`), the order ``p`` of each method, measured against the accuracy
report's references (:func:`convergence_order`), a hex grid's own ratio and order where it
keeps some axes (:func:`hex_coarsening`), and the estimate itself in cents
(:func:`richardson_error`), which :func:`.analyze.analyze` stores as
``ModalModel.error_estimate_cents``.
"""

from __future__ import annotations

import numpy as np

from .band import F_MIN_HZ
from .eigen import solve_modes
from .plan import Plan

__all__ = ["coarse_ratio", "convergence_order", "richardson_error", "hex_coarsening", "hex_error_order",
           "facet_error_order", "ERROR_ORDER", "FACET_ERROR_ORDER", "FACET_DRAFT_ERROR_ORDER",
           "HEX_STAIRCASE_ERROR_ORDER"]


def coarse_ratio(plan: Plan) -> float:
    """Element size of the error estimate's coarser solve over the fine one: 2 for a thin
    wall (its surface refinement halves edges: 1.5 h often gives the same surface), 1.5
    otherwise."""
    return 2.0 if not plan.through_wall or plan.method == "facet" else 1.5


#: convergence order of the frequencies in the element size, for the Richardson estimate:
#: 2 (hex and refined tets), 2.5 for one quadratic tet through a thin wall (measured on the
#: 20 cm bowl from 13 to 6.5 mm edges: 2.0 for the first mode, 2.7 for the eighth)
ERROR_ORDER = {True: 2.0, False: 2.5}
#: the same for the facet shell, measured on the 20 cm bowl at default quality (33 elements
#: along its longest side): its first eight modes move by 9.5 cents RMS from 12 to 6 mm edges
#: and are then 1.1 cents RMS from the reference, so 2^p - 1 = 8.6, p = 3.3 (estimate /
#: measured at f_max 2, 3.5, 20 kHz: 1.57, 0.84, 0.96; with 2.5: 2.98, 1.6, 1.82). Coarser
#: meshes are not yet in that range: at draft (16 per side, its coarser solve 8) the bowl's
#: 9.5 cents against 24 moved give p = 1.8 (see :func:`facet_error_order`)
FACET_ERROR_ORDER = 3.3
FACET_DRAFT_ERROR_ORDER = 1.8


def facet_error_order(per_side: float) -> float:
    """Convergence order of the facet shell at ``per_side`` elements along the longest
    side: :data:`FACET_DRAFT_ERROR_ORDER` at 16 (draft) rising linearly to
    :data:`FACET_ERROR_ORDER` at 33 (default) and beyond (estimate / measured on the bowl:
    draft 1.0, default 0.84, high 1.2; with 3.3 throughout draft was 0.28)."""
    frac = float(np.clip((per_side - 16.0) / (33.0 - 16.0), 0.0, 1.0))
    return FACET_DRAFT_ERROR_ORDER + frac * (FACET_ERROR_ORDER - FACET_DRAFT_ERROR_ORDER)
#: the same for voxel hexahedra on a thin curved wall, whose staircase converges slowly (the
#: bowl: +77, +64, +50 cents at 13k, 51k, 128k dofs, order ~0.4 in h). With 2 the bowl's
#: estimate was 21 cents against 63 measured at f_max 20 kHz; with 1.25 every f_max from 2 to
#: 20 kHz is within a factor of two (reports/accuracy.md)
HEX_STAIRCASE_ERROR_ORDER = 1.25


def hex_error_order(tm, order: int) -> float:
    """Convergence order of hex frequencies in the element size, for the Richardson estimate.

    20-node cells on a surface the voxels follow exactly (faces along the axes: bars,
    plates, boxes) converge as ``h^4``; where the voxel embedding approximates a curved
    surface its staircase (fine voxels of ``h / refine``) converges as ``h^2`` at best and
    slower while the voxels are coarse, its sign varying from mode to mode. The order is
    ``1.5 + 2.5 a``, ``a`` the fraction of the surface area facing along an axis (8-node
    cells: 2). Measured against the accuracy report's references at draft, default and high
    quality (estimate / measured): beam 0.7, 1.2, 1.2 (with order 2: 2.3, 3.9, 3.9); the
    sphere (``curved_refine``) 0.67, 1.55, 1.09 (with order 2: 0.45, 1.04, 0.73).
    """
    from .plan import axis_aligned_fraction

    if order != 2:
        return 2.0
    return 1.5 + 2.5 * axis_aligned_fraction(tm)


def convergence_order(plan: Plan, tm, thickness) -> float:
    """Convergence order of the planned method's frequencies in the element size, for the
    Richardson estimate: :func:`facet_error_order`, :func:`hex_error_order` (or
    :data:`HEX_STAIRCASE_ERROR_ORDER` on a thin curved wall), else :data:`ERROR_ORDER`."""
    if plan.method == "facet":
        return facet_error_order(float(np.max(tm.extents)) / plan.h)
    if plan.method == "hex":
        return HEX_STAIRCASE_ERROR_ORDER if thin_curved_wall(tm, thickness) else hex_error_order(tm, plan.order)
    return ERROR_ORDER[plan.through_wall]


def thin_curved_wall(tm, thickness) -> bool:
    """A watertight wall thinner than :data:`.plan.THIN_WALL_RATIO` of the smallest side
    (not a bar or plate): what voxels turn into a staircase."""
    from .plan import THIN_WALL_RATIO, thin_wall

    t = thin_wall(tm, thickness)
    return bool(tm.is_watertight and np.isfinite(t) and t < THIN_WALL_RATIO * float(np.min(tm.extents)))


def hex_coarsening(tm, fine_grid, ratio, order, quadratic, coarse_grid):
    """``(ratio, order)`` of the Richardson estimate for a coarser hex grid, or None.

    A bar or rod keeps its least cells across (:func:`.plan.hex_min_cells`) in the coarser
    grid too: only its length is coarsened, by ``n_fine / n_coarse`` there, and its
    frequencies then move only by the error along it, where the surface is straight: the
    order is that of a surface the voxels follow (:func:`hex_error_order` with the area
    square to the coarsened axes counted as followed). The round rod at draft (2 x 2 x 14
    cells against 2 x 2 x 9) was estimated 49.7 cents with the staircase's order 1.63 and
    the nominal 1.5, 8.9 with 4 and 14 / 9 (measured against its converged 3D values:
    10.0). A grid coarsened along every axis keeps ``ratio``, ``order``; the same grid
    (nothing to compare): None."""
    from .plan import axis_aligned_fraction

    nf, nc = np.asarray(fine_grid, float), np.asarray(coarse_grid, float)
    changed = nf != nc
    if not changed.any():
        return None
    if changed.all():
        return ratio, order
    r = float(np.exp(np.mean(np.log(nf[changed] / nc[changed]))))
    return r, (1.5 + 2.5 * axis_aligned_fraction(tm, along=changed) if quadratic else order)


def richardson_error(f_fine, coarse, ratio, f_max, n=10, order=2.0, coarsening=None):
    """Richardson-style error [cents] of the first ``n`` modes from a coarser solve.

    With convergence f(h) = f* + C h^p (p = ``order``, :data:`ERROR_ORDER`), the fine solve's error is
    ``(f(r h) - f(h)) / (r^p - 1)`` for the coarse solve at ``r h``; the RMS over the
    first modes is returned. ``coarse``: a future of the coarser discretization;
    ``coarsening(grid)``: ``(r, p)`` from the coarser discretization's grid instead, or
    None when it cannot tell (:func:`hex_coarsening`).
    """
    try:
        disc = coarse.result()
        if coarsening is not None:
            got = coarsening(disc.info["grid"])
            if got is None:
                return float("nan")
            ratio, order = got
        f_hi = float(f_fine[min(n, len(f_fine)) - 1]) * 1.3
        sol = solve_modes(disc, max(min(f_hi, 2 * f_max), 2 * F_MIN_HZ))
    except Exception:  # an estimate must never break the analysis itself
        return float("nan")
    f_coarse = np.sqrt(np.maximum(sol.eigenvalues, 0)) / (2 * np.pi)
    m = min(n, len(f_fine), len(f_coarse))
    if m == 0:
        return float("nan")
    cents = 1200 * np.log2(f_coarse[:m] / f_fine[:m])
    return float(np.sqrt(np.mean(cents**2)) / (ratio**order - 1))
